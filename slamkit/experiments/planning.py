"""Global planning on a named map: the function behind ``slamkit plan``, for notebooks too.

``plan_on_map("den312d", (10.5, 20.5), (60.5, 40.5), "rrt_star", seed=3, max_iterations=2000)``
loads the map (a registry name or a MovingAI ``.map`` file, via
:func:`slamkit.data.registry.load_grid_map_source`), inflates it by the robot radius when asked,
builds the registry planner with its config overrides and plans. Recording is the caller's: pass
``run=functools.partial(slamkit.viz.planning.record_plans, path)`` to watch the search.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from slamkit.data import registry
from slamkit.maps.inflation import inflate
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.planning.protocols import Planner, PlanningProblem, PlanResult
from slamkit.planning.registry import make_planner

#: ``run(problem, {name: planner}) -> {name: result}`` (``slamkit.viz.planning.record_plans``
#: with its path bound records while it plans)
PlanRunner = Callable[[PlanningProblem, Mapping[str, Planner]], Mapping[str, PlanResult]]


@dataclass(frozen=True)
class MapPlan:
    """One planner's answer on a map: the grid planned on (inflated when asked), the problem
    and the result."""

    grid: OccupancyGrid
    problem: PlanningProblem
    result: PlanResult


def plan_all(problem: PlanningProblem, planners: Mapping[str, Planner]) -> dict[str, PlanResult]:
    """Every planner on ``problem``, without recording."""
    return {name: p.plan(problem) for name, p in planners.items()}


def plan_on_map(map_name_or_path: str | Path, start_xy_m, goal_xy_m, planner: str = "astar",
                inflate_m: float = 0.0, seed: int = 0, run: PlanRunner = plan_all,
                **config: Any) -> MapPlan:
    """Plan from ``start_xy_m`` to ``goal_xy_m`` (world metres) on a map with the registry
    ``planner`` (sampling planners draw from ``numpy.random.default_rng(seed)``); ``config``
    overrides the planner's config fields (e.g. ``max_iterations=2000``)."""
    grid = registry.load_grid_map_source(map_name_or_path)
    if inflate_m > 0:
        grid = inflate(grid, inflate_m)
    problem = PlanningProblem(grid, np.asarray(start_xy_m, float), np.asarray(goal_xy_m, float))
    p = make_planner(planner, rng=np.random.default_rng(seed), **config)
    return MapPlan(grid, problem, run(problem, {p.name: p})[p.name])
