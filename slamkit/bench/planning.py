"""``slamkit bench planning``: planners against references measured in the same run.

Cases (``ratio`` = how many times better than the reference):

* ``astar_<n>x<n>_walls_vs_heapq`` - grid A* (compiled core) against the plain ``heapq`` A* of
  :func:`slamkit.planning.grid_search.search_python` on the same map (goal >= 20).
* ``astar_<n>x<n>_walls_vs_pyastar2d`` - against pyastar2d (C++; bench-only extra). Note that
  pyastar2d charges 1 for diagonal moves (and plans a slightly different optimum); goal "within
  3x", i.e. ratio >= 0.33.
* ``dstar_lite_replan_<map>`` - expansions of an incremental repair after an obstacle appears
  on the path, against a D* Lite search from scratch on the changed map.
* ``movingai_<map>`` - fraction of sampled scenarios where Dijkstra and A* reproduce the
  published optimal length; A* expansions against Dijkstra's.
* ``empty10_<planner>_<iters>`` - cost / optimum (14.14) in an empty 10 x 10 world, 20 seeds.
* ``table/<world>/<planner>`` - an OMPL-benchmark-style row per world and planner: value =
  mean solution length; ``extra`` holds success rate, time, clearance, smoothness,
  expansions/samples (:func:`table` returns the same rows for notebooks).
* ``rrt_star_1s_vs_ompl`` / ``rrt_star_iterations_per_s`` - our RRT* against OMPL's RRT*
  (python bindings; bench-only extra) after the same 1 s budget on the same circle world;
  OMPL's validity checker is a Python callback there, which slows it down - see ``extra``.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import numpy as np

from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.planning.astar import AStarConfig, AStarPlanner
from slamkit.planning.dijkstra import DijkstraPlanner
from slamkit.planning.dstar_lite import DStarLitePlanner
from slamkit.planning.grid_search import search_python
from slamkit.planning.postprocess import min_clearance, path_length, smoothness
from slamkit.planning.protocols import PlanningProblem
from slamkit.planning.registry import GRID_PLANNERS, make_planner
from slamkit.planning.rrt import RRTConfig, RRTPlanner
from slamkit.planning.rrt_star import RRTStarConfig, RRTStarPlanner
from slamkit.planning.worlds import PointWorld
from slamkit.bench.cases import BenchCase, best_of, compare


def walls_map(n: int = 1000, spacing: int = 100, thickness: int = 3, gap: int = 60) -> OccupancyGrid:
    """An n x n map of long vertical walls, alternately open at the bottom and the top, so the
    shortest path snakes through the whole map and A* must close most of it."""
    occ = np.zeros((n, n), bool)
    for k, x in enumerate(range(spacing, n - spacing // 2, spacing)):
        if k % 2 == 0:
            occ[0:n - gap, x:x + thickness] = True
        else:
            occ[gap:n, x:x + thickness] = True
    return OccupancyGrid(occ, name=f"walls{n}")


def _movingai_root() -> Path | None:
    """The shared MovingAI folder: ``$SLAMKIT_DATA`` or ``<checkout>/../shared/datasets``
    (the registry's first two roots; the planning layer may not import ``slamkit.data``)."""
    roots = [os.environ.get("SLAMKIT_DATA"), str(Path(__file__).resolve().parents[2].parent / "shared" / "datasets")]
    for r in roots:
        if r and (Path(r) / "grid_planning" / "movingai").is_dir():
            return Path(r) / "grid_planning" / "movingai"
    return None


# ------------------------------------------------------------------ grid speed

def grid_speed_cases(quick: bool) -> list[BenchCase]:
    n = 300 if quick else 1000
    grid = walls_map(n, spacing=max(30, n // 10), gap=max(6, n // 16))
    start = grid.cell_to_world(np.array([[5, 5]]))[0]
    goal = grid.cell_to_world(np.array([[n - 5, n - 5]]))[0]
    problem = PlanningProblem(grid, start, goal)
    astar = AStarPlanner(AStarConfig(heuristic="octile"))
    t_ours, ours = best_of(lambda: astar.plan(problem), repeat=3)
    cost = np.where(grid.occupied, np.inf, 1.0)
    s, g = 5 * n + 5, (n - 5) * n + (n - 5)
    t_py, ref = best_of(lambda: search_python(cost, s, g, 8, False, 3, 1.0), repeat=1)
    assert abs(ref.cost - ours.cost) < 1e-6, "heapq reference and compiled A* disagree"
    from slamkit.planning import _native

    compiled = _native.gridsearch() is not None
    cases = [compare(f"astar_{n}x{n}_walls_vs_heapq", 1e3 * t_ours, "ms", "plain heapq A* (Python)",
                     1e3 * t_py, goal=">= 20", expansions=ours.stats.expansions, cost=ours.cost,
                     compiled_core=compiled,
                     **({} if compiled else {"fallback_reason": _native.unavailable_reason()}))]
    try:
        import pyastar2d
    except ImportError:
        cases.append(BenchCase(f"astar_{n}x{n}_walls_vs_pyastar2d", 1e3 * t_ours, "ms",
                               "pyastar2d not installed", goal="ratio >= 0.33"))
        return cases
    w32 = np.where(grid.occupied, np.inf, 1.0).astype(np.float32)
    t_pa, pa_path = best_of(lambda: pyastar2d.astar_path(w32, (5, 5), (n - 5, n - 5), allow_diagonal=True), repeat=3)
    cases.append(compare(f"astar_{n}x{n}_walls_vs_pyastar2d", 1e3 * t_ours, "ms", "pyastar2d (C++)",
                         1e3 * t_pa, goal=">= 0.33 (within 3x)",
                         note="pyastar2d charges 1 per diagonal move (Chebyshev metric)",
                         pyastar2d_path_cells=int(len(pa_path)), ours_path_cells=int(len(ours.path))))
    return cases


# ------------------------------------------------------------------ D* Lite

def dstar_lite_cases(quick: bool) -> list[BenchCase]:
    root = _movingai_root()
    if root is not None:
        from slamkit.maps.movingai import load_map

        grid = load_map(root / "dao" / "den312d.map")
        start, goal = grid.cell_to_world(np.array([[4, 10], [60, 12]]))
        name = "den312d"
    else:
        grid = walls_map(120, spacing=20, gap=8)
        start, goal = grid.cell_to_world(np.array([[2, 2], [117, 117]]))
        name = "walls120"
    planner = DStarLitePlanner()
    first = planner.plan(PlanningProblem(grid, start, goal))
    rng = np.random.default_rng(0)
    occ = grid.occupied.copy()
    inc, scratch, astar_exp = [], [], []
    current = first
    for _ in range(3 if quick else 8):
        if not current.solved or len(current.path) < 6:
            break
        cells = grid.world_to_cell(current.path)
        c = cells[int(rng.integers(2, len(cells) - 2))]
        occ[c[1], c[0]] = True
        current = planner.update(c[None], True)
        changed = OccupancyGrid(occ)
        fresh = DStarLitePlanner().plan(PlanningProblem(changed, start, goal))
        assert abs(fresh.cost - current.cost) < 1e-9 or not fresh.solved
        inc.append(current.stats.expansions)
        scratch.append(fresh.stats.expansions)
        astar_exp.append(AStarPlanner().plan(PlanningProblem(changed, start, goal)).stats.expansions)
    return [compare(f"dstar_lite_replan_{name}", float(np.mean(inc)), "expansions",
                    "D* Lite from scratch on the changed map", float(np.mean(scratch)), goal="far fewer (>= 3)",
                    astar_from_scratch_expansions=float(np.mean(astar_exp)), replans=len(inc),
                    first_plan_expansions=first.stats.expansions)]


# ------------------------------------------------------------------ MovingAI

def movingai_cases(quick: bool) -> list[BenchCase]:
    root = _movingai_root()
    if root is None:
        return [BenchCase("movingai", float("nan"), "", "MovingAI files not found")]
    from slamkit.maps.movingai import load_map, load_scenarios, scenario_problem_points

    out = []
    maps = ["dao/arena", "dao/den520d", "street/Berlin_0_256", "maze/maze512-32-9"]
    for name in maps[:2] if quick else maps:
        grid = load_map(root / f"{name}.map")
        scen = load_scenarios(root / f"{name}.map.scen")
        idx = np.random.default_rng(0).choice(len(scen), min(len(scen), 10 if quick else 40), replace=False)
        match = 0
        exp_a = exp_d = t_a = t_d = 0.0
        for i in idx:
            s = scen[i]
            a, b = scenario_problem_points(grid, s)
            p = PlanningProblem(grid, a, b)
            rd, ra = DijkstraPlanner().plan(p), AStarPlanner().plan(p)
            tol = 1e-6 if s.decimals >= 8 else 1e-3 + 0.5 * 10.0 ** -s.decimals
            match += abs(rd.cost - s.optimal_length) <= tol and abs(ra.cost - rd.cost) <= 1e-9
            exp_a += ra.stats.expansions
            exp_d += rd.stats.expansions
            t_a += ra.stats.time_s
            t_d += rd.stats.time_s
        out.append(compare(f"movingai_{Path(name).name}_astar_expansions", exp_a / len(idx), "expansions",
                           "Dijkstra expansions", exp_d / len(idx), goal="> 1",
                           optimal_match_rate=match / len(idx), scenarios=len(idx),
                           astar_mean_ms=1e3 * t_a / len(idx), dijkstra_mean_ms=1e3 * t_d / len(idx)))
    return out


# ------------------------------------------------------------------ sampling

def empty_world_cases(quick: bool) -> list[BenchCase]:
    world = PointWorld([[0, 0], [10, 10]])
    problem = PlanningProblem(world, [0, 0], [10, 10])
    opt = math.hypot(10, 10)
    seeds = range(5 if quick else 20)
    out = []
    runs = [("rrt", 500, lambda s: RRTPlanner(RRTConfig(max_iterations=500), rng=np.random.default_rng(s)), "well above 1"),
            ("rrt_star", 500, lambda s: RRTStarPlanner(RRTStarConfig(max_iterations=500), rng=np.random.default_rng(s)), "<= 1.10"),
            ("rrt_star", 5000, lambda s: RRTStarPlanner(RRTStarConfig(max_iterations=5000, time_limit_s=60),
                                                         rng=np.random.default_rng(s)), "<= 1.02")]
    for name, iters, make, goal in runs:
        if quick and iters > 1000:
            continue
        ratios = np.array([make(s).plan(problem).cost / opt for s in seeds])
        out.append(BenchCase(f"empty10_{name}_{iters}_cost_over_opt", float(ratios.mean()), "x optimum",
                             goal=goal, extra={"max": float(ratios.max()), "min": float(ratios.min()),
                                               "seeds": len(ratios), "optimum": opt}))
    return out


def scenes(quick: bool) -> dict[str, PlanningProblem]:
    circles = PointWorld([[0, 0], [10, 10]], circles=[[5, 5, 1.5], [2, 7, 1.0], [7.5, 7.5, 0.8], [7, 2.5, 1.0]],
                         name="circles10")
    out = {"circles10": PlanningProblem(circles, [0.5, 0.5], [9.5, 9.5])}
    root = _movingai_root()
    if root is not None:
        from slamkit.maps.movingai import load_map

        grid = load_map(root / "dao" / "den312d.map")
        out["den312d"] = PlanningProblem(grid, [5.5, 5.5], [60.5, 70.5])
    return out


def table(quick: bool = False, planners: list[str] | None = None, runs: int | None = None,
          time_limit_s: float = 1.0) -> list[dict]:
    """One OMPL-benchmark-style row per (world, planner): success rate and means over runs."""
    planners = planners or ["astar", "dijkstra", "dstar_lite", "prm", "rrt", "rrt_connect", "rrt_star",
                            "informed_rrt_star"]
    runs = runs or (2 if quick else 5)
    rows = []
    for world_name, problem in scenes(quick).items():
        is_grid = isinstance(problem.world, OccupancyGrid)
        for name in planners:
            if name in GRID_PLANNERS and not is_grid:
                continue
            results = []
            for seed in range(1 if name in GRID_PLANNERS else runs):
                kw = {} if name in GRID_PLANNERS or name == "prm" else {"time_limit_s": time_limit_s,
                                                                         "max_iterations": 10**9 if "star" in name else 20000}
                p = make_planner(name, rng=np.random.default_rng(seed), **kw)
                results.append(p.plan(problem))
            ok = [r for r in results if r.solved]
            world = problem.world
            rows.append({
                "world": world_name, "planner": name, "runs": len(results),
                "success": len(ok) / len(results),
                "time_s": float(np.mean([r.stats.time_s for r in results])),
                "length_m": float(np.mean([path_length(world, r.path) for r in ok])) if ok else float("nan"),
                "clearance_m": float(np.mean([min_clearance(world, r.path) for r in ok])) if ok else float("nan"),
                "smoothness": float(np.mean([smoothness(r.path) for r in ok])) if ok else float("nan"),
                "expansions": float(np.mean([r.stats.expansions for r in results])),
                "samples": float(np.mean([r.stats.samples for r in results])),
                "cost_history": ok[0].stats.extra.get("cost_history") if ok and "star" in name else None,
            })
    return rows


def table_cases(quick: bool) -> list[BenchCase]:
    out = []
    for row in table(quick):
        extra = {k: v for k, v in row.items() if k not in ("world", "planner", "length_m", "cost_history")}
        if row["cost_history"]:
            extra["best_cost_over_time"] = [(round(t, 4), it, round(c, 4)) for t, it, c in row["cost_history"]]
        out.append(BenchCase(f"table/{row['world']}/{row['planner']}", row["length_m"], "m",
                             goal=f"success {row['success']:.0%}, {1e3 * row['time_s']:.1f} ms", extra=extra))
    return out


def ompl_rrt_star(problem: PlanningProblem, time_s: float = 1.0) -> dict | None:
    """OMPL's RRT* (python bindings, path-length objective, OMPL defaults: range = 20% of the
    extent, goal bias 0.05, rewire factor 1.1) on a circle world. None if ompl is missing."""
    try:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou
    except ImportError:
        return None
    try:
        ou.setLogLevel(ou.LogLevel.LOG_WARN)
    except Exception:  # noqa: BLE001 - only quietens OMPL's console output
        pass
    world = problem.world
    lo, hi = world.bounds_m
    space = ob.RealVectorStateSpace(2)
    bounds = ob.RealVectorBounds(2)
    for i in range(2):
        bounds.setLow(i, float(lo[i]))
        bounds.setHigh(i, float(hi[i]))
    space.setBounds(bounds)
    ss = og.SimpleSetup(space)
    cx, cy, r2 = world.circles[:, 0].tolist(), world.circles[:, 1].tolist(), (world.circles[:, 2] ** 2).tolist()

    def valid(state) -> bool:
        x, y = state[0], state[1]
        return all((x - a) ** 2 + (y - b) ** 2 > rr for a, b, rr in zip(cx, cy, r2))

    ss.setStateValidityChecker(valid)
    si = ss.getSpaceInformation()
    start, goal = space.allocState(), space.allocState()
    for i in range(2):
        start[i] = float(problem.start[i])
        goal[i] = float(problem.goal[i])
    ss.setStartAndGoalStates(start, goal)
    planner = og.RRTstar(si)
    ss.setPlanner(planner)
    ss.getProblemDefinition().setOptimizationObjective(ob.PathLengthOptimizationObjective(si))
    t0 = time.perf_counter()
    solved = ss.solve(time_s)
    elapsed = time.perf_counter() - t0
    cost = planner.bestCost().value() if solved else float("inf")
    return {"cost": float(cost), "iterations": int(planner.numIterations()), "time_s": elapsed}


def ompl_cases(quick: bool) -> list[BenchCase]:
    problem = scenes(True)["circles10"]
    seeds = range(2 if quick else 5)
    ours = [RRTStarPlanner(RRTStarConfig(max_iterations=10**9, time_limit_s=1.0), rng=np.random.default_rng(s)).plan(problem)
            for s in seeds]
    our_cost = float(np.mean([r.cost for r in ours]))
    our_rate = float(np.mean([r.stats.samples / r.stats.time_s for r in ours]))
    ref = [ompl_rrt_star(problem, 1.0) for _ in seeds]
    if ref[0] is None:
        return [BenchCase("rrt_star_1s_vs_ompl", our_cost, "m", "ompl not installed", goal="ratio >= 0.95"),
                BenchCase("rrt_star_iterations_per_s", our_rate, "it/s", goal=">= 5000")]
    ref_cost = float(np.mean([r["cost"] for r in ref]))
    ref_rate = float(np.mean([r["iterations"] / r["time_s"] for r in ref]))
    return [compare("rrt_star_1s_vs_ompl", our_cost, "m", "OMPL RRTstar, same 1 s budget", ref_cost,
                    goal=">= 0.95 (within 5%)", runs=len(ours),
                    note="OMPL's validity checker is a Python callback in its python bindings"),
            compare("rrt_star_iterations_per_s", our_rate, "it/s", "OMPL RRTstar iterations/s (Python validity callback)",
                    ref_rate, goal="value >= 5000", higher_is_better=True)]


def run(quick: bool = False) -> list[BenchCase]:
    cases: list[BenchCase] = []
    cases += grid_speed_cases(quick)
    cases += dstar_lite_cases(quick)
    cases += movingai_cases(quick)
    cases += empty_world_cases(quick)
    cases += ompl_cases(quick)
    cases += table_cases(quick)
    return cases
