"""The planning benchmark's scenes and table (speed itself is only printed by `slamkit bench`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slamkit.planning.astar import AStarPlanner
from slamkit.bench.planning import ompl_rrt_star, scenes, table, walls_map
from slamkit.planning.grid_search import search_python
from slamkit.planning.protocols import PlanningProblem


def test_walls_map_forces_a_snaking_path():
    grid = walls_map(100, spacing=20, thickness=2, gap=10)
    # walls at x = 20, 40, 60, 80, alternately open at the top and the bottom
    assert grid.occupied[:, 20].sum() == 90 and grid.occupied[:, 40].sum() == 90
    assert not grid.occupied[95, 20] and not grid.occupied[5, 40]
    s, g = grid.cell_to_world(np.array([[5, 5], [95, 95]]))
    r = AStarPlanner().plan(PlanningProblem(grid, s, g))
    assert r.solved and r.cost > 4 * 80  # four crossings of ~80 cells each
    ref = search_python(np.where(grid.occupied, np.inf, 1.0), 5 * 100 + 5, 95 * 100 + 95)
    assert ref.cost == pytest.approx(r.cost, abs=1e-9)


def test_table_rows(shared_datasets):
    rows = table(quick=True, planners=["astar", "dijkstra", "dstar_lite", "prm"], runs=2)
    by = {(r["world"], r["planner"]): r for r in rows}
    grid_lengths = {by[("den312d", p)]["length_m"] for p in ("astar", "dijkstra", "dstar_lite")}
    assert max(grid_lengths) - min(grid_lengths) < 1e-9
    assert by[("den312d", "astar")]["expansions"] < by[("den312d", "dijkstra")]["expansions"]
    assert ("circles10", "astar") not in by  # grid planners skip continuous worlds
    for row in rows:
        assert row["success"] == 1.0 and row["clearance_m"] >= 0.0 and row["smoothness"] >= 0.0
    assert by[("circles10", "prm")]["length_m"] >= math.hypot(9, 9)
    # any-angle roadmap paths undercut the 8-connected optimum on the grid (measured 103.0 vs 107.7)
    assert by[("den312d", "prm")]["length_m"] < by[("den312d", "astar")]["length_m"]


def test_ompl_reference_runs_on_the_same_scene():
    pytest.importorskip("ompl")
    problem = scenes(True)["circles10"]
    out = ompl_rrt_star(problem, 0.3)
    assert out is not None and out["iterations"] > 0
    assert math.hypot(9, 9) <= out["cost"] < 16.0
