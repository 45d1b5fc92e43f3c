"""``slamkit plan MAP --start X,Y --goal X,Y --planner NAME [--inflate M] [--json] [--rrd FILE]``

MAP is a registry name of a grid map (``slamkit data list``: ``arena``, ``den312d`` ...) or a
MovingAI ``.map`` file. Coordinates are world metres (a MovingAI cell (x, y) has its centre at
(x + 0.5, y + 0.5)). A thin shell over :func:`plan_on_map`, which notebooks can call directly.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer
from rich.console import Console

from slamkit.cli.app import EXIT_NO_RESULT, app, dumps_json, non_negative, positive
from slamkit.errors import DataError


def load_grid(map_name_or_path: str):
    """An OccupancyGrid from a registry name or a MovingAI .map path."""
    from slamkit.data import registry
    from slamkit.maps.movingai import load_map

    found = registry.resolve(map_name_or_path)
    note = registry.resolution_note(map_name_or_path)
    if note:
        typer.echo(f"note: {note}", err=True)
    if isinstance(found, Path):
        return load_map(found)
    if found.format != "movingai":
        raise DataError(f"dataset {found.name!r} is a {found.kind} ({found.format}), not a grid map")
    return load_map(registry.path_of(found.name))


def plan_on_map(map_name_or_path: str, start_xy_m, goal_xy_m, planner: str = "astar",
                inflate_m: float = 0.0, seed: int = 0, rrd: str | Path | None = None,
                **config) -> tuple[object, object]:
    """Plan on a map; returns (the grid planned on, PlanResult). ``config`` overrides the
    planner's config fields (e.g. ``max_iterations=2000``)."""
    from slamkit.maps.inflation import inflate
    from slamkit.planning.protocols import PlanningProblem
    from slamkit.planning.registry import make_planner

    grid = load_grid(map_name_or_path)
    if inflate_m > 0:
        grid = inflate(grid, inflate_m)
    problem = PlanningProblem(grid, np.asarray(start_xy_m, float), np.asarray(goal_xy_m, float))
    p = make_planner(planner, rng=np.random.default_rng(seed), **config)
    if rrd is None:
        return grid, p.plan(problem)
    from slamkit.viz.planning import record_plans

    return grid, record_plans(rrd, problem, {p.name: p})[p.name]


def _xy(text: str, what: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise typer.BadParameter(f"{what} must be 'X,Y' in metres, got {text!r}") from None
    if not (np.isfinite(x) and np.isfinite(y)):
        raise typer.BadParameter(f"{what} must be finite, got {text!r}")
    return x, y


@app.command()
def plan(
    map_: str = typer.Argument(..., metavar="MAP", help="registry name of a grid map or a MovingAI .map file"),
    start: str = typer.Option(..., "--start", help="X,Y in metres"),
    goal: str = typer.Option(..., "--goal", help="X,Y in metres"),
    planner: str = typer.Option("astar", "--planner",
                                help="astar|dijkstra|dstar_lite|prm|rrt|rrt_connect|rrt_star|informed_rrt_star"),
    inflate_m: float = typer.Option(0.0, "--inflate", help="inflate obstacles by this robot radius (m)",
                                    callback=non_negative),
    seed: int = typer.Option(0, "--seed", help="seed of the sampling planners' rng"),
    max_iterations: int = typer.Option(None, "--max-iterations", help="sampling planners' iteration budget", min=1),
    time_limit_s: float = typer.Option(None, "--time-limit", help="sampling planners' time budget (s)",
                                       callback=positive),
    as_json: bool = typer.Option(False, "--json", help="print one JSON object"),
    rrd: Path = typer.Option(None, "--rrd", help="write a Rerun recording of the search here"),
) -> None:
    """Plan a path on a grid map and print status, cost, length, time and expansions."""
    cfg = {}
    if max_iterations is not None:
        cfg["max_iterations"] = max_iterations
    if time_limit_s is not None:
        cfg["time_limit_s"] = time_limit_s
    grid, result = plan_on_map(map_, _xy(start, "--start"), _xy(goal, "--goal"), planner,
                               inflate_m, seed, rrd, **cfg)
    out = dict(result.to_dict())  # dumps_json writes an unsolved (infinite) cost as null
    out.update({"map": map_, "inflate_m": inflate_m, "path_points": int(len(result.path)),
                "rrd": None if rrd is None else str(rrd)})
    if as_json:
        print(dumps_json(out))
    else:
        Console().print(f"[bold]{out['planner']}[/] on {map_} ({grid.width}x{grid.height}): "
                        f"{out['status']}  cost {result.cost:.4f}  length {result.length_m:.4f} m  "
                        f"time {1e3 * out['time_s']:.2f} ms  expansions {out['expansions']}  "
                        f"samples {out['samples']}")
    if not result.solved:
        # the answer was printed above; the exit code says there is no path (see `slamkit --help`)
        raise typer.Exit(EXIT_NO_RESULT)
