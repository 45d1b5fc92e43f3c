"""Every planner in the registry keeps the same contract on the edge cases (issue 10)."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import PlanningError
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.planning.protocols import PlanningProblem, PlanStatus
from slamkit.planning.registry import PLANNERS, make_planner

SAMPLING_BUDGET = {"rrt": 500, "rrt_connect": 500, "rrt_star": 500, "informed_rrt_star": 500}


def _grid() -> OccupancyGrid:
    occ = np.zeros((50, 50), bool)
    occ[20:30, 25] = True
    return OccupancyGrid(occ, 0.2)


def _planner(name: str):
    budget = SAMPLING_BUDGET.get(name)
    return make_planner(name, rng=np.random.default_rng(0), **({"max_iterations": budget} if budget else {}))


@pytest.mark.parametrize("name", list(PLANNERS))
def test_start_equal_to_goal_is_solved_at_cost_zero(name) -> None:
    # RRT and RRT-Connect used to return 12-28 m detours here
    result = _planner(name).plan(PlanningProblem(_grid(), np.array([2.0, 2.0]), np.array([2.0, 2.0])))
    assert result.status is PlanStatus.SOLVED
    assert result.cost == 0.0 and result.length_m == 0.0
    # one point: the start itself (grid planners: the centre of its cell, within half a cell)
    assert result.path.shape == (1, 2)
    np.testing.assert_allclose(result.path[0], [2.0, 2.0], atol=0.1 + 1e-12)


@pytest.mark.parametrize("name", list(PLANNERS))
def test_goal_inside_an_obstacle_is_a_status_not_an_exception(name) -> None:
    result = _planner(name).plan(PlanningProblem(_grid(), np.array([2.0, 2.0]), np.array([5.1, 5.0])))
    assert result.status is PlanStatus.INVALID_GOAL and result.cost == float("inf") and len(result.path) == 0


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_endpoints_are_refused_before_any_planner_runs(bad) -> None:
    with pytest.raises(PlanningError, match=r"start/goal must be finite"):
        PlanningProblem(_grid(), np.array([bad, 2.0]), np.array([2.0, 2.0]))
