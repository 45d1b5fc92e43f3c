"""``slamkit plan MAP --start X,Y --goal X,Y --planner NAME [--inflate M] [--json] [--rrd FILE]``

MAP is a registry name of a grid map (``slamkit data list``: ``arena``, ``den312d`` ...) or a
MovingAI ``.map`` file. Coordinates are world metres (a MovingAI cell (x, y) has its centre at
(x + 0.5, y + 0.5)). A thin shell over :func:`slamkit.experiments.planning.plan_on_map`, which
notebooks can call directly.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer
from rich.console import Console

from slamkit.cli.app import EXIT_NO_RESULT, app, dumps_json, non_negative, positive


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
    from functools import partial

    from slamkit.data.registry import resolution_note
    from slamkit.experiments.planning import plan_all, plan_on_map

    note = resolution_note(map_)
    if note:
        typer.echo(f"note: {note}", err=True)
    run = plan_all
    if rrd is not None:
        from slamkit.viz.planning import record_plans

        run = partial(record_plans, rrd)
    planned = plan_on_map(map_, _xy(start, "--start"), _xy(goal, "--goal"), planner, inflate_m, seed, run, **cfg)
    grid, result = planned.grid, planned.result
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
