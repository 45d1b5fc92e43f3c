"""Pieces shared by the tree-based sampling planners: growable tree storage, budgets, steering,
problem checks. Not a public API."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from slamkit.planning.protocols import Hook, PlanningProblem, PlanStatus, at_goal, failed
from slamkit.planning.worlds import as_world


class SamplingPlanner:
    """What every sampling planner holds: its frozen config, its own seeded generator and an
    optional observation hook."""

    name = "sampling"

    def __init__(self, config, rng: np.random.Generator | None = None, hook: Hook | None = None):
        self.config = config
        self.rng = np.random.default_rng(0) if rng is None else rng
        self.hook = hook


class Tree:
    """Vertices (n, d), parent index (-1 at the root), cost-to-come, growable by doubling."""

    def __init__(self, root: np.ndarray, capacity: int = 1024):
        d = len(root)
        self.nodes = np.empty((capacity, d))
        self.parent = np.full(capacity, -1, dtype=np.int64)
        self.cost = np.empty(capacity)
        self.nodes[0] = root
        self.cost[0] = 0.0
        self.n = 1

    def add(self, x: np.ndarray, parent: int, cost: float) -> int:
        if self.n == len(self.nodes):
            cap = 2 * len(self.nodes)
            self.nodes = np.resize(self.nodes, (cap, self.nodes.shape[1]))
            self.parent = np.resize(self.parent, cap)
            self.cost = np.resize(self.cost, cap)
        i = self.n
        self.nodes[i] = x
        self.parent[i] = parent
        self.cost[i] = cost
        self.n += 1
        return i

    def path_to(self, i: int) -> np.ndarray:
        idx = []
        while i != -1:
            idx.append(i)
            i = int(self.parent[i])
        return self.nodes[idx[::-1]].copy()

    @property
    def view(self) -> np.ndarray:
        return self.nodes[:self.n]


@dataclass
class Budget:
    """Stop after ``max_iterations`` or ``time_limit_s`` (checked every 32 iterations to keep
    the clock off the hot path)."""

    max_iterations: int
    time_limit_s: float

    def __post_init__(self) -> None:
        self.t0 = time.perf_counter()

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def exhausted(self, iteration: int) -> bool:
        if iteration >= self.max_iterations:
            return True
        return (iteration & 31) == 0 and self.elapsed() >= self.time_limit_s


def check_endpoints(problem: PlanningProblem, planner: str):
    """(world, start, goal, None), or (world, start, goal, result) when the answer is known
    before any sampling: INVALID_START / INVALID_GOAL, or SOLVED with the one-point path
    [start] and cost 0 when start equals goal (growing a tree there only finds detours)."""
    from slamkit.errors import PlanningError

    world = as_world(problem.world)
    if problem.start.size != world.dim:
        raise PlanningError(f"{type(world).__name__} states have {world.dim} entries, "
                            f"start/goal have {problem.start.size}")
    start, goal = problem.start.copy(), problem.goal.copy()
    valid = world.is_valid(np.stack([start, goal]))
    if not valid[0]:
        return world, start, goal, failed(PlanStatus.INVALID_START, planner, world.dim)
    if not valid[1]:
        return world, start, goal, failed(PlanStatus.INVALID_GOAL, planner, world.dim)
    if float(world.distance(start, goal[None])[0]) == 0.0:
        return world, start, goal, at_goal(start, planner)
    return world, start, goal, None


def steer(world, a: np.ndarray, b: np.ndarray, max_step: float) -> np.ndarray:
    d = float(world.distance(a, b[None])[0])
    if d <= max_step:
        return b.copy()
    return world.interpolate(a, b, max_step / d)


def default_step(world) -> float:
    """OMPL's default range: 20% of the space's extent."""
    return 0.2 * world.extent
