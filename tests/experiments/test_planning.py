"""plan_on_map: the library function behind ``slamkit plan`` (numbers against the MovingAI
scenario optimum), its recording hook, and maps that are not grid maps."""

from __future__ import annotations

import math

import pytest

from slamkit.errors import DataError
from slamkit.experiments.planning import plan_all, plan_on_map


def test_plan_on_a_registry_map_matches_the_scenario_optimum(shared_datasets) -> None:
    # arena.map.scen line 4: (1, 13) -> (4, 12), optimal length 3.41421
    planned = plan_on_map("arena", (1.5, 13.5), (4.5, 12.5))
    assert planned.result.solved and planned.result.planner == "astar"
    assert planned.result.cost == pytest.approx(3.41421, abs=1e-5)
    assert (planned.grid.width, planned.grid.height) == (49, 49)
    seen = []

    def run(problem, planners):
        seen.append((problem, sorted(planners)))
        return plan_all(problem, planners)

    rrt = plan_on_map("arena", (1.5, 13.5), (4.5, 12.5), "rrt_connect", seed=2, run=run, max_iterations=500)
    assert seen[0][0] is rrt.problem and seen[0][1] == ["rrt_connect"]
    # any-angle paths may undercut the 8-connected optimum but never the straight line
    assert rrt.result.solved and rrt.result.cost >= math.hypot(3.0, 1.0) - 1e-9


def test_a_dataset_that_is_not_a_grid_map_is_refused(shared_datasets) -> None:
    with pytest.raises(DataError, match="dataset 'intel' is a .* not a grid map"):
        plan_on_map("intel", (0.0, 0.0), (1.0, 1.0))
