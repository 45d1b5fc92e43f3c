"""``slamkit doctor [--json]``: what this installation has (compiled kernels, data locations)."""

from __future__ import annotations

import platform

import typer

from slamkit.cli.app import app, dumps_json


def doctor_report() -> dict:
    """Version, Python, which C kernels are compiled (else why the fallback runs), data roots."""
    import slamkit
    from slamkit import _native
    from slamkit.data import registry

    return {"slamkit_version": slamkit.__version__, "python": platform.python_version(),
            "kernels": _native.status(),
            "data_roots": [{"kind": kind, "path": str(path), "exists": path.is_dir()}
                           for kind, path in registry.search_roots()]}


@app.command()
def doctor(as_json: bool = typer.Option(False, "--json", help="print one JSON object on stdout")) -> None:
    """Say which compiled kernels this installation has and where datasets are looked up."""
    report = doctor_report()
    if as_json:
        print(dumps_json(report))
        return
    typer.echo(f"slamkit {report['slamkit_version']} on Python {report['python']}")
    typer.echo("kernels:")
    for name, state in report["kernels"].items():
        typer.echo(f"  {name}: {state}")
    typer.echo("dataset search roots (first match wins):")
    for root in report["data_roots"]:
        typer.echo(f"  {root['kind']}: {root['path']}{'' if root['exists'] else '  (missing)'}")
