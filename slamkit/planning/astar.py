"""A* on occupancy grids and costmaps.

Hart, Nilsson & Raphael, "A Formal Basis for the Heuristic Determination of Minimum Cost
Paths", IEEE Trans. Systems Science and Cybernetics 4(2), 1968: expand the open vertex with the
smallest f(n) = g(n) + h(n); with an admissible h (never above the true cost-to-go) the first
time the goal is closed its g is optimal. Heuristics (in cells, times resolution and the
smallest cell multiplier): Euclidean, octile (exact on an empty 8-connected grid), Chebyshev,
Manhattan (admissible on 4-connected grids only) and zero (= Dijkstra).

The search loop is in :mod:`slamkit.planning.grid_search` (compiled C with a Python fallback).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from slamkit.planning.grid_search import HEURISTICS, check_edge_cost, search, setup_grid_problem
from slamkit.planning.protocols import (Hook, PlanEvent, PlanResult, PlanStats, PlanStatus,
                                        PlanningProblem, failed)
from slamkit.errors import PlanningError


@dataclass(frozen=True)
class AStarConfig:
    heuristic: str = "octile"
    connectivity: int = 8
    corner_cutting: bool = False
    heuristic_weight: float = 1.0   # > 1: weighted A* (bounded suboptimal by this factor)
    hook_batches: int = 50          # expansion events sent to a hook per search
    #: "mean": a move costs the mean of its two cells' multipliers; "enter": the cell it enters
    edge_cost: str = "mean"

    def __post_init__(self) -> None:
        check_edge_cost(self.edge_cost)
        if self.heuristic not in HEURISTICS:
            raise PlanningError(f"unknown heuristic {self.heuristic!r}; choose from {sorted(HEURISTICS)}")
        if self.connectivity not in (4, 8):
            raise PlanningError(f"connectivity must be 4 or 8, got {self.connectivity}")
        if not self.heuristic_weight >= 1.0:
            raise PlanningError(f"heuristic_weight must be >= 1, got {self.heuristic_weight}")


def report_expansions(hook: Hook, grid, order: np.ndarray, batches: int) -> None:
    """Replay a recorded expansion order to ``hook`` as ``batches`` "expanded" events."""
    w = grid.width
    cells = np.stack([order % w, order // w], axis=1)
    pts = grid.cell_to_world(cells)
    for i, chunk in enumerate(np.array_split(pts, max(1, min(batches, len(pts))))):
        hook(PlanEvent("expanded", i, chunk))


class AStarPlanner:
    name = "astar"

    def __init__(self, config: AStarConfig = AStarConfig(), hook: Hook | None = None):
        self.config = config
        self.hook = hook

    def plan(self, problem: PlanningProblem) -> PlanResult:
        t0 = time.perf_counter()
        setup = setup_grid_problem(problem)
        if setup.status is not None:
            return failed(PlanStatus(setup.status), self.name, time_s=time.perf_counter() - t0)
        cfg = self.config
        hscale = cfg.heuristic_weight * setup.min_cost
        out = search(setup.cell_cost, setup.start_ixy, setup.goal_ixy, cfg.connectivity,
                     cfg.corner_cutting, cfg.heuristic, hscale, record_order=self.hook is not None,
                     edge_cost=cfg.edge_cost)
        elapsed = time.perf_counter() - t0
        grid = setup.grid
        if self.hook is not None and out.order is not None:
            report_expansions(self.hook, grid, out.order, cfg.hook_batches)
        stats = PlanStats(time_s=elapsed, expansions=int(out.expansions), tree_size=out.opened)
        if not np.isfinite(out.cost):
            # the whole component of the start was closed: the goal is provably unreachable
            return PlanResult(PlanStatus.NO_PATH, np.zeros((0, 2)), float("inf"), stats, self.name)
        w = grid.width
        path = grid.cell_to_world(np.stack([out.path % w, out.path // w], axis=1))
        return PlanResult(PlanStatus.SOLVED, path, float(out.cost) * grid.resolution_m, stats, self.name)
