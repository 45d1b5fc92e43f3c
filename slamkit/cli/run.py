"""``slamkit run PIPELINE.yaml [--out DIR]``."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.markdown import Markdown

from slamkit.cli.app import app
from slamkit.errors import SlamkitError


@app.command("run")
def run_command(
    pipeline: Path = typer.Argument(..., help="pipeline config (YAML), e.g. pipelines/pose_graph.yaml"),
    out: Path = typer.Option(None, "--out", help="results folder (default runs/<config name>)"),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar or table"),
) -> None:
    """Run a pipeline config and write config.yaml, results.json, report.md, plots and a recording."""
    from slamkit.experiments.pipeline import run_pipeline

    try:
        result = run_pipeline(pipeline, out, progress=not quiet)
    except SlamkitError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2)
    if not quiet:
        console = Console()
        console.print(Markdown(result.report_md))
        console.print(f"\nresults written to [bold]{result.out_dir}[/bold]")
