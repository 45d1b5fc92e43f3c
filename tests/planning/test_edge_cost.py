"""Grid edge costs: the mean-of-two-cells model (default) and the enter-cell model, worked
examples with hand-computed costs and agreement of every grid planner on the enter model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import PlanningError
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.planning.astar import AStarConfig, AStarPlanner
from slamkit.planning.dijkstra import DijkstraConfig, DijkstraPlanner
from slamkit.planning.dstar_lite import DStarLiteConfig, DStarLitePlanner
from slamkit.planning.grid_search import search
from slamkit.planning.protocols import PlanningProblem

SQRT2 = math.sqrt(2.0)


def _problem(cost: np.ndarray, s_ixy, g_ixy, resolution_m: float = 1.0) -> PlanningProblem:
    grid = OccupancyGrid(~np.isfinite(cost), resolution_m)
    pts = grid.cell_to_world(np.array([s_ixy, g_ixy]))
    return PlanningProblem(grid, pts[0], pts[1], cell_cost=np.where(np.isfinite(cost), cost, 1.0))


def test_row_of_cells_pays_what_it_enters():
    # cells 1 2 3 4 in one row, from the first to the last (4-connected, 0.5 m cells):
    # enter: 2 + 3 + 4 = 9 cells -> 4.5 m; mean: 1.5 + 2.5 + 3.5 = 7.5 cells -> 3.75 m
    cost = np.array([[1.0, 2.0, 3.0, 4.0]])
    p = _problem(cost, (0, 0), (3, 0), resolution_m=0.5)
    enter = AStarPlanner(AStarConfig(connectivity=4, edge_cost="enter")).plan(p)
    mean = AStarPlanner(AStarConfig(connectivity=4)).plan(p)
    assert enter.cost == pytest.approx(4.5)
    assert mean.cost == pytest.approx(3.75)


def test_expensive_start_cell_changes_the_path_only_under_the_mean_model():
    # start (0, 0) costs 10, every other cell 1; goal (1, 1), 8-connected.
    #   diagonal:     enter sqrt2 * 1 = 1.414     mean sqrt2 * (10 + 1) / 2 = 7.778
    #   straight x2:  enter 1 + 1     = 2         mean (10 + 1) / 2 + 1     = 6.5
    # so the enter model goes diagonally and the mean model takes the L
    cost = np.ones((2, 2))
    cost[0, 0] = 10.0
    p = _problem(cost, (0, 0), (1, 1))
    enter = AStarPlanner(AStarConfig(edge_cost="enter")).plan(p)
    mean = AStarPlanner(AStarConfig()).plan(p)
    assert enter.cost == pytest.approx(SQRT2)
    assert len(enter.path) == 2
    assert mean.cost == pytest.approx(6.5)
    assert len(mean.path) == 3


def test_unknown_edge_cost_is_refused():
    with pytest.raises(PlanningError, match="edge_cost"):
        AStarConfig(edge_cost="max")
    with pytest.raises(PlanningError, match="edge_cost"):
        DStarLiteConfig(edge_cost="max")


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(2, 10), st.integers(2, 10), st.sampled_from([4, 8]))
def test_enter_model_agrees_across_planners_and_cores(seed, h, w, conn):
    rng = np.random.default_rng(seed)
    cost = 1.0 + 4.0 * rng.random((h, w))
    cost[rng.random((h, w)) < 0.25] = np.inf
    free = np.argwhere(np.isfinite(cost))
    if len(free) < 2:
        return
    i, j = rng.choice(len(free), 2, replace=False)
    s, t = tuple(free[i][::-1]), tuple(free[j][::-1])
    p = _problem(cost, s, t, resolution_m=0.1)
    ref = DijkstraPlanner(DijkstraConfig(connectivity=conn, edge_cost="enter")).plan(p)
    a = AStarPlanner(AStarConfig(connectivity=conn, edge_cost="enter")).plan(p)
    d = DStarLitePlanner(DStarLiteConfig(connectivity=conn, edge_cost="enter")).plan(p)
    assert a.status is ref.status is d.status
    if not ref.solved:
        return
    assert a.cost == pytest.approx(ref.cost, abs=1e-9)
    assert d.cost == pytest.approx(ref.cost, abs=1e-9)
    # the path's cost under the enter model, recomputed from its cells
    cells = p.world.world_to_cell(a.path)
    steps = np.linalg.norm(np.diff(cells, axis=0), axis=1)
    assert a.cost == pytest.approx(0.1 * float((steps * cost[cells[1:, 1], cells[1:, 0]]).sum()), abs=1e-9)
    native = search(cost, s, t, conn, edge_cost="enter")
    python = search(cost, s, t, conn, edge_cost="enter", use_native=False)
    assert native.cost == pytest.approx(python.cost, abs=1e-9)
