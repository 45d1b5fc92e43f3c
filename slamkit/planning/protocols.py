"""The planning contract: ``Planner.plan(problem) -> PlanResult``.

Every planner (grid search and sampling-based) takes a :class:`PlanningProblem` and returns a
frozen :class:`PlanResult`. A start or goal in collision or outside the map is a *status*
(``INVALID_START`` / ``INVALID_GOAL``), never an exception; a malformed problem (wrong
dimensions, NaN coordinates, a world type the planner cannot search) is a
:class:`slamkit.errors.PlanningError`.

Hooks: planners accept ``hook: Callable[[PlanEvent], None] | None``. Grid planners report their
expansion order in batches once the search is done (the compiled loop records it; nothing is
called inside the loop), sampling planners report a snapshot of the tree every few iterations.
The viewer (``slamkit.viz.planning``) subscribes through this hook; planners never log.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol, runtime_checkable

import numpy as np

from slamkit.errors import PlanningError


class PlanStatus(enum.Enum):
    SOLVED = "solved"
    NO_PATH = "no_path"          # proven: the goal is not reachable (complete planners)
    TIMEOUT = "timeout"          # time or iteration budget spent without a solution
    INVALID_START = "invalid_start"
    INVALID_GOAL = "invalid_goal"


@dataclass(frozen=True)
class PlanStats:
    time_s: float = 0.0
    expansions: int = 0          # grid planners: nodes closed
    samples: int = 0             # sampling planners: samples drawn (iterations)
    tree_size: int = 0           # sampling: tree/roadmap vertices; grid: nodes ever opened
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class PlanResult:
    status: PlanStatus
    path: np.ndarray             # (N, d) world coordinates (d = 2 for points, 3 for SE(2)); (0, d) if none
    cost: float                  # path cost under the planner's metric; inf if unsolved
    stats: PlanStats
    planner: str = ""

    @property
    def solved(self) -> bool:
        return self.status is PlanStatus.SOLVED

    @property
    def length_m(self) -> float:
        """Euclidean length of the (x, y) polyline (equals ``cost`` on uniform-cost grids)."""
        if len(self.path) < 2:
            return 0.0 if self.solved else float("inf")
        return float(np.linalg.norm(np.diff(self.path[:, :2], axis=0), axis=1).sum())

    def to_dict(self) -> dict[str, Any]:
        return {"planner": self.planner, "status": self.status.value, "cost": self.cost,
                "length": self.length_m, "time_s": self.stats.time_s,
                "expansions": self.stats.expansions, "samples": self.stats.samples,
                "tree_size": self.stats.tree_size}


@dataclass(frozen=True)
class PlanEvent:
    """What a hook receives.

    kind ``"expanded"``: ``points`` (K, 2) world positions of the cells closed since the last
    event (grid planners). kind ``"tree"``: ``points`` (n, d) all tree vertices, ``parents`` (n,)
    their parent index (-1 at roots), ``best_cost`` the best solution cost so far (sampling)."""

    kind: str
    iteration: int
    points: np.ndarray
    parents: np.ndarray | None = None
    best_cost: float = float("inf")


Hook = Callable[[PlanEvent], None]


@dataclass(frozen=True)
class PlanningProblem:
    """Start and goal in world coordinates, and the world to plan in.

    ``world`` is an :class:`~slamkit.maps.occupancy_grid.OccupancyGrid` (grid planners plan on
    its cells; sampling planners treat it as a point-robot world), a
    :class:`~slamkit.planning.worlds.PointWorld` or an :class:`~slamkit.planning.worlds.SE2World`.
    ``cell_cost`` optionally gives grid planners a per-cell traversal multiplier (>= 1, inf =
    blocked), e.g. from :func:`slamkit.planning.grid_search.costmap_to_cell_cost`.
    ``goal_tolerance`` is the distance (space metric) at which sampling planners count the goal
    as reached; 0 means they must connect to the goal exactly."""

    world: Any
    start: np.ndarray
    goal: np.ndarray
    cell_cost: np.ndarray | None = None
    goal_tolerance: float = 0.0

    def __post_init__(self) -> None:
        start = np.asarray(self.start, dtype=float).reshape(-1)
        goal = np.asarray(self.goal, dtype=float).reshape(-1)
        if start.shape != goal.shape or start.size not in (2, 3):
            raise PlanningError(f"start and goal must both have 2 (x, y) or 3 (x, y, theta) "
                                f"entries, got {start.size} and {goal.size}")
        if not (np.all(np.isfinite(start)) and np.all(np.isfinite(goal))):
            raise PlanningError(f"start/goal must be finite, got {start} and {goal}")
        if self.goal_tolerance < 0 or not np.isfinite(self.goal_tolerance):
            raise PlanningError(f"goal_tolerance must be finite and >= 0, got {self.goal_tolerance}")
        start.setflags(write=False)
        goal.setflags(write=False)
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "goal", goal)


@runtime_checkable
class Planner(Protocol):
    name: str

    def plan(self, problem: PlanningProblem) -> PlanResult: ...


def empty_path(dim: int = 2) -> np.ndarray:
    return np.zeros((0, dim))


def at_goal(start: np.ndarray, planner: str) -> PlanResult:
    """The answer when start equals goal: SOLVED, the one-point path [start], cost 0."""
    return PlanResult(PlanStatus.SOLVED, np.asarray(start, dtype=float).reshape(1, -1).copy(), 0.0,
                      PlanStats(), planner)


def failed(status: PlanStatus, planner: str, dim: int = 2, time_s: float = 0.0, **stats: Any) -> PlanResult:
    return PlanResult(status, empty_path(dim), float("inf"), PlanStats(time_s=time_s, **stats), planner)
