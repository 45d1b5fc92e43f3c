"""Best-first search on 4/8-connected grids: the shared core of A* and Dijkstra.

Graph: one vertex per free cell; straight moves cost 1, diagonal moves sqrt(2) (times the
resolution and a traversal multiplier). ``edge_cost`` says which multiplier: ``"mean"`` (the
default) the mean of the two cells' multipliers, a symmetric graph; ``"enter"`` the multiplier of
the cell the move enters, the textbook grid model in which a cell's cost is paid on entering it
(the start cell's cost is never paid, the goal cell's is). Without corner cutting a
diagonal move needs both orthogonally adjacent cells free - the rule of the MovingAI benchmark
(Sturtevant, "Benchmarks for Grid-Based Pathfinding", IEEE TCIAIG 4(2), 2012).

A* (Hart, Nilsson & Raphael, IEEE Trans. SSC 4(2), 1968) orders the open list by
f = g + h; Dijkstra (1959) is the zero heuristic. The loop runs in compiled C
(``_gridsearch.c``, loaded by ``_native``); :func:`search_python` is the same algorithm with
``heapq`` for machines without a C compiler, and is the "plain heapq A*" reference of
``slamkit bench planning``.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from slamkit.errors import PlanningError
from slamkit.planning import _native

HEURISTICS = {"zero": 0, "euclidean": 1, "manhattan": 2, "octile": 3, "chebyshev": 4}
#: how a move is charged: the mean of its two cells' multipliers, or the multiplier of the cell entered
EDGE_COSTS = ("mean", "enter")
#: the C core's edge mode for the enter model searched backwards (a move pays the cell it leaves)
_EDGE_MODE_LEAVE = 2


def check_edge_cost(edge_cost: str) -> bool:
    """Validate an ``edge_cost`` name; True for the enter-cell model."""
    if edge_cost not in EDGE_COSTS:
        raise PlanningError(f"unknown edge_cost {edge_cost!r}; choose from {list(EDGE_COSTS)}")
    return edge_cost == "enter"


@dataclass(frozen=True)
class SearchOutput:
    cost: float                 # in cell units times the multipliers (multiply by resolution)
    path: np.ndarray            # (N,) flat cell indices start..goal, empty if unreachable
    expansions: int
    g: np.ndarray               # (H*W,) cost-to-come, inf where never reached
    order: np.ndarray | None    # (expansions,) flat indices in expansion order, if recorded
    opened: int = 0             # distinct cells ever put on the open list


def costmap_to_cell_cost(costmap: np.ndarray, weight: float = 3.0,
                         lethal_threshold: float = 253.0) -> np.ndarray:
    """Nav2 costmap (0..254, see ``slamkit.maps.inflation.costmap``) -> traversal multiplier.

    Cells at or above ``lethal_threshold`` (inscribed 253 and lethal 254 by default: the robot
    disc would touch an obstacle) are blocked (inf); others cost ``1 + weight * cost / 252`` so
    a path pays up to ``1 + weight`` times its length near obstacles and heuristics scaled by
    the minimum multiplier 1 stay admissible."""
    c = np.asarray(costmap, dtype=float)
    out = 1.0 + weight * c / 252.0
    out[c >= lethal_threshold] = np.inf
    return out


def heuristic_code(name: str) -> int:
    try:
        return HEURISTICS[name]
    except KeyError:
        raise PlanningError(f"unknown heuristic {name!r}; choose from {sorted(HEURISTICS)}") from None


def search(cell_cost: np.ndarray, start_ixy: tuple[int, int], goal_ixy: tuple[int, int],
           connectivity: int = 8, corner_cutting: bool = False, heuristic: str = "octile",
           heuristic_scale: float | None = None, record_order: bool = False,
           use_native: bool = True, edge_cost: str = "mean", reverse: bool = False) -> SearchOutput:
    """Search ``cell_cost`` (H, W) (multiplier >= 0, inf = blocked) from start to goal cell.

    ``heuristic_scale`` multiplies the heuristic in cells; by default the smallest finite
    multiplier, which keeps Euclidean/octile/Chebyshev admissible (Manhattan only on
    4-connected grids). Values > that give weighted A* (faster, suboptimal). ``edge_cost``: see
    the module docstring. ``reverse`` searches the graph with every edge reversed, so ``g`` is
    each cell's cost-to-go to ``start_ixy`` (D* Lite's backward search); it matters only for the
    directed "enter" model, where a reversed move pays the cell it leaves."""
    mode = _EDGE_MODE_LEAVE if check_edge_cost(edge_cost) and reverse else int(edge_cost == "enter")
    if connectivity not in (4, 8):
        raise PlanningError(f"connectivity must be 4 or 8, got {connectivity}")
    cost = np.ascontiguousarray(cell_cost, dtype=np.float64)
    if cost.ndim != 2:
        raise PlanningError(f"cell_cost must be (H, W), got shape {cost.shape}")
    if np.any(cost < 0):
        raise PlanningError("cell_cost must be >= 0 everywhere")
    h, w = cost.shape
    hkind = heuristic_code(heuristic)
    if heuristic_scale is None:
        finite = cost[np.isfinite(cost)]
        heuristic_scale = float(finite.min()) if finite.size else 1.0
    s = int(start_ixy[1]) * w + int(start_ixy[0])
    t = int(goal_ixy[1]) * w + int(goal_ixy[0])
    mod = _native.gridsearch() if use_native else None
    if mod is None:
        return search_python(cost, s, t, connectivity, corner_cutting, hkind, heuristic_scale,
                             record_order, mode)
    n = h * w
    g = np.empty(n)
    parent = np.empty(n, dtype=np.int64)
    path = np.empty(n, dtype=np.int64)
    order = np.empty(n, dtype=np.int64) if record_order else None
    goal_cost, path_len, expansions, n_order, opened = mod.search(
        cost.reshape(-1), h, w, s, t, connectivity, int(corner_cutting), hkind,
        float(heuristic_scale), g, parent, path, order, mode)
    return SearchOutput(goal_cost, path[:path_len].copy(), expansions, g,
                        None if order is None else order[:n_order].copy(), opened)


_DX = (1, -1, 0, 0, 1, 1, -1, -1)
_DY = (0, 0, 1, -1, 1, -1, 1, -1)


def search_python(cost: np.ndarray, start: int, goal: int, connectivity: int = 8,
                  corner_cutting: bool = False, hkind: int = 3, hscale: float = 1.0,
                  record_order: bool = False, enter_cost: int = 0) -> SearchOutput:
    """The same search as the C core, in plain Python with ``heapq`` (flat indices, lists);
    ``enter_cost`` is the C core's edge mode (0 mean, 1 enter, 2 leave)."""
    h, w = cost.shape
    flat = cost.reshape(-1).tolist()
    free = [math.isfinite(c) for c in flat]
    n = h * w
    g = [math.inf] * n
    parent = [-1] * n
    closed = [False] * n
    gx, gy = goal % w, goal // w
    sqrt2 = math.sqrt(2.0)

    def heur(x: int, y: int) -> float:
        dx, dy = abs(x - gx), abs(y - gy)
        if hkind == 1:
            return hscale * math.sqrt(dx * dx + dy * dy)
        if hkind == 2:
            return hscale * (dx + dy)
        if hkind == 3:
            return hscale * (max(dx, dy) + (sqrt2 - 1.0) * min(dx, dy))
        if hkind == 4:
            return hscale * max(dx, dy)
        return 0.0

    nmoves = 4 if connectivity == 4 else 8
    g[start] = 0.0
    # (f, -g, idx): ties in f go to the deeper node, as in the C core
    heap = [(heur(start % w, start // w), -0.0, start)]
    order: list[int] = []
    expansions = 0
    goal_cost = math.inf
    while heap:
        _, _, u = heapq.heappop(heap)
        if closed[u]:
            continue
        closed[u] = True
        expansions += 1
        if record_order:
            order.append(u)
        if u == goal:
            goal_cost = g[u]
            break
        ux, uy = u % w, u // w
        cu, gu = flat[u], g[u]
        for k in range(nmoves):
            vx, vy = ux + _DX[k], uy + _DY[k]
            if vx < 0 or vy < 0 or vx >= w or vy >= h:
                continue
            v = vy * w + vx
            if closed[v] or not free[v]:
                continue
            step = 1.0
            if k >= 4:
                if not corner_cutting and (not free[uy * w + vx] or not free[vy * w + ux]):
                    continue
                step = sqrt2
            ng = gu + step * (flat[v] if enter_cost == 1 else cu if enter_cost == 2 else 0.5 * (cu + flat[v]))
            if ng < g[v]:
                g[v] = ng
                parent[v] = u
                heapq.heappush(heap, (ng + heur(vx, vy), -ng, v))
    path: list[int] = []
    if math.isfinite(goal_cost):
        v = goal
        while v != -1:
            path.append(v)
            v = parent[v]
        path.reverse()
    g_arr = np.asarray(g)
    return SearchOutput(goal_cost, np.asarray(path, dtype=np.int64), expansions, g_arr,
                        np.asarray(order, dtype=np.int64) if record_order else None,
                        int(np.isfinite(g_arr).sum()))


_UNIT_COST_CACHE: list[tuple[object, np.ndarray]] = []


def _unit_cost(grid) -> np.ndarray:
    """``inf`` on occupied cells, 1 elsewhere; cached for the last few grids (grids are
    immutable), so repeated queries on one map skip an O(cells) conversion."""
    for g, cost in _UNIT_COST_CACHE:
        if g is grid:
            return cost
    cost = np.where(grid.occupied, np.inf, 1.0)
    cost.setflags(write=False)
    _UNIT_COST_CACHE.insert(0, (grid, cost))
    del _UNIT_COST_CACHE[4:]
    return cost


@dataclass(frozen=True)
class GridSetup:
    """A grid problem resolved to cells: what every grid planner needs."""

    grid: "object"               # the OccupancyGrid
    cell_cost: np.ndarray        # (H, W) multiplier, inf = blocked
    min_cost: float              # smallest finite multiplier (scales admissible heuristics)
    start_ixy: tuple[int, int]
    goal_ixy: tuple[int, int]
    status: str | None           # None if valid, else "invalid_start" / "invalid_goal"


def setup_grid_problem(problem) -> GridSetup:
    """Check a PlanningProblem for a grid planner and map start/goal to cells.

    Raises PlanningError if the world is not an OccupancyGrid or ``cell_cost`` has the wrong
    shape; returns a status for starts/goals outside the map or in blocked cells."""
    from slamkit.maps.occupancy_grid import OccupancyGrid

    grid = problem.world
    if not isinstance(grid, OccupancyGrid):
        raise PlanningError(f"grid planners need an OccupancyGrid world, got {type(grid).__name__}")
    if problem.start.size != 2:
        raise PlanningError("grid planners plan for a point robot: start/goal must be (x, y)")
    base = _unit_cost(grid)
    if problem.cell_cost is not None:
        cc = np.asarray(problem.cell_cost, dtype=float)
        if cc.shape != grid.shape:
            raise PlanningError(f"cell_cost shape {cc.shape} != grid shape {grid.shape}")
        if np.any(np.isnan(cc)) or np.any(cc < 0):
            raise PlanningError("cell_cost must be >= 0 and not NaN")
        base = np.where(grid.occupied, np.inf, cc)
        finite = base[np.isfinite(base)]
        min_cost = float(finite.min()) if finite.size else 1.0
    else:
        min_cost = 1.0
    cells = grid.world_to_cell(np.stack([problem.start, problem.goal]))
    inside = grid.in_bounds(cells)
    s = (int(cells[0, 0]), int(cells[0, 1]))
    t = (int(cells[1, 0]), int(cells[1, 1]))
    status = None
    if not inside[0] or not np.isfinite(base[s[1], s[0]]):
        status = "invalid_start"
    elif not inside[1] or not np.isfinite(base[t[1], t[0]]):
        status = "invalid_goal"
    return GridSetup(grid, base, min_cost, s, t, status)
