"""Closed-loop local planning: seeded scenarios, metrics with worked numbers, success of DWA and
MPC on fixed scenarios with stated clearances, collisions end episodes, the pipeline's results."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slamkit.control.protocols import ControlOutput, LocalWorld
from slamkit.errors import ConfigError
from slamkit.control.registry import make_controller
from slamkit.experiments.closed_loop import (ClosedLoopConfig, Episode, Scenario, episode_metrics,
                                             make_scenario, perceive, run_episode, run_pipeline)
from slamkit.sim.moving_obstacles import MovingObstacles


def test_scenarios_are_seeded_and_consistent():
    a, b = make_scenario(3, "open"), make_scenario(3, "open")
    np.testing.assert_array_equal(a.path_xy_m, b.path_xy_m)
    np.testing.assert_array_equal(a.obstacles.a_xy_m, b.obstacles.a_xy_m)
    assert a.name == "open_3"
    # the path starts at the start and ends at the goal (cell centres of the A* search)
    assert np.linalg.norm(a.path_xy_m[0] - a.start_xytheta[:2]) < 0.08
    assert np.linalg.norm(a.path_xy_m[-1] - a.goal_xy_m) < 0.08
    # the global path keeps >= robot radius + 0.15 m from walls (the costmap's inscribed radius),
    # up to half a cell of the distance field's discretisation
    d = a.distance.query(a.path_xy_m)[0]
    assert d.min() >= 0.35 - 0.05
    with pytest.raises(ConfigError):
        make_scenario(0, "moon")


def test_metrics_worked_example():
    """Speeds 0, 0.1, 0.3, 0.6 at dt = 0.1: second differences 0.1 and 0.1 -> jerk 10 m/s^3 each,
    RMS 10; path (0,0) -> (3,4) -> (3,5): 6 m; min clearance 0.2; goal reached at t = 0.3 s."""
    ep = Episode("s", "c", 0, np.array([0.0, 0.1, 0.2, 0.3]),
                 np.array([[0, 0, 0], [3, 4, 0], [3, 5, 0], [3, 5, 0]], float),
                 np.array([[0.0, 0], [0.1, 0], [0.3, 0], [0.6, 0]])[1:], ("ok", "fallback_brake", "ok"),
                 np.array([1e-3, 2e-3, 3e-3]), np.array([0.5, 0.2, 0.4, 0.3]), True, False)
    m = episode_metrics(Episode(**{**ep.__dict__, "commands": np.array([[0.0, 0], [0.1, 0], [0.3, 0], [0.6, 0]])}), 0.1)
    assert m["jerk_rms_mps3"] == pytest.approx(10.0)
    assert m["path_length_m"] == pytest.approx(6.0)
    assert m["min_clearance_m"] == pytest.approx(0.2)
    assert m["time_to_goal_s"] == pytest.approx(0.3)
    assert m["fallback_steps"] == 1.0
    assert m["step_latency_median_ms"] == pytest.approx(2.0)


def test_perception_is_range_limited():
    sc = make_scenario(0, "open")
    far = MovingObstacles([[sc.start_xytheta[0] + 9.0, sc.start_xytheta[1]]] * 1,
                          [[sc.start_xytheta[0] + 9.0, sc.start_xytheta[1] + 1.0]], [0.0], [0.3], [0.0])
    near = MovingObstacles([[sc.start_xytheta[0] + 2.0, sc.start_xytheta[1]]],
                           [[sc.start_xytheta[0] + 2.0, sc.start_xytheta[1] + 1.0]], [0.5], [0.3], [0.0])
    loop = ClosedLoopConfig(sensor_range_m=5.0)
    w_far = perceive(Scenario(**{**sc.__dict__, "obstacles": far}), sc.start_xytheta, 0.0, loop)
    w_near = perceive(Scenario(**{**sc.__dict__, "obstacles": near}), sc.start_xytheta, 0.0, loop)
    assert w_far.num_circles == 0 and w_near.num_circles == 1
    np.testing.assert_allclose(w_near.circle_velocity_mps, [[0.0, 0.5]])


class _Straight:
    """Drives straight at 0.5 m/s whatever happens (to provoke a collision)."""

    name = "straight"

    def reset(self) -> None:
        pass

    def compute(self, state, reference, world: LocalWorld) -> ControlOutput:
        return ControlOutput(np.array([0.5, 0.0]))


def test_collision_ends_the_episode():
    """A static circle (r = 0.3) 2.02 m ahead of the start on the heading: the robot's disc (0.2)
    touches it after 1.52 m; at 0.05 m per step the first negative clearance is at t = 3.1 s
    (1.55 m, clearance -0.03 m), which ends the episode."""
    sc = make_scenario(0, "open")
    x, y, th = sc.start_xytheta
    ahead = np.array([x + 2.02 * math.cos(th), y + 2.02 * math.sin(th)])
    obs = MovingObstacles([ahead], [ahead], [0.0], [0.3], [0.0])
    sc = Scenario(**{**sc.__dict__, "obstacles": obs})
    if sc.distance.query(ahead)[0] < 1.0:
        pytest.skip("static map too close to the test line")
    ep = run_episode(sc, _Straight())
    assert ep.collided and not ep.reached_goal
    assert ep.metrics["collisions"] == 1.0 and ep.metrics["success"] == 0.0
    assert ep.t_s[-1] == pytest.approx(3.1)
    assert ep.metrics["min_clearance_m"] == pytest.approx(-0.03, abs=1e-9)


@pytest.mark.parametrize("controller,scenario,min_clearance", [
    ("dwa", ("open", 0), 0.5),          # measured 0.64 m, 14.4 s
    ("mpc_osqp", ("open", 2), 0.12),    # measured 0.17 m, 21.3 s
    ("mpc", ("open", 2), 0.12),         # measured 0.17 m, 21.3 s
    ("mpc_fatrop", ("open", 2), 0.12),
    ("potential_fields", ("open", 0), 0.3),  # measured 0.42 m, 13.1 s
])
def test_closed_loop_success_on_fixed_scenarios(controller, scenario, min_clearance):
    """Each controller reaches the goal of a fixed seeded scenario with three crossing obstacles,
    without collision, keeping the stated minimum clearance, in under 30 s."""
    sc = make_scenario(scenario[1], scenario[0])
    assert len(sc.obstacles) == 3
    ep = run_episode(sc, make_controller(controller))
    assert ep.reached_goal and not ep.collided
    assert ep.metrics["min_clearance_m"] >= min_clearance
    assert ep.metrics["time_to_goal_s"] < 30.0
    # the path driven is at most 1.3x the global path
    glob = np.linalg.norm(np.diff(sc.path_xy_m, axis=0), axis=1).sum()
    assert ep.metrics["path_length_m"] <= 1.3 * glob


def test_pipeline_results_shape(tmp_path):
    config = {"pipeline": "local_planning", "name": "lp_test", "controllers": ["dwa", "mpc_osqp"],
              "scenarios": {"kinds": ["open"], "seeds": [0, 1], "n_obstacles": 3},
              "closed_loop": {"max_time_s": 40.0}}
    results = run_pipeline(config, tmp_path / "out")
    assert results["pipeline"] == "local_planning"
    assert len(results["runs"]) == 4
    assert {r["estimator"] for r in results["runs"]} == {"dwa", "mpc_osqp"}
    assert {r["seed"] for r in results["runs"]} == {0, 1}
    succ = [s for s in results["summary"] if s["metric"] == "success"]
    assert len(succ) == 2 and all(s["n"] == 2 for s in succ)
    assert all(s["mean"] == 1.0 for s in succ)  # both solve open_0 and open_1 (measured above)
    out = tmp_path / "out"
    for f in ("config.yaml", "results.json", "report.md", "plots/trajectories.png", "plots/metrics.png"):
        assert (out / f).exists(), f
    with pytest.raises(ConfigError):
        run_pipeline({**config, "controllers": ["teleport"]}, tmp_path / "bad")


def test_pipeline_recording(tmp_path, verify_rrd):
    from slamkit.viz.pipelines import observer_for

    config = {"pipeline": "local_planning", "controllers": ["dwa", "mpc_osqp"],
              "scenarios": {"kinds": ["open"], "seeds": [1]}, "closed_loop": {"max_time_s": 2.0}}
    run_pipeline(config, tmp_path / "rec", observer_factory=observer_for)
    entities = verify_rrd(tmp_path / "rec" / "recording.rrd")
    assert "/dwa/open_1/world/candidates" in entities
    assert "/mpc_osqp/open_1/world/mpc_horizon" in entities


def test_control_benchmark_cases_have_same_run_ratios():
    """The bench's case structure on a tiny run (no timing assertions: speed belongs to the bench)."""
    from slamkit.bench.control import _record_cycles, closed_loop_cases, timing_cases

    cases, episodes = closed_loop_cases(1, controllers=("dwa",), kinds=("open",))
    assert [c.name for c in cases] == ["success_rate_dwa", "time_to_goal_mean_s_dwa", "path_length_mean_m_dwa",
                                       "min_clearance_mean_m_dwa", "collision_rate_dwa", "jerk_rms_mean_mps3_dwa"]
    assert cases[0].value == episodes[0].metrics["success"]
    cycles = _record_cycles(1, 4)
    assert len(cycles) == 4 and cycles[0][0].t_s == 0.0
    timing = timing_cases(cycles)
    assert [c.name for c in timing] == ["mpc_ipopt_n20_median", "mpc_ipopt_n20_p99", "mpc_osqp_n20_median",
                                        "mpc_fatrop_n20_median", "dwa_cycle_median"]
    for c in timing:
        assert c.unit == "ms" and c.ratio == pytest.approx(c.reference_value / c.value)
        assert c.extra["cycles"] == 4 and c.extra["reference_failures"] == 0


def _u_trap():
    """A U open towards the start (back wall at x = 8 m, arms at y = 3 and 7 m) with the tracked
    path a straight line through it: a local minimum for gradient descent."""
    from slamkit.control.protocols import DistanceGrid
    from slamkit.maps.distance_field import distance_field_m
    from slamkit.maps.inflation import costmap
    from slamkit.maps.occupancy_grid import OccupancyGrid
    from slamkit.planning.grid_search import costmap_to_cell_cost

    occ = np.zeros((100, 140), bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    occ[30:70, 80:83] = True
    occ[30:33, 55:83] = True
    occ[67:70, 55:83] = True
    g = OccupancyGrid(occ, 0.1)
    return Scenario("trap", 0, g, np.array([2.0, 5.0, 0.0]), np.array([12.0, 5.0]),
                    np.array([[2.0, 5.0], [12.0, 5.0]]), MovingObstacles.empty(),
                    DistanceGrid(distance_field_m(g), 0.1), costmap_to_cell_cost(costmap(g, 0.35, 1.0)))


def test_potential_field_hands_over_to_the_global_planner():
    """In the U trap, potential fields with escape="handover" stall, report LOCAL_MINIMUM, the loop
    replans with A* (once) and the robot reaches the goal around the U (measured 29.5 s, 19.4 m);
    the seeded random walk does not get out of a U this deep within 60 s."""
    sc = _u_trap()
    ep = run_episode(sc, make_controller("potential_fields", {"escape": "handover"}))
    assert ep.reached_goal and ep.metrics["replans"] >= 1
    assert "local_minimum" in ep.statuses
    assert ep.metrics["path_length_m"] > 14.0  # around the U, not through it (straight line: 10 m)
    walk = run_episode(sc, make_controller("potential_fields", {"escape": "random_walk"}))
    assert not walk.reached_goal and "escaping" in walk.statuses


def test_pipeline_observers_get_a_typed_snapshot():
    # issue 30, item 4: a step snapshot's state is a LocalPlanningSnapshot, not a dict of string keys
    from slamkit.experiments.closed_loop import ControlStep, LocalPlanningSnapshot, compare

    class Keep:
        wants_steps = True

        def __init__(self):
            self.seen = []

        def on_step(self, snapshot):
            self.seen.append(snapshot)

    keep = Keep()
    compare({"controllers": ["dwa"], "scenarios": {"kinds": ["open"], "seeds": [1]},
             "closed_loop": {"max_time_s": 0.5}}, keep)
    assert len(keep.seen) == 5 and keep.seen[0].run == "dwa/open_1"
    st = keep.seen[0].state
    assert isinstance(st, LocalPlanningSnapshot) and isinstance(st.step, ControlStep)
    assert (st.controller, st.scenario.name, st.step.step) == ("dwa", "open_1", 1)
