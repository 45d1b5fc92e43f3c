"""The navigation stack: its contract (events in, commands out, a public pose and covariance),
and a short closed-loop run through the simulator in the default suite."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml

from slamkit.data.estimate import LatestBelief
from slamkit.data.sequence import Odometry
from slamkit.errors import ConfigError
from slamkit.experiments.navigation import EpisodeConfig, make_navigation_scenario, run_episode
from slamkit.experiments.navigation.run import willow_yaml
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.systems.navigation import (CommandStatus, GlobalPlanningConfig, NavigationConfig, NavigationStack,
                                       SafetyConfig, YieldingConfig, default_controller_params)


def _room() -> OccupancyGrid:
    occ = np.zeros((80, 120), bool)  # 6 m x 4 m at 5 cm, walls 2 cells thick
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    return OccupancyGrid(occ, 0.05)


def test_events_in_commands_out_and_a_public_belief():
    stack = NavigationStack(_room())
    stack.reset([1.0, 2.0, 0.0], np.diag([0.01, 0.01, 0.01]))
    assert isinstance(stack, LatestBelief)
    assert stack.command(0.0).status == "no_goal"
    assert stack.command(0.0).status is CommandStatus.NO_GOAL  # an enum that is its string
    stack.set_goal([4.5, 2.0, 0.0])
    out = stack.command(0.0)
    assert out.status == "driving" and out.command[0] >= 0.0 and out.safe_stop
    assert stack.path is not None and np.allclose(stack.path[-1], [4.5, 2.0], atol=0.05)
    stack.step(Odometry(0.1, 0.1, 0.5, 0.0))
    mean, cov = stack.current_pose()
    assert mean[0] == pytest.approx(1.05, abs=0.05) and cov.shape == (3, 3)
    est = stack.latest_estimate()
    np.testing.assert_allclose(est.trajectory.xytheta()[0], mean)
    assert est.pose_covariances.shape == (1, 3, 3)
    assert set(stack.timings_s) == {"localisation", "perception", "global_planner", "local_planner"}


def test_config_is_checked():
    with pytest.raises(ConfigError, match="uncertainty"):
        NavigationConfig(uncertainty="maybe")
    with pytest.raises(ConfigError, match="grid planner"):
        NavigationConfig(global_planner="rrt_star")
    # the sections are their own frozen configs (a mapping is the pipeline's to build)
    with pytest.raises(ConfigError, match="yielding must be a YieldingConfig"):
        NavigationConfig(yielding={"hedge": 0.3})
    with pytest.raises(ConfigError, match="SafetyConfig.brake_decel_mps2 must be > 0"):
        SafetyConfig(brake_decel_mps2=0.0)


def test_short_closed_loop_run_reaches_the_goal_within_3_cm():
    # office seed 1 with its two crossing obstacles: measured 28.6 s, final error 0.7 cm (43.3 s and
    # 1.2 cm before yielding chose where to wait, the signed likelihood field and the roughening
    # floor: it had stopped between the two shuttlers' lines)
    sc = make_navigation_scenario(1, "office")
    ep = run_episode(sc, NavigationConfig(), EpisodeConfig(max_time_s=60.0))
    m = ep.metrics
    assert m["success"] == 1.0
    assert m["final_position_error_m"] <= 0.03 and m["final_heading_error_rad"] <= 0.1
    assert m["collision_static"] == 0.0 and m["collision_moving"] == 0.0
    assert m["localisation_error_max_m"] < 0.1
    assert m["replans"] >= 1


def test_covariance_aware_costmap_inflates_by_k_sigma():
    grid = _room()
    stack = NavigationStack(grid, NavigationConfig(uncertainty="covariance", collision_probability=0.05))
    fixed = NavigationStack(grid, NavigationConfig())
    cov = np.diag([0.04**2, 0.02**2, 0.01])
    # k sigma = 1.645 * 0.04 = 6.58 cm -> 7 cm (cached per whole centimetre); fixed: always 0
    assert stack.planning.sigma_key(cov) == 7 and fixed.planning.sigma_key(cov) == 0
    # inscribed radius 0.2 + 0.15 (+ 0.07): the cell whose centre is 0.375 m from the wall cells'
    # centres (x = 0.1 + 0.375) is free with fixed inflation, blocked with the covariance-aware one
    iy, ix = 40, int(round((0.1 + 0.375) / 0.05 - 0.5))
    assert np.isfinite(fixed.cell_cost(0)[iy, ix]) and not np.isfinite(stack.cell_cost(7)[iy, ix])


def test_safe_stop_check_on_a_braking_trajectory():
    stack = NavigationStack(_room(), NavigationConfig(safety=SafetyConfig(brake_decel_mps2=1.0)))
    stack.reset([1.0, 2.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    from slamkit.control.protocols import LocalWorld

    # braking from 0.5 m/s in 0.1 s steps covers 0.1 * 0.5 * (1 + .8 + .6 + .4 + .2) = 0.15 m, so
    # the 0.2 m disc reaches 0.35 m ahead: a disc surface 0.40 m ahead is safe, 0.32 m is not
    far = LocalWorld([[1.5, 2.0]], [0.1], [[0.0, 0.0]])
    near = LocalWorld([[1.42, 2.0]], [0.1], [[0.0, 0.0]])
    assert stack.safe_stop_exists(np.array([1.0, 2.0, 0.0]), np.array([0.5, 0.0]), far)
    assert not stack.safe_stop_exists(np.array([1.0, 2.0, 0.0]), np.array([0.5, 0.0]), near)


def test_plant_clearance_is_the_exact_distance_to_the_wall_squares():
    from slamkit.experiments.navigation import NavigationScenario
    from slamkit.maps.distance_field import distance_field_m
    from slamkit.sim.moving_obstacles import MovingObstacles
    from slamkit.sim.navigation_world import NavigationPlant

    grid = _room()  # walls: cells 0-1 (x < 0.1 m) on the left
    sc = NavigationScenario("room", 0, grid, np.array([0.37, 2.0, 0.0]), np.array([4.0, 2.0, 0.0]),
                            np.zeros((2, 2)), MovingObstacles.empty())
    plant = NavigationPlant(sc, np.random.default_rng(0))
    field = distance_field_m(grid)
    # centre 0.37 m from x = 0: the wall surface is at x = 0.1 -> 0.27 m, minus the 0.2 m radius
    assert plant.clearance_m(0.0, 0.2, field)[0] == pytest.approx(0.07, abs=1e-9)
    plant.world_xytheta_body[:2] = [0.25, 0.22]  # corner: 0.15 m from the left wall, 0.12 from the bottom
    assert plant.clearance_m(0.0, 0.2, field)[0] == pytest.approx(0.12 - 0.2, abs=1e-9)


def test_dstar_lite_repairs_its_search_where_astar_starts_over():
    """global_planner: dstar_lite searches once, then repairs: a moved start alone expands
    nothing (measured 0 of the first search's 83), and after a disc blocks half the room the
    repaired path costs what a fresh A* search on the same costmap costs (measured: the repair
    expanded 450 cells, a fresh D* Lite 434, A* 561 -- a change next to the robot is no cheaper
    to repair than to search again)."""
    from slamkit.planning.registry import make_planner
    from slamkit.planning.protocols import PlanningProblem

    stack = NavigationStack(_room(), NavigationConfig(global_planner="dstar_lite"))
    stack.reset([1.0, 2.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    stack.set_goal([5.0, 2.0, 0.0])
    cost = stack.cell_cost(0)
    first = stack.planning.search(np.array([1.0, 2.0]), cost)
    assert first.solved and stack.plan_expansions[-1] == first.stats.expansions > 50
    moved = stack.planning.search(np.array([1.2, 2.0]), cost)
    assert moved.solved and moved.stats.expansions == 0
    blocked = cost.copy()
    g = stack.grid
    iy, ix = np.mgrid[0:g.height, 0:g.width]
    centres = g.cell_to_world(np.column_stack([ix.ravel(), iy.ravel()])).reshape(g.height, g.width, 2)
    blocked[np.linalg.norm(centres - [3.0, 1.6], axis=2) <= 0.6] = np.inf  # the lower half of the room
    repaired = stack.planning.search(np.array([1.2, 2.0]), blocked)
    fresh = make_planner("astar").plan(PlanningProblem(g, np.array([1.2, 2.0]), np.array([5.0, 2.0]), cell_cost=blocked))
    assert repaired.solved and fresh.solved
    assert repaired.cost == pytest.approx(fresh.cost, rel=1e-9) and repaired.cost > moved.cost
    assert stack.plan_expansions == [first.stats.expansions, 0, repaired.stats.expansions]
    # the path goes round the disc, above it
    assert np.all(np.linalg.norm(repaired.path - [3.0, 1.6], axis=1) > 0.6)


@pytest.mark.parametrize("name", ["dwa", "rollout", "mpc", "mpc_osqp"])
def test_every_local_planner_builds_in_the_stack_with_its_own_defaults(name):
    """controller_params None: the course's DWA weights for the sampling controllers, the MPC's
    own config with the stack's robot radius (the DWA weights were unknown keys to the MPC, so
    ``controller: mpc`` raised a ConfigError)."""
    stack = NavigationStack(_room(), NavigationConfig(controller=name, robot_radius_m=0.25))
    cfg = stack.controller.config
    assert cfg.robot_radius_m == 0.25
    if name in ("dwa", "rollout"):
        assert (cfg.w_heading, cfg.w_clearance, cfg.w_velocity) == (0.8, 0.2, 0.4)
    else:
        assert cfg.solver == ("osqp" if name == "mpc_osqp" else "ipopt")
    stack.reset([1.0, 2.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    stack.set_goal([4.5, 2.0, 0.0])
    out = stack.command(0.0)
    assert out.status == "driving" and out.command[0] >= 0.0


def _straight_stack(x_m: float) -> NavigationStack:
    """A stack in the room at (x_m, 2) facing +x, its path straight along y = 2 to x = 5."""
    stack = NavigationStack(_room())
    stack.reset([x_m, 2.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    stack.path = np.array([[x_m, 2.0], [5.0, 2.0]])
    return stack


def _tracks(xy, velocity, radius):
    from slamkit.estimation.obstacle_tracker import Tracks

    n = len(radius)
    return Tracks(np.arange(n), np.asarray(xy, float), np.asarray(velocity, float), np.asarray(radius, float),
                  np.tile(np.eye(4), (n, 1, 1)))


def test_yielding_stops_short_of_a_crossing_track():
    stack = _straight_stack(2.05)
    pose = np.array([2.05, 2.0, 0.0])
    # a 0.3 m person crossing x = 3 downwards at 0.5 m/s, on the path at t = 3 s: its sweep grown by
    # the robot (0.2) and the moving margin (0.25) covers |x - 3| <= 0.75; the path is sampled every
    # 0.075 m from the robot, so the first covered sample is x = 2.275: gap 0.225 m, stop 5 cm short,
    # v = sqrt(2 * 0.5 * 0.175) = 0.4183 m/s (the robot at cruise speed would be there within the slack)
    crossing = _tracks([[3.0, 3.5]], [[0.0, -0.5]], [0.3])
    assert stack.yield_decision(pose, crossing).v_max_mps == pytest.approx(np.sqrt(0.175), abs=1e-9)
    # the same person 8 m away arrives after the robot has passed (10.5 s > horizon): no yield
    assert stack.yield_decision(pose, _tracks([[3.0, 8.0]], [[0.0, -0.5]], [0.3])).v_max_mps == np.inf
    # already past the path and walking away: no yield
    assert stack.yield_decision(pose, _tracks([[3.0, 1.0]], [[0.0, -0.5]], [0.3])).v_max_mps == np.inf
    # walking along the path at the robot: stopping would not help, the evasion handles it
    assert stack.yield_decision(pose, _tracks([[4.0, 2.0]], [[-0.5, 0.0]], [0.3])).v_max_mps == np.inf
    # slow tracks are not traffic (they block the path and are planned around)
    assert stack.yield_decision(pose, _tracks([[3.0, 2.5]], [[0.0, -0.1]], [0.3])).v_max_mps == np.inf



def test_local_world_hedges_the_prediction_of_tracks_seen_reversing():
    from slamkit.estimation.obstacle_tracker import Tracks

    # two 0.3 m tracks moving +x at 0.4 m/s, typical speed 0.5 m/s (they were faster a moment
    # ago); the second has reversed once. Hedges 0.5 / 1.0: the first is predicted at half its
    # velocity with its disc growing at 0.5 * 0.5 = 0.25 m/s, the second stays where it is and
    # grows at 0.5 m/s (anywhere it can reach); both get the 0.25 m moving margin
    stack = _straight_stack(1.0)
    stack.config = dataclasses.replace(stack.config, prediction_hedge=0.5, reversed_prediction_hedge=1.0)
    tracks = Tracks(np.arange(2), np.array([[3.0, 2.0], [3.0, 3.0]]), np.array([[0.4, 0.0], [0.4, 0.0]]),
                    np.array([0.3, 0.3]), np.tile(np.eye(4), (2, 1, 1)), reversals=np.array([0, 1]),
                    speed_typical_mps=np.array([0.5, 0.5]))
    world = stack.local_world(tracks)
    np.testing.assert_allclose(world.circle_velocity_mps, [[0.2, 0.0], [0.0, 0.0]])
    np.testing.assert_allclose(world.circle_growth_mps, [0.25, 0.5])
    np.testing.assert_allclose(world.radii_at([2.0]), [[1.05, 1.55]])
    # the defaults (no hedge) are the constant-velocity prediction
    plain = _straight_stack(1.0).local_world(tracks)
    np.testing.assert_allclose(plain.circle_velocity_mps, tracks.velocity_mps)
    np.testing.assert_allclose(plain.circle_growth_mps, [0.0, 0.0])


def test_local_world_grows_a_standing_track_that_may_set_off():
    # a 0.3 m person standing (0.05 m/s: below blocking_speed_mps 0.15) and one walking at
    # 0.4 m/s. standing_growth_mps 0.2 up to 0.15 m: the standing disc grows 0.1 m by 0.5 s and
    # stops at 0.45 m from 0.75 s on; the walking one keeps the plain prediction (its 0.25 m
    # moving margin, no growth). With 0 the standing disc stays as it is
    stack = _straight_stack(1.0)
    tracks = _tracks([[3.0, 2.6], [3.0, 3.5]], [[0.05, 0.0], [0.0, -0.4]], [0.3, 0.3])
    stack.config = dataclasses.replace(stack.config, standing_growth_mps=0.0)
    np.testing.assert_allclose(stack.local_world(tracks).radii_at([2.0]), [[0.3, 0.55]])
    # the defaults: 0.2 m/s up to 0.2 m
    assert (NavigationConfig().standing_growth_mps, NavigationConfig().standing_growth_max_m) == (0.2, 0.2)
    stack.config = dataclasses.replace(stack.config, standing_growth_mps=0.2, standing_growth_max_m=0.15)
    world = stack.local_world(tracks)
    np.testing.assert_allclose(world.circle_growth_mps, [0.2, 0.0])
    np.testing.assert_allclose(world.radii_at([0.5, 0.75, 2.0]), [[0.4, 0.55], [0.45, 0.55], [0.45, 0.55]])
    # no limit: over the whole look-ahead (0.7 m at 2 s)
    stack.config = dataclasses.replace(stack.config, standing_growth_max_m=float("inf"))
    np.testing.assert_allclose(stack.local_world(tracks).radii_at([2.0]), [[0.7, 0.55]])
    # from a pipeline's YAML: `.inf` switches the limit off; null keeps the default; a string is refused
    from slamkit.config import build

    assert build(NavigationConfig, yaml.safe_load("standing_growth_max_m: .inf")).standing_growth_max_m == float("inf")
    assert build(NavigationConfig, yaml.safe_load("standing_growth_max_m: null")).standing_growth_max_m == 0.2
    with pytest.raises(ConfigError, match="standing_growth_max_m"):
        build(NavigationConfig, {"standing_growth_max_m": "none"})
    # a hedge that grows a standing track faster keeps its own, unlimited rate: hedge 1 of a typical
    # speed of 0.5 m/s (a shuttler slowed at its turn), 0.5 m/s, 1.3 m at 2 s
    stack.config = dataclasses.replace(stack.config, standing_growth_max_m=0.15, prediction_hedge=1.0)
    slowed = dataclasses.replace(tracks, speed_typical_mps=np.array([0.5, 0.4]))
    world = stack.local_world(slowed)
    np.testing.assert_allclose(world.circle_growth_mps, [0.5, 0.4])
    np.testing.assert_allclose(world.radii_at([2.0]), [[1.3, 1.35]])
    for key, bad in (("standing_growth_mps", -0.1), ("standing_growth_mps", float("nan")),
                     ("standing_growth_max_m", -0.1), ("standing_growth_max_m", float("nan"))):
        with pytest.raises(ConfigError, match=f"NavigationConfig.{key}"):
            dataclasses.replace(stack.config, **{key: bad})


def test_wall_turns_predict_a_track_turning_back_short_of_a_wall():
    # the room's bottom wall has its surface at y = 0.1. A 0.3 m person at (3, 1.02) walking at it
    # at 0.5 m/s: its centre would come within half its radius (0.15 m) of the wall at
    # t = 1.54 s (sampled every 0.05 s: 1.55); it turns 0.15 + 0.2 (wall_turn_clearance_m) = 0.35 m
    # of its way earlier, at 1.55 - 0.7 = 0.85 s (its disc then 0.195 m off the wall)
    stack = _straight_stack(1.0)
    toward = _tracks([[3.0, 1.02]], [[0.0, -0.5]], [0.3])
    assert stack.local_world(toward).num_circles == 1  # off by default
    stack.config = dataclasses.replace(stack.config, wall_turn_horizon_s=6.0)
    k, t_turn = stack.wall_turns(toward.xy_m, toward.velocity_mps, toward.radius_m, np.array([True]))
    assert k.tolist() == [0] and t_turn == pytest.approx([0.85], abs=1e-9)
    # the turn back is the prediction mirrored there: a second disc (with the 0.25 m moving margin)
    # from (3, 1.02 - 2 * 0.85 * 0.5) = (3, 0.17) at +0.5 m/s, where the first is at 0.85 s
    world = stack.local_world(toward)
    np.testing.assert_allclose(world.circle_xy_m, [[3.0, 1.02], [3.0, 0.17]], atol=1e-12)
    np.testing.assert_allclose(world.circle_velocity_mps, [[0.0, -0.5], [0.0, 0.5]])
    np.testing.assert_allclose(world.circle_radius_m, [0.55, 0.55])
    np.testing.assert_allclose(world.circles_at([0.85])[0, 1], [3.0, 0.595], atol=1e-12)
    assert stack.moving_discs(toward, world).tolist() == [True, True]
    # walking along that wall (its disc 2 cm into it) at 0.3 m/s towards the east wall (surface
    # x = 5.9), which it would run into after 12.5 s: no turn within the 6 s horizon; nor for a
    # slow track (not traffic) or a standing one
    along = _tracks([[2.0, 0.38]], [[0.3, 0.0]], [0.3])
    assert len(stack.wall_turns(along.xy_m, along.velocity_mps, along.radius_m, np.array([True]))[0]) == 0
    slow = _tracks([[3.0, 1.02]], [[0.0, -0.1]], [0.3])
    assert stack.local_world(slow).num_circles == 1
    with pytest.raises(ConfigError):
        dataclasses.replace(stack.config, wall_turn_horizon_s=-1.0)
    with pytest.raises(ConfigError):
        dataclasses.replace(stack.config, wall_turn_clearance_m=float("nan"))
    for key, bad in (("wall_turn_horizon_s", -1.0), ("wall_turn_horizon_s", float("nan")), ("plan_dt_s", 0.0),
                     ("plan_dt_s", float("nan")), ("plan_slack_s", -0.1), ("plan_slack_s", float("nan")),
                     ("plan_margin_m", -0.1), ("plan_margin_m", float("nan"))):
        with pytest.raises(ConfigError, match=f"YieldingConfig.{key}"):
            dataclasses.replace(stack.config.yielding, **{key: bad})


def test_yielding_to_a_track_that_will_turn_back_at_a_wall():
    # the person of test_wall_turns_... walks away from the path towards the wall; constant
    # velocity says no yield. Its turn back (wall_turn_horizon_s 6) is on the path (y = 2, reach
    # 0.3 + 0.25 + 0.2 = 0.75 m) from 2.16 s, 0.7 s after the robot at cruise speed would be at
    # x = 3: a conflict. Within the 3 s waiting horizon it comes up to (3, 1.67), so the path is no
    # waiting place from x = 3 - sqrt(0.8^2 - 0.33^2) = 2.271 m (0.8: with the 5 cm waiting margin),
    # sampled at 2.05 + 0.075 k: 2.275, a gap of 0.225 m: v = sqrt(2 * 0.5 * 0.175) m/s
    stack = _straight_stack(2.05)
    pose = np.array([2.05, 2.0, 0.0])
    away = _tracks([[3.0, 1.02]], [[0.0, -0.5]], [0.3])
    assert stack.yield_decision(pose, away).v_max_mps == np.inf
    stack.config = dataclasses.replace(stack.config, wall_turn_horizon_s=6.0)
    decision = stack.yield_decision(pose, away)
    assert decision.v_max_mps == pytest.approx(np.sqrt(0.175), abs=1e-9)
    assert decision.wait_gap_m == pytest.approx(0.225, abs=1e-9)
    # the same turn for yielding alone (yielding.wall_turn_horizon_s): the local planner's world
    # keeps the track's one disc, yielding's sweep has the turn and the same decision
    stack.config = dataclasses.replace(stack.config, wall_turn_horizon_s=0.0,
                                       yielding=dataclasses.replace(stack.config.yielding, wall_turn_horizon_s=6.0))
    assert stack.local_world(away).num_circles == 1
    decision = stack.yield_decision(pose, away)
    assert decision.v_max_mps == pytest.approx(np.sqrt(0.175), abs=1e-9)
    assert decision.wait_gap_m == pytest.approx(0.225, abs=1e-9)


def test_yielding_to_a_shuttler_that_may_turn_back():
    from slamkit.estimation.obstacle_tracker import Tracks

    # the person of the yielding example 1 m past the path, walking away at 0.5 m/s: constant
    # velocity says no yield. Seen reversing before and with yielding.reversed_hedge 1, it may be
    # anywhere within 0.5 t: grown by the margin and the robot its disc reaches the path (1 m off)
    # at t = 0.5 s, before the robot (there at 0.95 / 0.65 = 1.46 s), and within the 6 s horizon
    # it covers the robot's own place (1.38 m off, reach 3.75 m): the robot stops where it is
    stack = _straight_stack(2.05)
    pose = np.array([2.05, 2.0, 0.0])
    away = dict(ids=np.arange(1), xy_m=np.array([[3.0, 1.0]]), velocity_mps=np.array([[0.0, -0.5]]),
                radius_m=np.array([0.3]), covariance=np.eye(4)[None])
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(stack.config.yielding, reversed_hedge=0.0))
    assert stack.yield_decision(pose, Tracks(**away, reversals=np.array([1]))).v_max_mps == np.inf
    # the default hedge 0.3: centre receding at 0.35 m/s, disc growing at 0.15 m/s -- the trailing
    # edge still recedes (at 0.2 m/s) from 1 m off: it never comes back over the path, no yield
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(stack.config.yielding, reversed_hedge=0.3))
    assert stack.yield_decision(pose, Tracks(**away, reversals=np.array([1]))).v_max_mps == np.inf
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(stack.config.yielding, reversed_hedge=1.0))
    assert stack.yield_decision(pose, Tracks(**away, reversals=np.array([1]))).v_max_mps == 0.0
    # one never seen reversing is still predicted with its constant velocity
    assert stack.yield_decision(pose, Tracks(**away)).v_max_mps == np.inf

def test_a_robot_without_progress_for_its_patience_yields_to_the_constant_velocity_prediction_with_less_slack():
    from slamkit.estimation.obstacle_tracker import Tracks

    # the shuttler of test_yielding_to_a_shuttler_that_may_turn_back with reversed_hedge 1: the
    # robot stops. With patience_s 5, after 5 s without getting 0.5 m nearer the goal along its
    # path it predicts the shuttler at constant velocity (walking away: no yield) until it gains
    # 0.5 m on where it was then
    stack = _straight_stack(2.05)
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(
        stack.config.yielding, reversed_hedge=1.0, patience_s=5.0))
    pose = np.array([2.05, 2.0, 0.0])
    away = Tracks(np.arange(1), np.array([[3.0, 1.0]]), np.array([[0.0, -0.5]]), np.array([0.3]),
                  np.eye(4)[None], reversals=np.array([1]))
    for t_s, v_max in ((0.0, 0.0), (4.9, 0.0), (5.0, np.inf), (8.0, np.inf)):
        stack._t_s = t_s  # creeping 0.4 m on along the path meanwhile: no gain
        assert stack.yield_decision(pose + [0.05 * t_s, 0.0, 0.0], away).v_max_mps == v_max, t_s
    assert (stack.yielding.progress_reference_m, stack.yielding.progress_since_s) == (2.95, 0.0)
    # 0.5 m along its path from the 2.95 m left at 0 s restarts the clock; then 0.45 m more does
    # not, nor does backing off and coming back
    for t_s, remaining_m, impatient in ((8.5, 2.45, False), (13.4, 2.0, False), (13.5, 2.6, True), (14.0, 2.01, True),
                                        (14.5, 1.95, False)):
        stack._t_s = t_s
        stack.yielding.watch_progress(remaining_m)
        assert stack.yielding.impatient == impatient, t_s
    assert (stack.yielding.progress_reference_m, stack.yielding.progress_since_s) == (1.95, 14.5)
    # the crossing person of test_yielding_stops_short_of_a_crossing_track 0.5 m further up: its
    # sweep meets the path about 1 s after the robot at cruise speed would be there -- within the
    # 2 s slack, so the robot stops short of it (the first sample no waiting place is x = 2.425:
    # gap 0.375 m, v = sqrt(2 * 0.5 * 0.325)); impatient, it keeps 0.5 s (escape_slack_s): it goes
    later = _tracks([[3.0, 4.0]], [[0.0, -0.5]], [0.3])
    stack.yielding.reset()
    stack._t_s = 20.0
    assert stack.yield_decision(np.array([2.05, 2.0, 0.0]), later).v_max_mps == pytest.approx(np.sqrt(0.325), abs=1e-9)
    stack._t_s = 25.0
    assert stack.yield_decision(np.array([2.05, 2.0, 0.0]), later).v_max_mps == np.inf
    # never impatient by default; the settings are checked
    assert YieldingConfig().patience_s == 0.0
    never = NavigationStack(_room(), NavigationConfig())
    never.reset([2.05, 2.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    never.path = np.array([[2.05, 2.0], [5.0, 2.0]])
    for t_s in (0.0, 1000.0):  # 1000 s without progress
        never._t_s = t_s
        assert never.yield_decision(np.array([2.05, 2.0, 0.0]), later).v_max_mps == pytest.approx(np.sqrt(0.325), abs=1e-9)
    assert not never.yielding.impatient
    for key, bad in (("patience_s", -1.0), ("patience_s", float("nan")), ("patience_progress_m", 0.0)):
        with pytest.raises(ConfigError, match=f"YieldingConfig.{key}"):
            dataclasses.replace(stack.config.yielding, **{key: bad})


def test_speed_plan_creeps_to_its_waiting_place_and_falls_back_to_the_gate_when_it_cannot_stop():
    # the person of the yielding example, on the path (x = 3) from 1.5 to 4.5 s; its sweep (grown by
    # 0.5 s each way) covers the path from x = 2.25 m, and within the 3 s waiting horizon the path
    # is no waiting place from x = 2.25 - 0.05 m. From rest at x = 2.05 the robot cannot pass in
    # front (past x = 3 by 1 s, when the grown sweep first touches it), so it waits: its plan
    # starts at one speed level (0.65 / 7 m/s, the
    # fewest levels a step of <= 0.5 m/s^2 * 0.2 s apart), creeping to its waiting place
    stack = _straight_stack(2.05)
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(stack.config.yielding,
                                                                                  speed_plan=True))
    pose = np.array([2.05, 2.0, 0.0])
    crossing = _tracks([[3.0, 3.5]], [[0.0, -0.5]], [0.3])
    assert stack.yield_decision(pose, crossing).v_max_mps == pytest.approx(0.65 / 7, abs=1e-12)
    # at cruise speed it needs 0.42 m to stop, the waiting place ends 0.15 m ahead: no plan keeps
    # clear, so the gate's rule decides -- stop short of the first covered sample, sqrt(0.175) m/s
    stack._last_cmd = np.array([0.65, 0.0])
    decision = stack.yield_decision(pose, crossing)
    assert decision.v_max_mps == pytest.approx(np.sqrt(0.175), abs=1e-9) and decision.wait_gap_m == pytest.approx(0.225)
    # a person reaching the path at 4.4 s, after the robot at cruise speed has passed x = 3.75
    # (2.6 s; the sweep, 0.5 s early, covers x in [2.63, 3.37] at 2.6 s): nothing to yield to
    assert stack.yield_decision(pose, _tracks([[3.0, 4.2]], [[0.0, -0.5]], [0.3])).v_max_mps == np.inf
    # gone past, or beyond the horizon: nothing either
    assert stack.yield_decision(pose, _tracks([[3.0, 1.0]], [[0.0, -0.5]], [0.3])).v_max_mps == np.inf
    assert stack.yield_decision(pose, _tracks([[3.0, 8.0]], [[0.0, -0.5]], [0.3])).v_max_mps == np.inf
    # a 0.3 m track walking along the path 0.6 m beside it at 0.3 m/s, 0.85 m ahead of a robot at
    # cruise speed: within the local planner's margin (0.3 + 0.2 + 0.25 m) it covers the path at
    # [2.45, 3.35] m and drifts on, the robot must slow at once and nowhere ahead (covered within 3 s)
    # may it wait -- no plan, the gate stops it short of 2.425 m: sqrt(2 * 0.5 * 0.325) m/s. With
    # plan_margin_m 0 (the speed plan keeps only both radii clear, 0.5 m) it does not hold the robot
    beside = _tracks([[2.9, 2.6]], [[0.3, 0.0]], [0.3])
    decision = stack.yield_decision(pose, beside)
    assert decision.v_max_mps == pytest.approx(np.sqrt(0.325), abs=1e-9) and decision.wait_gap_m == pytest.approx(0.375)
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(stack.config.yielding,
                                                                                  plan_margin_m=0.0))
    assert stack.yield_decision(pose, beside).v_max_mps == np.inf


def test_speed_cap_keeps_the_arc():
    from slamkit.systems.navigation import speed_capped

    np.testing.assert_allclose(speed_capped(np.array([0.8, 0.4]), 0.5), [0.5, 0.25])
    np.testing.assert_allclose(speed_capped(np.array([-0.3, 0.6]), 0.5), [-0.3, 0.6])
    np.testing.assert_allclose(speed_capped(np.array([0.4, 1.0]), 0.0), [0.0, 0.0])


def test_recovery_backs_off_from_a_wall_towards_free_space():
    from slamkit.control.protocols import LocalWorld

    stack = _straight_stack(0.37)
    world = LocalWorld(distance=stack.distance)
    # 0.27 m from the left wall's surface: the disc is 0.07 m clear, less than the 0.15 m path margin
    assert stack.recovery.back_off(np.array([0.37, 2.0, 0.0]), world) == pytest.approx([0.1, 0.0])  # facing away: forwards
    assert stack.recovery.back_off(np.array([0.37, 2.0, np.pi]), world) == pytest.approx([-0.1, 0.0])  # facing it: backwards
    # heading 1.4 rad (the wall on its left): 0.1 m either way gains 1.7 cm < 2.5 cm -> turn towards
    # the field's gradient (+x): omega = clip(1.5 * -1.4, -0.8, 0.8)
    assert stack.recovery.back_off(np.array([0.37, 2.0, 1.4]), world) == pytest.approx([0.0, -0.8])
    assert stack.recovery.back_off(np.array([1.0, 2.0, 0.0]), world) is None  # clear: back to the path


def test_recovery_heads_for_the_farthest_path_point_it_can_drive_to_straight():
    from slamkit.control.protocols import LocalWorld

    occ = _room().occupied.copy()
    occ[30:, 50:60] = True  # a pillar from the top wall: x in [2.5, 3.0], y >= 1.5
    stack = NavigationStack(OccupancyGrid(occ, 0.05))
    stack.reset([2.1, 1.4, 0.0], np.eye(3) * 1e-4)
    # the path dips under the pillar's corner (2.5, 1.5) and comes back up behind it
    stack.path = np.array([[2.1, 1.4], [2.4, 1.1], [3.1, 1.1], [3.4, 1.4], [3.4, 3.0]])
    world = LocalWorld(distance=stack.distance)
    pose = np.array([2.1, 1.4, 0.0])

    def line_clearance(end):
        line = pose[:2] + np.linspace(0.0, 1.0, 2001)[:, None] * (np.asarray(end) - pose[:2])
        return float(world.clearance_m(line).min())

    # 1 m along the path is (2.976, 1.1): the straight line there passes 0.232 m from the corner,
    # inside the disc + recovery margin (0.25 m). The farthest 5 cm step whose line clears it is
    # 0.85 m along: (2.826, 1.1), line clearance 0.253 m; 0.90 m along: 0.245 m
    assert line_clearance([2.976, 1.1]) == pytest.approx(0.232, abs=1e-3)
    target = stack.recovery.recovery_target(pose, world)
    np.testing.assert_allclose(target, [2.1 + 0.3 + 0.85 - 0.3 * np.sqrt(2), 1.1], atol=1e-9)
    assert line_clearance(target) == pytest.approx(0.253, abs=1e-3)
    assert line_clearance(target + [0.05, 0.0]) == pytest.approx(0.245, abs=1e-3)
    # nothing visible (the robot itself 0.18 m from the corner): the path point 5 cm beyond the
    # nearest, which is (2.275, 1.225) on the first segment
    close = np.array([2.4, 1.35, 0.0])
    np.testing.assert_allclose(stack.recovery.recovery_target(close, world),
                               [2.275 + 0.05 / np.sqrt(2), 1.225 - 0.05 / np.sqrt(2)], atol=1e-9)


def test_safe_stop_is_acted_on():
    from slamkit.control.protocols import LocalWorld

    stack = _straight_stack(1.0)
    pose = np.array([1.0, 2.0, 0.0])
    stack._last_cmd = np.array([0.5, 0.0])
    # braking from 0.5 m/s reaches 0.35 m ahead (see above), from 0.6 m/s 0.2 + 0.06 * 3.5 = 0.41 m:
    # with a surface 0.40 m ahead the 0.6 m/s command loses its safe stop, braking now keeps one
    wall = LocalWorld([[1.5, 2.0]], [0.1], [[0.0, 0.0]])
    cmd, safe = stack.safety.keep_safe_stop(pose, np.array([0.6, 0.0]), wall)
    assert not safe and cmd == pytest.approx([0.4, 0.0]) and stack.no_safe_stop_cycles == 0
    cmd, safe = stack.safety.keep_safe_stop(pose, np.array([0.3, 0.0]), wall)
    assert safe and cmd == pytest.approx([0.3, 0.0])
    # 0.32 m ahead: no braking is free -> the command stands and the cycle is counted
    near = LocalWorld([[1.42, 2.0]], [0.1], [[0.0, 0.0]])
    cmd, safe = stack.safety.keep_safe_stop(pose, np.array([0.6, 0.0]), near)
    assert not safe and cmd == pytest.approx([0.6, 0.0]) and stack.no_safe_stop_cycles == 1


def test_returns_from_inside_the_robot_are_not_obstacles():
    from slamkit.data.sequence import Scan

    stack = NavigationStack(_room())
    stack.reset([3.0, 2.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    angles = np.linspace(-np.pi, np.pi, 360, endpoint=False)
    ranges = np.full(360, np.nan)
    ranges[178:183] = 0.15  # five short readings straight ahead, inside the 0.2 m disc
    ranges[88:93] = 1.0  # five returns 1 m to the right (y = 1): an obstacle
    stack.step(Scan(0.1, angles, ranges, 8.0))
    assert len(stack.last_scan_points) == 5
    np.testing.assert_allclose(stack.last_scan_points[:, 1], 1.0, atol=0.01)


def test_evasion_never_runs_into_a_wall_while_an_arc_stays_clear():
    from slamkit.control.protocols import LocalWorld, Reference, RobotState
    from slamkit.control.rollout import rollout_arcs

    # 0.03 m off the bottom wall (its surface at y = 0.1), driving +x at 0.3 m/s; a forklift (0.4 m
    # + 0.25 m margin) 0.8 m ahead, 0.42 m to the left, coming at (-0.6, -0.3) m/s: no arc is
    # admissible, and every candidate is predicted to touch it at the first step. Among the
    # window's held arcs the best (the larger smallest clearance) is (0.4, -0.03), -0.666 m; the
    # arc that would score better, (0.4, -0.3), turns 0.19 m into the wall within 2 s and is
    # never taken. With the braking profiles the evasion also sees braking on to back off at
    # -0.3 m/s while turning to -0.75 rad/s: smallest clearance -0.612 m, ending at (2.73, 0.665)
    # away from both, its first command (0.2, -0.3) (one 0.1 s step of the 1 m/s^2, 3 rad/s^2
    # limits; ``evade_brake_profiles``); it never comes nearer the wall than the 0.229 m where it starts
    stack = _straight_stack(3.0)
    pose = np.array([3.0, 0.33, 0.0])
    stack.path = np.array([[3.0, 0.33], [5.5, 0.33]])
    world = LocalWorld([[3.8, 0.75]], [0.65], [[-0.6, -0.3]], stack.distance, 0.0)
    state = RobotState(pose, np.array([0.3, 0.0]), 0.0)
    out = stack.controller.compute(state, Reference(stack.path, speed_mps=0.5), world)
    assert out.status.value == "fallback_brake"
    # the held evasion (held arcs only; SafetyConfig's own default) takes (0.4, -0.03)
    stack.config = dataclasses.replace(stack.config, safety=SafetyConfig())
    cmd = stack.safety.evade(state, world, out)
    assert cmd == pytest.approx([0.4, -0.03], abs=1e-9)
    held = rollout_arcs(pose, cmd[None], 0.1, 20)[0]
    assert stack.distance.query(held[:, :2])[0].min() > stack.config.robot_radius_m
    stack.config = dataclasses.replace(stack.config, safety=dataclasses.replace(stack.config.safety, evade_brake_profiles=True))
    cmd = stack.safety.evade(state, world, out)
    assert cmd == pytest.approx([0.2, -0.3], abs=1e-9)
    first, profiles = stack.safety.brake_profiles(state, 20, 0.1)
    chosen = profiles[1]  # v -> -0.3 m/s, omega -> -0.75 rad/s (order: v_end major, omega_end minor)
    assert first[1] == pytest.approx(cmd)
    np.testing.assert_allclose(chosen[-1, :2], [2.728, 0.665], atol=2e-3)
    assert stack.distance.query(chosen[:, :2])[0].min() > stack.config.robot_radius_m


def test_ramped_evasion_turns_a_backing_robot_round_before_it_is_run_into():
    from slamkit.control.protocols import ControlOutput, ControlStatus, LocalWorld, RobotState
    from slamkit.control.rollout import rollout_arcs

    # backing at -0.3 m/s along y = 2 with a person (0.25 m + 0.25 m margin) 1.3 m behind coming at
    # 0.6 m/s (issue 33: office 429, Willow 428 were hit from behind while backing off). The
    # held arcs of the one-cycle window (v -0.3 .. -0.2 m/s) all back into it within 0.8 s, later
    # only standing (1.0 s): the held evasion brakes. The ramped one accelerates forwards at
    # 1 m/s^2 to 0.531 m/s: never nearer than 0.24 m over 3 s, at x = 3.545 m by then
    stack = _straight_stack(2.0)
    pose = np.array([2.0, 2.0, 0.0])
    world = LocalWorld([[0.7, 2.0]], [0.5], [[0.6, 0.0]], stack.distance, 0.0)
    state = RobotState(pose, np.array([-0.3, 0.0]), 0.0)
    arcs = rollout_arcs(pose, stack.controller.candidates(state), 0.1, 20)
    out = ControlOutput(np.zeros(2), ControlStatus.FALLBACK_BRAKE, candidates_xytheta=arcs, chosen=-1)
    held_clear = world.clearance_m(arcs[..., :2], 0.1 * np.arange(21)) - stack.config.robot_radius_m
    assert np.argmax(held_clear <= 0.0, axis=1).max() == 8 and (held_clear <= 0.0).any(axis=1).all()
    stack.config = dataclasses.replace(stack.config, safety=SafetyConfig())  # held: SafetyConfig's own default
    assert stack.safety.evade(state, world, out) == pytest.approx([0.0, 0.0])
    assert stack.safety.evasion_xytheta is None
    stack.config = dataclasses.replace(stack.config, safety=SafetyConfig(evasion="ramped"))
    cmd = stack.safety.evade(state, world, out)
    assert cmd == pytest.approx([-0.2, 0.0], abs=1e-12)
    chosen = stack.safety.evasion_xytheta
    assert chosen.shape == (31, 3)
    clear = world.clearance_m(chosen[:, :2], 0.1 * np.arange(31)) - stack.config.robot_radius_m
    assert clear.min() == pytest.approx(0.24, abs=1e-9)
    np.testing.assert_allclose(chosen[-1], [3.545, 2.0, 0.0], atol=1e-9)
    with pytest.raises(ConfigError, match="evasion"):
        SafetyConfig(evasion="swerve")
    for bad in ({"evade_horizon_s": float("nan")}, {"evade_horizon_s": 1e9}, {"evade_grid": (9,)},
                {"evade_grid": (9, 10**6)}, {"evade_grid": (9.5, 11)}):
        with pytest.raises(ConfigError, match="evade_"):
            SafetyConfig(evasion="ramped", **bad)


def test_brake_profiles_stop_or_back_off_within_the_acceleration_limits():
    from slamkit.control.protocols import RobotState

    # from (0.3, 0.0): v falls by 0.1 m/s per 0.1 s step to 0 (stop) or to -0.3 (back off), omega
    # rises by 0.3 rad/s per step towards one of -1.5 .. 1.5 rad/s
    stack = _straight_stack(1.0)
    state = RobotState(np.array([1.0, 2.0, 0.0]), np.array([0.3, 0.0]), 0.0)
    first, traj = stack.safety.brake_profiles(state, 20, 0.1)
    assert first.shape == (10, 2) and traj.shape == (10, 21, 3)
    np.testing.assert_allclose(first[:, 0], 0.2)
    np.testing.assert_allclose(np.sort(np.unique(first[:, 1].round(9))), [-0.3, 0.0, 0.3])
    straight = traj[np.flatnonzero((first[:, 1] == 0.0))]
    # straight stop: 0.2 and 0.1 m/s for a step each: 0.03 m on; straight back-off: 0.2, 0.1, 0,
    # -0.1, -0.2, then -0.3 m/s for the remaining 15 steps: 0.1 * (0.3 - 0.3 - 4.5) = -0.45 m net
    np.testing.assert_allclose(sorted(straight[:, -1, 0] - 1.0), [-0.45, 0.03], atol=1e-9)


def test_shuttle_centres_turn_at_the_span_ends_but_not_at_one_still_being_pushed_out():
    from slamkit.systems.navigation import shuttle_centres

    # span x = 1 .. 3 on y = 0; at x = 2.5 moving +x at 0.5 m/s: 3.0 at 1 s (the end), back to
    # 2.5 at 2 s, 1.5 at 4 s; a second one at the end x = 3 moving out keeps going (3.5 at 1 s)
    span = np.array([[[1.0, 0.0], [3.0, 0.0]]] * 2)
    c = shuttle_centres(np.array([[2.5, 0.2], [3.0, 0.0]]), np.array([[0.5, 0.1], [0.4, 0.0]]),
                        np.array([0.5, 0.5]), span, np.array([0.0, 1.0, 2.0, 4.0]))
    np.testing.assert_allclose(c[:, 0], [[2.5, 0.0], [3.0, 0.0], [2.5, 0.0], [1.5, 0.0]], atol=1e-12)
    np.testing.assert_allclose(c[:, 1], [[3.0, 0.0], [3.5, 0.0], [4.0, 0.0], [5.0, 0.0]], atol=1e-12)


def _line_tracks(xy, velocity, radius, span, reversals=(0, 0)):
    from slamkit.estimation.obstacle_tracker import Tracks

    n = len(radius)
    return Tracks(np.arange(n), np.asarray(xy, float), np.asarray(velocity, float), np.asarray(radius, float),
                  np.tile(np.eye(4), (n, 1, 1)), reversals=np.asarray(reversals), span_xy_m=np.asarray(span, float))


def _span_and_crossing(crossing_x_m: float):
    """Track B (r 0.25) seen walking up x = 2.2 from y = 0.5 to 3.5 and walking on, away; track A
    (r 0.3) at (crossing_x_m, 3.5) walking down at 0.5 m/s; a stack at x = 0.8 whose path runs along
    y = 2 to x = 5.5. Returns (stack, tracks)."""
    b = ([2.2, 3.5], [0.0, 0.3], 0.25, [[2.2, 0.5], [2.2, 3.5]])
    a = ([crossing_x_m, 3.5], [0.0, -0.5], 0.3, [[crossing_x_m, 3.5], [crossing_x_m, 3.5]])
    tracks = _line_tracks([b[0], a[0]], [b[1], a[1]], [b[2], a[2]], [b[3], a[3]])
    stack = _straight_stack(0.8)
    stack.path = np.array([[0.8, 2.0], [5.5, 2.0]])
    return stack, tracks


def test_yielding_waits_outside_every_sweep_and_seen_span_and_backs_off_to_such_a_place():
    # the path along y = 2 from x = 0.8. Track B (r 0.25) has been seen walking up x = 2.2 from
    # y = 0.5 to 3.5 and walks on, away: its sweep is no conflict, but its seen span grown by
    # r + 0.25 (moving margin) + 0.2 (robot) covers |x - 2.2| <= 0.7 of the path. Track A (r 0.3,
    # at (4, 3.5), walking down at 0.5 m/s) crosses the path at x = 4 when the robot would get
    # there: a conflict, whose sweep starts at x = 3.25
    stack, tracks = _span_and_crossing(4.0)
    # standing at x = 0.8 (a waiting place) it stops short of B's span, not between B and A: the
    # path is sampled every 0.075 m, x = 1.475 is the first sample within the 5 cm wait margin
    # (0.025 m clear), gap 0.675 m, stop 5 cm short: v = sqrt(2 * 0.5 * 0.625)
    d = stack.yield_decision(np.array([0.8, 2.0, 0.0]), tracks)
    assert d.wait_gap_m == pytest.approx(0.675, abs=1e-9) and d.back_off_xy_m is None
    assert d.v_max_mps == pytest.approx(np.sqrt(0.625), abs=1e-9)
    # (the rule before stopped where A's sweep begins, x = 3.25 less 5 cm: inside B's span)
    # standing inside B's span at x = 2, having come along y = 2 from x = 0.82 (trail every 5 cm):
    # going on would meet A within 0.5 s of its sweep, so it backs off to the nearest trail point
    # 5 cm clear of B's span, x = 1.42 (0.08 m clear; 1.47 is 0.03 m), and reverses towards it at
    # the controller's acceleration: -0.1 m/s after one 0.1 s cycle from standing
    stack.yielding.trail = [np.array([x, 2.0]) for x in 0.82 + 0.05 * np.arange(24)]
    d = stack.yield_decision(np.array([2.0, 2.0, 0.0]), tracks)
    assert d.v_max_mps == 0.0
    np.testing.assert_allclose(d.back_off_xy_m, [1.42, 2.0], atol=1e-9)
    np.testing.assert_allclose(stack.yielding.drive_to(np.array([2.0, 2.0, 0.0]), d.back_off_xy_m), [-0.1, 0.0], atol=1e-12)
    # no trail to back along: it stops where A's sweep begins (the first conflicting point)
    stack.yielding.trail = []
    d = stack.yield_decision(np.array([2.0, 2.0, 0.0]), tracks)
    assert d.back_off_xy_m is None and d.wait_gap_m == pytest.approx(1.275, abs=1e-9)


def test_speed_plan_may_wait_where_it_stands_inside_a_span_when_nothing_is_predicted_there():
    # the robot stands at x = 2 inside B's seen span (|x - 2.2| <= 0.7 of the path, no waiting
    # place), A (r 0.3) crossing x = 3 downwards at 0.5 m/s covers the path from x = 2.25 m between
    # 1.5 and 4.5 s (1 and 5 s with the plan's 0.5 s slack); the next waiting place is past A. The
    # robot cannot stop in B's span, and creeping on at the lowest speed level (0.65 / 7 m/s) it
    # reaches x = 2.25 within A's sweep and no waiting place by 6 s: no plan, so the gate stops it
    # short of A, at x = 2.3 less 5 cm: sqrt(2 * 0.5 * 0.25) = 0.5 m/s. With plan_rest_in_place it may wait where it stands
    # (nothing is predicted at x = 2 within the horizon): the plan inches within its own 7.5 cm
    # cell and waits there, one speed level now
    stack, tracks = _span_and_crossing(3.0)
    pose = np.array([2.0, 2.0, 0.0])
    yielding = dataclasses.replace(stack.config.yielding, speed_plan=True)
    stack.config = dataclasses.replace(stack.config, yielding=yielding)
    d = stack.yield_decision(pose, tracks)
    assert d.v_max_mps == pytest.approx(0.5, abs=1e-9) and d.wait_gap_m == pytest.approx(0.3, abs=1e-9)
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(yielding, plan_rest_in_place=True))
    assert stack.yield_decision(pose, tracks).v_max_mps == pytest.approx(0.65 / 7, abs=1e-12)


def test_yielding_back_off_goes_no_deeper_into_a_lane_with_back_off_outward():
    # the scene of the waiting-places test, the robot at x = 2.6 having come along y = 2 from
    # x = 0.98 (trail every 5 cm): it has crossed B's line (x = 2.2) and stands 0.4 m past it, still
    # inside its span grown by the margins (0.7 m). Going on would meet A: it backs off along its
    # trail to the nearest place 5 cm clear of B's span, x = 1.43 -- back across B's line. With
    # back_off_outward that way goes deeper into the span (clearance -0.7 m on the line against
    # -0.3 m where it stands): no back-off, the gate stops it short of A's sweep (from x = 3.25,
    # first covered sample 2.6 + 9 * 0.075 = 3.275): gap 0.675 m, v = sqrt(2 * 0.5 * 0.625)
    stack, tracks = _span_and_crossing(4.0)
    pose = np.array([2.6, 2.0, 0.0])
    trail = [np.array([x, 2.0]) for x in 0.98 + 0.05 * np.arange(33)]
    stack.yielding.trail = list(trail)
    d = stack.yield_decision(pose, tracks)
    assert d.v_max_mps == 0.0
    np.testing.assert_allclose(d.back_off_xy_m, [1.43, 2.0], atol=1e-9)
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(stack.config.yielding,
                                                                                  back_off_outward=True))
    stack.yielding.trail = list(trail)
    d = stack.yield_decision(pose, tracks)
    assert d.back_off_xy_m is None and d.wait_gap_m == pytest.approx(0.675, abs=1e-9)
    assert d.v_max_mps == pytest.approx(np.sqrt(0.625), abs=1e-9)
    # standing inside the span on the side it came from (x = 2), the way back leads out of it:
    # the same back-off to x = 1.42 as without
    stack.yielding.trail = [np.array([x, 2.0]) for x in 0.82 + 0.05 * np.arange(24)]
    np.testing.assert_allclose(stack.yield_decision(np.array([2.0, 2.0, 0.0]), tracks).back_off_xy_m, [1.42, 2.0],
                               atol=1e-9)


def test_the_goal_approach_slows_in_proportion_to_the_distance():
    # the regulator drives within 0.35 m of the goal: at 0.2 m, straight ahead, the approach speed
    # 0.15 m/s (0.8 / s * 0.2 m = 0.16 is more); at 0.1 m, 0.8 * 0.1 = 0.08 m/s; with
    # approach_gain_per_s 3 (the default), 0.15 again (0.3), and 0.09 m/s at 3 cm
    assert NavigationConfig().goal.approach_gain_per_s == 3.0

    def approach_v(d_m: float, gain: float = 0.8) -> float:
        stack = _straight_stack(1.0)
        stack.config = dataclasses.replace(stack.config, goal=dataclasses.replace(stack.config.goal,
                                                                                  approach_gain_per_s=gain))
        stack.set_goal([1.0 + d_m, 2.0, 0.0])
        out = stack.regulator.regulate(np.array([1.0, 2.0, 0.0]), d_m, _tracks(np.zeros((0, 2)), np.zeros((0, 2)), []))
        assert out.status == "approach" and out.command[1] == 0.0
        return float(out.command[0])

    assert approach_v(0.2) == pytest.approx(0.15, abs=1e-9)
    assert approach_v(0.1) == pytest.approx(0.08, abs=1e-9)
    assert approach_v(0.1, 3.0) == pytest.approx(0.15, abs=1e-9)
    assert approach_v(0.03, 3.0) == pytest.approx(0.09, abs=1e-9)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ConfigError, match="approach_gain_per_s"):
            dataclasses.replace(NavigationConfig().goal, approach_gain_per_s=bad)


#: the lane examples' person: 0.3 m at (3, 2) walking +x at 0.5 m/s, along the straight path from
#: (1, 2) to the goal (5, 2); its lane is its way over 6 s, (3, 2)-(6, 2), grown by its radius, the
#: 0.25 m moving margin and the robot's 0.2 m (0.75 m)
LANE_PERSON_XY_M, LANE_PERSON_VELOCITY_MPS, LANE_PERSON_RADIUS_M = [[3.0, 2.0]], [[0.5, 0.0]], [0.3]


def _lane_example(**planning) -> NavigationStack:
    """A stack in the room at (1, 2) with the goal (5, 2) and ``planning`` fields set."""
    stack = NavigationStack(_room())
    stack.config = dataclasses.replace(stack.config, planning=dataclasses.replace(stack.config.planning, **planning))
    stack.reset([1.0, 2.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    stack.set_goal([5.0, 2.0, 0.0])
    return stack


def _planned_length_and_in_lane_m(stack: NavigationStack, person) -> tuple[float, float]:
    """Plan from (1, 2) and return the path's length and the length of it inside the person's lane."""
    from slamkit.geometry.segments import point_segment_distance

    assert stack.planning.plan(np.array([1.0, 2.0, 0.0]), np.diag([1e-4] * 3), person, np.zeros(0, int))
    inside = point_segment_distance(stack.path, np.array([[3.0, 2.0]]), np.array([[6.0, 2.0]]))[:, 0] <= 0.75
    step = np.linalg.norm(np.diff(stack.path, axis=0), axis=1)
    return float(step.sum()), float(step[inside[1:] & inside[:-1]].sum())


def test_lane_cost_makes_the_global_path_leave_a_moving_tracks_line():
    # Without lane_cost the path runs 2.75 m inside the person's lane (x from 2.25 to the goal);
    # with lane_cost 1 (those cells cost twice) it keeps beside the lane (y ~ 2.78) and enters it
    # only for the goal: under 1 m inside, 0.6 m longer in all
    person = _tracks(LANE_PERSON_XY_M, LANE_PERSON_VELOCITY_MPS, LANE_PERSON_RADIUS_M)
    length, in_lane = _planned_length_and_in_lane_m(_lane_example(lane_cost=0.0), person)
    assert length == pytest.approx(4.0, abs=0.06) and in_lane == pytest.approx(2.75, abs=0.06)
    stack = _lane_example(lane_cost=1.0)
    length_lane, in_lane = _planned_length_and_in_lane_m(stack, person)
    assert in_lane < 1.0 and length_lane - length == pytest.approx(0.6, abs=0.1)
    lanes = stack.planning.lane_cells(person)
    cells = stack.grid.world_to_cell(np.array([[4.0, 2.0], [4.0, 2.8], [2.2, 2.0], [5.9 - 0.05, 2.7]]))
    assert lanes[cells[:, 1], cells[:, 0]].tolist() == [True, False, False, True]
    assert _lane_example(lane_cost=0.0).planning.lane_cells(person) is None
    for key, bad in (("lane_cost", float("nan")), ("lane_cost", -1.0), ("lane_horizon_s", float("nan")),
                     ("lane_horizon_s", -1.0)):
        with pytest.raises(ConfigError, match=f"GlobalPlanningConfig.{key}"):
            dataclasses.replace(stack.config.planning, **{key: bad})


def test_a_robot_without_progress_for_detour_after_s_plans_round_the_lanes():
    # the lane example with lane_cost 0 and detour_after_s 10: while the robot makes progress its
    # path runs 2.75 m inside the lane; after 10 s without 0.5 m of progress the lanes cost
    # detour_lane_cost (2, those cells three times) and it keeps beside the lane; 0.5 m of
    # progress ends that
    stack = _lane_example(lane_cost=0.0, detour_after_s=10.0)
    person = _tracks(LANE_PERSON_XY_M, LANE_PERSON_VELOCITY_MPS, LANE_PERSON_RADIUS_M)
    stack.yielding.watch_progress(4.0)  # 4 m of path left at 0 s
    for t_s, cost in ((0.0, 0.0), (9.9, 0.0), (10.0, 2.0)):
        stack._t_s = t_s
        assert stack.planning.lane_cost() == cost, t_s
    assert _planned_length_and_in_lane_m(stack, person)[1] < 1.0
    stack._t_s = 10.5
    stack.yielding.watch_progress(3.5)
    assert stack.planning.lane_cost() == 0.0
    assert _planned_length_and_in_lane_m(stack, person)[1] == pytest.approx(2.75, abs=0.06)
    # lane_cost when larger keeps its own value; detour_after_s 0 never detours (10 s is the default)
    stack.config = dataclasses.replace(stack.config, planning=dataclasses.replace(stack.config.planning, lane_cost=3.0))
    stack._t_s = 30.0
    assert stack.planning.lane_cost() == 3.0
    stack.config = dataclasses.replace(stack.config, planning=dataclasses.replace(
        stack.config.planning, lane_cost=0.0, detour_after_s=0.0))
    stack._t_s = 1000.0
    assert stack.yielding.stalled_s == 989.5 and stack.planning.lane_cost() == 0.0  # last gain at 10.5 s
    assert GlobalPlanningConfig().detour_after_s == 10.0
    for key, bad in (("detour_after_s", -1.0), ("detour_after_s", float("nan")), ("detour_lane_cost", float("inf")),
                     ("detour_lane_cost", -0.5)):
        with pytest.raises(ConfigError, match=f"GlobalPlanningConfig.{key}"):
            dataclasses.replace(stack.config.planning, **{key: bad})


def test_a_rollout_held_at_its_end_meets_a_track_walking_into_where_it_stops():
    from slamkit.control.protocols import ControlOutput, ControlStatus, RobotState

    # the robot at (1, 2) facing +x drives 0.5 m/s straight for the DWA's 2 s horizon, to x = 2.
    # A 0.3 m person walks at it along y = 2 from x = 4.5 at 0.5 m/s; grown by the 0.25 m moving
    # margin and the robot's 0.2 m it touches the robot standing at x = 2 when 4.5 - 0.5 t - 2 <=
    # 0.75, t >= 3.5 s: after the horizon (DWA's "it can stop before it" holds), within 2 s of rest
    stack = _straight_stack(1.0)
    state = RobotState(np.array([1.0, 2.0, 0.0]), np.array([0.5, 0.0]), 0.0)
    traj = stack.controller.rollouts(state, np.array([[0.5, 0.0]]), 20)
    out = ControlOutput(np.array([0.5, 0.0]), ControlStatus.OK, candidates_xytheta=traj, chosen=0)
    world = stack.local_world(_tracks([[4.5, 2.0]], [[-0.5, 0.0]], [0.3]))
    checks = {}
    for rest in (0.0, 1.0, 1.4, 1.6, 2.0):
        stack.config = dataclasses.replace(stack.config, safety=dataclasses.replace(stack.config.safety, rest_check_s=rest))
        checks[rest] = stack.safety.chosen_hits(world, out)
    assert checks == {0.0: False, 1.0: False, 1.4: False, 1.6: True, 2.0: True}


def test_at_the_goal_a_robot_about_to_be_run_into_evades():
    # standing at (2, 2): a person 2 m ahead walking at it (0.5 m/s) touches it (0.75 m reach) at
    # t = 2.5 s, within the 2 s horizon + 2 s of rest; walking across 2 m away, or with
    # rest_check_s 0, it does not count. Threatened, the stack leaves the regulator: the
    # evasion's command, the phase back to driving (it approaches again once clear)
    stack = _straight_stack(2.0)
    stack.config = dataclasses.replace(stack.config, safety=dataclasses.replace(stack.config.safety, rest_check_s=2.0))
    stack.set_goal([2.0, 2.0, 0.0])
    pose = np.array([2.0, 2.0, 0.0])
    at_it = _tracks([[4.0, 2.0]], [[-0.5, 0.0]], [0.3])
    assert stack.safety.threatened(pose, at_it, 0.0)
    assert not stack.safety.threatened(pose, _tracks([[4.0, 2.0]], [[0.0, 0.5]], [0.3]), 0.0)
    decision = stack.safety.escape(pose, at_it, 0.0)
    assert decision.status == "evading" and stack.regulator.phase == "driving"
    stack.config = dataclasses.replace(stack.config, safety=dataclasses.replace(stack.config.safety, rest_check_s=0.0))
    assert not stack.safety.threatened(pose, at_it, 0.0)


def test_back_off_retraces_the_trail_round_its_bend():
    # the robot came up x = 1 from y = 1 to 2, then along y = 2 to x = 2 (a trail point every 5 cm)
    # and stands at (2.01, 2) facing +x; it backs off to (1, 1.2), round the bend. It steers at
    # the trail point 0.25 m back, (1.75, 2) -- straight behind it, so it reverses without turning
    # (-0.1 m/s: one cycle's acceleration from standing) -- not at the place itself, which would
    # cut the corner (the old rule, back_off_along_trail off, turns towards it)
    stack = _straight_stack(2.01)
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(stack.config.yielding, back_off_along_trail=True))
    up = [np.array([1.0, y]) for y in 1.0 + 0.05 * np.arange(20)]
    along = [np.array([x, 2.0]) for x in 1.0 + 0.05 * np.arange(21)]
    stack.yielding.trail = up + along
    pose, place = np.array([2.01, 2.0, 0.0]), np.array([1.0, 1.2])
    aim = stack.yielding.back_off_aim(pose, place)
    np.testing.assert_allclose(aim, [1.75, 2.0], atol=1e-12)
    np.testing.assert_allclose(stack.yielding.drive_to(pose, place, aim), [-0.1, 0.0], atol=1e-12)
    # backing off keeps the trail between the place and the robot (it drives back along it)
    stack.yielding.record_trail(pose, place)
    assert len(stack.yielding.trail) == 41
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(stack.config.yielding, back_off_along_trail=False))
    np.testing.assert_allclose(stack.yielding.back_off_aim(pose, place), place)
    assert abs(stack.yielding.drive_to(pose, place, place)[1]) > 0.1
    stack.yielding.record_trail(pose, place)
    assert len(stack.yielding.trail) == 5  # the old rule: up to the place only


def test_yield_hedge_treats_a_track_never_seen_reversing_as_one_that_may_turn_back():
    from slamkit.estimation.obstacle_tracker import Tracks

    # the receding person of test_yielding_to_a_shuttler_that_may_turn_back, never seen
    # reversing: constant velocity (yielding.hedge 0, the default) says no yield; with yielding.hedge
    # 1 its reachable set covers the robot's place within the horizon: it stops where it is
    stack = _straight_stack(2.05)
    pose = np.array([2.05, 2.0, 0.0])
    away = Tracks(np.arange(1), np.array([[3.0, 1.0]]), np.array([[0.0, -0.5]]), np.array([0.3]), np.eye(4)[None])
    assert stack.yield_decision(pose, away).v_max_mps == np.inf
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(stack.config.yielding, hedge=1.0))
    assert stack.yield_decision(pose, away).v_max_mps == 0.0
    with pytest.raises(ConfigError):
        YieldingConfig(hedge=1.5)


def test_yield_turning_keeps_giving_way_to_a_shuttler_slowed_at_its_turn():
    from slamkit.estimation.obstacle_tracker import Tracks

    # a shuttler (r 0.3, typically 0.5 m/s, seen reversing along x = 3 from y = -1.5 to 1) brakes
    # at its turn 1 m from the path: its filtered speed is 0.05 m/s, under blocking_speed_mps
    # (0.15), so plain yielding drops it and the robot at (2.05, 2) drives on into its lane. With
    # yielding.turning its typical speed keeps it traffic, predicted by the reachable set of the speed
    # it lost (hedge 1 - 0.05 / 0.5 = 0.9): it covers the path ahead, the robot stays where it is
    def shuttler(y_m: float) -> Tracks:
        return Tracks(np.arange(1), np.array([[3.0, y_m]]), np.array([[0.0, 0.05]]), np.array([0.3]), np.eye(4)[None],
                      reversals=np.array([1]), speed_typical_mps=np.array([0.5]),
                      span_xy_m=np.array([[[3.0, -1.5], [3.0, 1.0]]]))

    stack = _straight_stack(2.05)
    pose = np.array([2.05, 2.0, 0.0])
    assert stack.yield_decision(pose, shuttler(1.0)).v_max_mps == np.inf
    stack.config = dataclasses.replace(stack.config, yielding=dataclasses.replace(stack.config.yielding, turning=True))
    d = stack.yield_decision(pose, shuttler(1.0))
    assert d.v_max_mps == 0.0 and d.wait_gap_m == 0.0
    # turning at the far end of its lane, 3 m from the path, it reaches no point of the path
    # within the slack of the robot's passing: no yield
    assert stack.yield_decision(pose, shuttler(-1.0)).v_max_mps == np.inf


def test_escape_check_keeps_an_escape_from_a_person_turning_back():
    # following a person (0.3 m, +0.25 m margin) who walks away along the robot's line at 0.5 m/s,
    # in the 6 m x 4 m room, at 0.65 m/s. Were the person to turn back now, after the 0.3 s the
    # tracker needs to see it, some ramped profile must stay clear of the walls and of the person
    # both going on and coming back, for 3 s: 2.5 m ahead one does; 2.05 m ahead only after
    # braking (the guard brakes one cycle, 0.65 -> 0.55 m/s); 1.6 m ahead not even then (contact
    # 0.75 m, the gap closing at 1.15 m/s: the command stands, braking would not help either).
    # Measured in 1 cm steps: braking keeps an escape from 1.99 m, the command from 2.10 m
    stack = _straight_stack(1.0)
    stack.config = dataclasses.replace(stack.config, safety=SafetyConfig(evasion="ramped", escape_reaction_s=0.3))
    stack._last_cmd = np.array([0.65, 0.0])
    pose, cmd = np.array([1.0, 2.0, 0.0]), np.array([0.65, 0.0])
    expected = {2.5: ([0.65, 0.0], False), 2.05: ([0.55, 0.0], True), 1.6: ([0.65, 0.0], False)}
    for ahead_m, (command, braked) in expected.items():
        tracks = _tracks([[1.0 + ahead_m, 2.0]], [[0.5, 0.0]], [0.3])
        out, did = stack.safety.keep_escapable(pose, cmd, stack.local_world(tracks), tracks)
        assert out == pytest.approx(command, abs=1e-12) and did is braked, ahead_m
    # the turned-back world: the track's disc twice, the second with the velocity reversed
    tracks = _tracks([[3.0, 2.0]], [[0.5, 0.0]], [0.3])
    turned = stack.safety.turned_back_world(stack.local_world(tracks), tracks)
    np.testing.assert_allclose(turned.circles_at([2.0])[0], [[4.0, 2.0], [2.0, 2.0]])
    np.testing.assert_allclose(turned.circle_radius_m, [0.55, 0.55])
    # a slow track is no traffic: no second disc, and off (0 s) the command is never touched
    slow = _tracks([[2.0, 2.0]], [[0.1, 0.0]], [0.3])
    assert stack.safety.turned_back_world(stack.local_world(slow), slow).num_circles == 1
    stack.config = dataclasses.replace(stack.config, safety=SafetyConfig(evasion="ramped"))
    tracks = _tracks([[2.6, 2.0]], [[0.5, 0.0]], [0.3])
    assert stack.safety.keep_escapable(pose, cmd, stack.local_world(tracks), tracks) == (pytest.approx(cmd), False)
    for bad in (-0.1, 5.0, float("nan")):
        with pytest.raises(ConfigError, match="escape_reaction_s"):
            SafetyConfig(escape_reaction_s=bad)


def test_a_line_of_sight_carrot_leads_dwa_round_a_hook_where_the_plain_carrot_stalls():
    """Willow development seed 3060 (issue 33): the path hooks round a one-cell obstacle, DWA's
    plain carrot lies behind it and the robot turns on the spot between recoveries until the 90 s
    limit (measured: 6 recoveries, 0.16 m short); with ``line_of_sight_target`` the carrot stays
    where the robot sees the path and it drives round the hook (measured: 27.6 s, no recovery,
    final error 1.0 cm). Both with the course's DWA weights, as the stack's default."""
    sc = make_navigation_scenario(3060, "willow", willow_yaml("willow"))
    outcome = {}
    for on in (False, True):
        nav = dataclasses.replace(NavigationConfig(), controller_params={
            **default_controller_params(NavigationConfig()), "line_of_sight_target": on})
        outcome[on] = run_episode(sc, nav, EpisodeConfig()).metrics
    assert outcome[False]["timeout"] == 1.0 and outcome[False]["recoveries"] >= 4
    m = outcome[True]
    assert m["success"] == 1.0 and m["recoveries"] == 0.0 and m["time_s"] < 40.0
    assert m["collision_static"] == 0.0 and m["collision_moving"] == 0.0
