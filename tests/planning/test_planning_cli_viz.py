"""`slamkit plan` end to end (JSON numbers against the MovingAI optimum) and the Rerun recording
of a search (entity tree checked with `rerun rrd verify`)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from slamkit.cli import app
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.planning.protocols import PlanningProblem
from slamkit.planning.registry import make_planner
from slamkit.planning.worlds import PointWorld
from slamkit.viz.planning import record_plans

runner = CliRunner()


def test_cli_json_matches_scenario_optimum(shared_datasets):
    # arena.map.scen line 4: (1, 13) -> (4, 12), optimal length 3.41421
    out = runner.invoke(app, ["plan", "arena", "--start", "1.5,13.5", "--goal", "4.5,12.5", "--json"])
    assert out.exit_code == 0, out.output
    d = json.loads(out.stdout)
    assert d["status"] == "solved" and d["planner"] == "astar"
    assert d["cost"] == pytest.approx(3.41421, abs=1e-5) and d["length"] == pytest.approx(d["cost"])
    assert d["expansions"] >= 3 and d["time_s"] > 0


def test_cli_map_path_inflation_and_statuses(shared_datasets, tmp_path):
    path = shared_datasets / "grid_planning/movingai/dao/arena.map"
    plain = json.loads(runner.invoke(app, ["plan", str(path), "--start", "1.5,13.5", "--goal", "40.5,40.5",
                                           "--planner", "dijkstra", "--json"]).stdout)
    inflated = json.loads(runner.invoke(app, ["plan", str(path), "--start", "3.5,13.5", "--goal", "40.5,40.5",
                                              "--planner", "dijkstra", "--inflate", "1.0", "--json"]).stdout)
    assert plain["status"] == "solved" and inflated["status"] == "solved"
    assert inflated["cost"] > plain["cost"] - 2.5  # inflation never opens shortcuts (start moved 2 cells)
    wall = json.loads(runner.invoke(app, ["plan", "arena", "--start", "0.5,0.5", "--goal", "40.5,40.5", "--json"]).stdout)
    assert wall["status"] == "invalid_start" and wall["cost"] is None
    rrt = runner.invoke(app, ["plan", "arena", "--start", "1.5,13.5", "--goal", "40.5,40.5", "--planner", "rrt_star",
                              "--max-iterations", "400", "--seed", "1", "--json"])
    d = json.loads(rrt.stdout)
    assert d["status"] == "solved" and d["samples"] == 400
    # any-angle paths may undercut the 8-connected optimum but never the straight line
    assert d["cost"] >= math.hypot(39, 27) - 1e-9
    bad = runner.invoke(app, ["plan", "no-such-map", "--start", "0,0", "--goal", "1,1"])
    assert bad.exit_code == 2
    bad_xy = runner.invoke(app, ["plan", "arena", "--start", "1.5", "--goal", "1,1"])
    assert bad_xy.exit_code != 0


def test_recording_has_map_frontier_tree_and_paths(tmp_path, verify_rrd):
    occ = np.zeros((30, 30), bool)
    occ[5:25, 15] = True
    grid = OccupancyGrid(occ, resolution_m=0.5)
    problem = PlanningProblem(grid, [1.0, 7.0], [13.0, 7.0])
    planners = {"astar": make_planner("astar"), "rrt_star": make_planner("rrt_star", max_iterations=300),
                "prm": make_planner("prm", n_samples=200)}
    results = record_plans(tmp_path / "plan.rrd", problem, planners)
    assert all(r.solved for r in results.values())
    entities = verify_rrd(tmp_path / "plan.rrd")
    for e in ("/world/map", "/world/start", "/world/goal", "/world/search/astar/expanded",
              "/world/search/rrt_star/tree", "/world/search/prm/roadmap", "/world/path/astar",
              "/world/path/rrt_star", "/plots/best_cost/rrt_star"):
        assert e in entities, (e, sorted(entities))


def test_recording_of_a_continuous_world(tmp_path, verify_rrd):
    world = PointWorld([[0, 0], [10, 10]], circles=[[5, 5, 2.0]], polygons=[np.array([[1, 6], [3, 6], [2, 8]])])
    problem = PlanningProblem(world, [0.5, 0.5], [9.5, 9.5])
    record_plans(tmp_path / "c.rrd", problem, {"rrt_connect": make_planner("rrt_connect")})
    entities = verify_rrd(tmp_path / "c.rrd")
    assert {"/world/obstacles/circles", "/world/obstacles/polygons", "/world/path/rrt_connect"} <= entities
