"""``slamkit sweep SWEEP.yaml --out DIR [--workers N] [--executor local|ray --address A] [--resume] [--overwrite]``."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console

from slamkit.cli.app import app


@app.command("sweep")
def sweep_command(
    sweep: Path = typer.Argument(..., help="sweep file (YAML): a pipeline config and the axes to vary"),
    out: Path = typer.Option(..., "--out", help="sweep folder: cells/<key[:2]>/<key>/ per cell, results.json, report.md, plots/"),
    workers: int = typer.Option(None, "--workers", min=1, max=256,
                                help="local worker processes (default min(2, cpus)); Ray uses its cluster's CPUs"),
    executor: str = typer.Option("local", "--executor", help="local (a process pool) or ray"),
    address: str = typer.Option(None, "--address",
                                help="Ray cluster: auto (the one this machine belongs to) or HOST:PORT; "
                                     "default a new local Ray instance"),
    resume: bool = typer.Option(False, "--resume", help="continue the sweep in --out: run only unfinished cells"),
    retry_failed: bool = typer.Option(False, "--retry-failed", help="with --resume, run failed cells again"),
    overwrite: bool = typer.Option(False, "--overwrite", help="start afresh over the sweep in --out (its cells "
                                   "are removed; --resume keeps and reuses them)"),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar or report"),
    plugin: list[str] = typer.Option(None, "--plugin", metavar="MODULE",
                                     help="import this module first (repeatable): it registers your own "
                                          "estimators, planners, ... (the config's 'plugins:' list)"),
) -> None:
    """Run a pipeline over a grid of config values, seeds and datasets; resumable after any kill."""
    from slamkit.experiments.sweep import run_sweep
    from slamkit.naming import import_plugins

    import_plugins(plugin or [], "--plugin")

    result = run_sweep(sweep, out, workers=workers, executor=executor, address=address, resume=resume,
                       retry_failed=retry_failed, progress=not quiet, overwrite=overwrite)
    if not quiet:
        typer.echo(result.report_md)
        Console().print(f"{result.ran} cells run ({result.failed} failed); results written to "
                        f"[bold]{result.out_dir}[/bold]")
