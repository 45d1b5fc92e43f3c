"""``slamkit run PIPELINE.yaml [--out DIR] [--overwrite]``."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console

from slamkit.cli.app import app


@app.command("run")
def run_command(
    pipeline: Path = typer.Argument(..., help="pipeline config (YAML), e.g. pipelines/pose_graph.yaml"),
    out: Path = typer.Option(None, "--out", help="results folder (default runs/<config name>)"),
    overwrite: bool = typer.Option(False, "--overwrite", help="replace an earlier result of this pipeline in --out "
                                   "(a result of another pipeline or a sweep is never replaced)"),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar or table"),
    spawn: bool = typer.Option(False, "--spawn", help="also stream the recording to a Rerun viewer"),
    perturbations: int = typer.Option(None, "--perturbations", min=0, max=100,
                                      help="rerun every dataset on this many seeded twins and report the "
                                           "median and worst beside each figure (the config's "
                                           "'perturbations: {count: N}')"),
    plugin: list[str] = typer.Option(None, "--plugin", metavar="MODULE",
                                     help="import this module first (repeatable): it registers your own "
                                          "estimators, planners, ... (the config's 'plugins:' list)"),
) -> None:
    """Run a pipeline config and write config.yaml, results.json, report.md, plots and a recording."""
    from slamkit.errors import ConfigError
    from slamkit.experiments.pipeline import PIPELINES, has_config_field, load_config, run_pipeline
    from slamkit.naming import import_plugins
    from slamkit.viz.pipelines import observer_for

    import_plugins(plugin or [], "--plugin")
    config = pipeline
    if perturbations is not None:
        config = load_config(pipeline)
        if not has_config_field(config["pipeline"], "perturbations"):
            takers = sorted(n for n in PIPELINES.names() if has_config_field(n, "perturbations"))
            raise ConfigError(f"{pipeline}: --perturbations: pipeline {config['pipeline']!r} does not rerun its data "
                              f"on perturbations; these do: {', '.join(takers)}")
        config["perturbations"] = {**(config.get("perturbations") or {}), "count": perturbations}
    result = run_pipeline(config, out, progress=not quiet,
                          observer_factory=lambda kind, path: observer_for(kind, path, spawn), overwrite=overwrite)
    if not quiet:
        # plain Markdown: tables stay readable at any terminal width and in logs
        typer.echo(result.report_md)
        Console().print(f"results written to [bold]{result.out_dir}[/bold]")
