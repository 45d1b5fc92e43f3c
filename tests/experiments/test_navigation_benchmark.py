"""The navigation benchmark's protocol (development seeds vs evaluation blocks), optimal path
and summaries, on hand-computable cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slamkit.errors import ConfigError
from slamkit.experiments.pipeline import check_pipeline
from slamkit.experiments.navigation.benchmark import (ALL_EVAL, benchmark_markdown, benchmark_rows, difficulty_rows,
                                                      episode_benchmark_metrics, goals_check, optimal_path_xy_m,
                                                      seed_blocks)
from slamkit.experiments.results import RunRecord
from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.occupancy_grid import OccupancyGrid


def test_seed_blocks_are_disjoint_and_labelled():
    blocks = seed_blocks([0, 1, 2], {"start": 1000, "blocks": 3, "block_size": 2})
    assert blocks == [("dev", 0), ("dev", 1), ("dev", 2), ("eval1", 1000), ("eval1", 1001),
                      ("eval2", 1002), ("eval2", 1003), ("eval3", 1004), ("eval3", 1005)]
    assert seed_blocks([4], None) == [("dev", 4)]
    with pytest.raises(ConfigError, match="eval2 .*shares seeds \\[1002\\]"):
        seed_blocks([1002], {"start": 1000, "blocks": 3, "block_size": 2})


def test_config_refuses_evaluation_seeds_that_were_developed_on():
    config = {"pipeline": "navigation",
              "scenarios": {"seeds": {"start": 0, "count": 30}, "evaluation": {"start": 29, "blocks": 1}}}
    with pytest.raises(ConfigError, match="scenarios.*shares seeds \\[29\\]"):
        check_pipeline(config)
    config["scenarios"]["evaluation"] = {"start": 30, "blocks": 1, "block_sizes": 3}
    with pytest.raises(ConfigError, match="block_sizes"):
        check_pipeline(config)
    config["scenarios"]["evaluation"] = {"start": 30}
    check_pipeline(config)


def _room(wall_top_m: float | None) -> OccupancyGrid:
    """A 10 m x 10 m room at 5 cm with walls round it and, optionally, an internal wall along
    x = 5.0-5.05 m from the floor up to ``wall_top_m``."""
    occ = np.zeros((200, 200), bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    if wall_top_m is not None:
        occ[: int(round(wall_top_m / 0.05)), 100] = True
    return OccupancyGrid(occ, 0.05)


def test_optimal_path_is_straight_in_the_open_and_bends_round_a_wall():
    grid = _room(None)
    path = optimal_path_xy_m(grid, (2.0, 5.0), (8.0, 5.0), 0.2, distance_field_m(grid))
    assert np.linalg.norm(np.diff(path, axis=0), axis=1).sum() == pytest.approx(6.0, abs=1e-9)
    # a wall up to y = 7 m between them: round its end, whose nearest free point for a disc of
    # 0.2 m sits 0.2 m above the end cell's centre (5.025, 6.975): 2 * hypot(3.0, 2.0 + 0.175 + 0.025)
    # = 7.44 m, within a cell of the grid's discretisation (8-connected A* alone: ~8.2 m)
    grid = _room(7.0)
    field = distance_field_m(grid)
    path = optimal_path_xy_m(grid, (2.0, 5.0), (8.0, 5.0), 0.2, field)
    length = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    assert length == pytest.approx(2 * math.hypot(3.0, 2.2), abs=0.1)
    # the path keeps the disc off the wall: every vertex farther than 0.2 m from it
    ij = np.floor(path / 0.05).astype(int)
    assert np.all(field[ij[:, 1], ij[:, 0]] > 0.2)
    # no way through: empty
    occ = grid.occupied.copy()
    occ[:, 100] = True
    closed = OccupancyGrid(occ, 0.05)
    assert optimal_path_xy_m(closed, (2.0, 5.0), (8.0, 5.0), 0.2, distance_field_m(closed)).shape == (0, 2)


def test_oracle_delay_of_a_shuttle_crossing_the_path():
    from slamkit.experiments.navigation.benchmark import scenario_difficulty
    from slamkit.sim.moving_obstacles import MovingObstacles
    from slamkit.sim.navigation_world import NavigationScenario

    # the open room, path (2, 5) -> (8, 5), robot 0.2 m at up to 0.65 m/s; a 0.3 m shuttle crossing
    # x = 5 upwards at 0.65 m/s, at the path (phase 0 from (5, 2)) at 3 / 0.65 s -- when a robot at
    # top speed would be there. In (x, 0.65 t) the forbidden set is a disc of radius 0.5 round
    # (5, 5) and the fastest way passes behind it on the tangent: 0.5 sqrt(2) m later, a delay of
    # 0.5 sqrt(2) / 0.65 = 1.088 s (plus at most two lattice steps of 0.05 / 0.65 s)
    grid = _room(None)
    field = distance_field_m(grid)
    path = np.array([[2.0, 5.0], [8.0, 5.0]])

    def scenario(obstacles: MovingObstacles) -> NavigationScenario:
        return NavigationScenario("room_0", 0, grid, np.array([2.0, 5.0, 0.0]), np.array([8.0, 5.0, 0.0]), path,
                                  obstacles)

    crossing = scenario(MovingObstacles([[5.0, 2.0]], [[5.0, 8.0]], [0.65], [0.3], [0.0]))
    d = scenario_difficulty(crossing, 0.2, field, 0.65, 90.0)
    assert d["oracle_feasible"] == 1.0
    assert 0.5 * math.sqrt(2.0) / 0.65 <= d["oracle_delay_s"] <= 0.5 * math.sqrt(2.0) / 0.65 + 2 * 0.05 / 0.65
    # a disc standing on the path: no arrival, the delay is the whole horizon
    parked = scenario(MovingObstacles([[5.0, 5.0]], [[5.0, 5.0]], [0.0], [0.3], [0.0]))
    d = scenario_difficulty(parked, 0.2, field, 0.65, 90.0)
    assert (d["oracle_feasible"], d["oracle_delay_s"]) == (0.0, 90.0)
    # no traffic: no delay; without the robot's speed it is not computed
    assert scenario_difficulty(scenario(MovingObstacles.empty()), 0.2, field, 0.65)["oracle_delay_s"] == 0.0
    assert math.isnan(scenario_difficulty(crossing, 0.2, field)["oracle_delay_s"])


def test_episode_metrics_of_a_hand_episode():
    difficulty = {"optimal_path_length_m": 13.0, "narrowest_passage_m": 1.2, "crossing_agents": 2.0,
                  "agent_speed_max_mps": 0.5}
    # arrived in 26 s having driven 14.3 m; clearance 0.0-2.0 m static, one moving sample of 0.3 m
    m = episode_benchmark_metrics(success=True, collision_static=False, collision_moving=False,
                                  reached_by_belief=True, clearance_static_m=np.linspace(0.0, 2.0, 21),
                                  clearance_moving_m=[np.inf, 0.3, np.inf], time_s=26.0, path_length_m=14.3,
                                  difficulty=difficulty, max_speed_mps=0.65)
    assert m["optimal_time_s"] == pytest.approx(20.0)
    assert m["time_over_optimal"] == pytest.approx(1.3)
    assert m["path_over_optimal"] == pytest.approx(1.1)
    assert m["clearance_static_p5_m"] == pytest.approx(0.1) and m["clearance_moving_p5_m"] == pytest.approx(0.3)
    assert (m["timeout"], m["off_goal"], m["crossing_agents"]) == (0.0, 0.0, 2.0)
    # ran out of time: no time or path ratio, a timeout
    m = episode_benchmark_metrics(success=False, collision_static=False, collision_moving=False,
                                  reached_by_belief=False, clearance_static_m=[1.0], clearance_moving_m=[],
                                  time_s=float("nan"), path_length_m=3.0, difficulty=difficulty, max_speed_mps=0.65)
    assert m["timeout"] == 1.0 and math.isnan(m["time_over_optimal"]) and math.isnan(m["path_over_optimal"])
    assert math.isnan(m["clearance_moving_p5_m"])


def _run(world, seed, block, success=1.0, moving=0.0, agents=2.0, speed=0.5, passage=1.2, time_ratio=1.25):
    metrics = {"success": success, "collision_static": 0.0, "collision_moving": moving,
               "timeout": float(not success and not moving), "time_over_optimal": time_ratio if success else math.nan,
               "path_over_optimal": 1.1 if success else math.nan, "clearance_static_p5_m": 0.4,
               "clearance_moving_p5_m": 1.0, "crossing_agents": agents, "agent_speed_max_mps": speed,
               "narrowest_passage_m": passage}
    return RunRecord(world, "nominal", metrics, seed=seed, params={"block": block})


def _runs():
    # office: block 1 has one moving hit in 30 (seed 1009), block 2 a timeout (seed 1040);
    # warehouse: all 60 succeed; 3 development seeds of office, one failed
    runs = [_run("office", s, "eval1", success=float(s != 1009), moving=float(s == 1009), speed=0.3 + 0.01 * (s % 30))
            for s in range(1000, 1030)]
    runs += [_run("office", s, "eval2", success=float(s != 1040), passage=0.8 if s < 1035 else 2.5)
             for s in range(1030, 1060)]
    runs += [_run("warehouse", s, f"eval{1 + (s - 1000) // 30}", agents=1.0) for s in range(1000, 1060)]
    runs += [_run("office", s, "dev", success=float(s != 2)) for s in range(3)]
    return runs


def test_rows_per_world_block_and_pooled():
    rows = {(r["world"], r["block"]): r for r in benchmark_rows(_runs())}
    b1 = rows["office", "eval1"]
    assert (b1["episodes"], b1["seeds"]) == (30, [1000, 1029])
    s = b1["success_rate"]
    # 29 of 30, Wilson 95%: [0.8333, 0.9941] (hand computation in tests/metrics/test_binomial_intervals.py)
    assert (s["events"], s["trials"]) == (29, 30)
    assert (s["ci_low"], s["ci_high"]) == pytest.approx((0.83330, 0.99409), abs=1e-5)
    assert b1["collision_moving_rate"]["events"] == 1 and b1["timeout_rate"]["events"] == 0
    assert rows["office", "eval2"]["timeout_rate"]["events"] == 1
    pooled = rows["office", ALL_EVAL]
    assert (pooled["success_rate"]["events"], pooled["success_rate"]["trials"]) == (58, 60)
    # the development seeds stay out of every evaluation row
    assert rows["office", "dev"]["episodes"] == 3 and rows["all worlds", ALL_EVAL]["episodes"] == 120
    assert rows["office", ALL_EVAL]["time_over_optimal"] == pytest.approx(1.25)
    assert rows["office", ALL_EVAL]["time_over_optimal_n"] == 58


def test_difficulty_bins_and_goals():
    diff = {(d["factor"], d["bin"]): d for d in difficulty_rows(_runs())}
    assert diff["crossing_agents", "1"]["episodes"] == 60 and diff["crossing_agents", "2"]["episodes"] == 60
    narrow = diff["narrowest_passage_m", "< 1 m"]
    assert narrow["episodes"] == 5 and narrow["success_rate"]["events"] == 5
    # seed 1009 (the moving hit) had speed 0.3 + 0.01 * (1009 % 30) = 0.49 m/s: the fastest bin
    assert diff["agent_speed_max_mps", ">= 0.45 m/s"]["collision_moving_rate"]["events"] == 1
    # the evaluation runs only (the 3 development ones stay out), each in one bin
    assert sum(d["episodes"] for (f, _), d in diff.items() if f == "agent_speed_max_mps") == 120
    goals = goals_check(benchmark_rows(_runs()))
    assert [ok for _, ok, _ in goals] == [True, True, True]   # lowest block 29/30 >= 0.95; 1/120 < 2%
    text = benchmark_markdown(benchmark_rows(_runs()), list(diff.values()),
                              {"dev_seeds": [0, 1, 2], "evaluation": {"start": 1000, "blocks": 2, "block_size": 30}})
    headline = text.split("| office |")[1].split("\n")[0]
    # 58/60 and 1/60 with scipy.stats.binomtest(...).proportion_ci(method="wilson"): [0.8864, 0.9908], [0.0030, 0.0886]
    assert "0.967 [0.886, 0.991]" in headline and "1/60 [0.003, 0.089]" in headline


def test_a_run_records_each_episodes_block(tmp_path):
    import json

    from slamkit.experiments.pipeline import run_pipeline

    config = {"pipeline": "navigation", "name": "nav_blocks",
              "scenarios": {"worlds": ["office"], "seeds": [1], "n_obstacles": 1,
                            "evaluation": {"start": 5, "blocks": 2, "block_size": 1}},
              "episode": {"max_time_s": 2.0}, "record": False}
    check_pipeline(config)
    run_pipeline(config, tmp_path / "out", progress=False)
    res = json.loads((tmp_path / "out" / "results.json").read_text())
    assert [(r["seed"], r["params"]["block"]) for r in res["runs"]] == [(1, "dev"), (5, "eval1"), (6, "eval2")]
    bench = res["benchmark"]
    assert bench["protocol"] == {"dev_seeds": [1], "evaluation": {"start": 5, "blocks": 2, "block_size": 1}}
    rows = {(r["world"], r["block"]): r for r in bench["rows"]}
    # 2 s is too short to arrive: every run a timeout, and the pooled evaluation row has 2 of them
    assert rows["office", ALL_EVAL]["timeout_rate"]["events"] == 2 and rows["office", "dev"]["episodes"] == 1
    for r in res["runs"]:
        m = r["metrics"]
        assert m["optimal_path_length_m"] > 0 and m["clearance_static_p5_m"] >= m["min_clearance_static_m"]
    report = (tmp_path / "out" / "report.md").read_text()
    assert report.index("## Benchmark") < report.index("## Every metric")
    assert (tmp_path / "out" / "plots" / "benchmark.png").is_file()
