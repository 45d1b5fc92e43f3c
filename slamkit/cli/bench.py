"""``slamkit bench NAME [--json] [--quick]``: benchmark suites with same-run references."""

from __future__ import annotations


import typer
from rich.console import Console
from rich.table import Table

from slamkit.bench import SUITES, run_bench
from slamkit.cli.app import app, dumps_json


@app.command()
def bench(
    name: str = typer.Argument(..., help=f"one of: {', '.join(SUITES)}"),
    as_json: bool = typer.Option(False, "--json", help="print one JSON object on stdout"),
    quick: bool = typer.Option(False, "--quick", help="smaller problem sizes (for smoke runs)"),
) -> None:
    """Time slamkit against a reference measured in the same run and print the ratios."""
    result = run_bench(name, quick=quick)
    if as_json:
        print(dumps_json(result, indent=2))
        return
    table = Table(title=f"slamkit bench {name}")
    for col in ("case", "value", "unit", "reference", "ref value", "ratio", "goal"):
        table.add_column(col)
    for c in result["cases"]:
        fmt = lambda v: "" if v is None else (f"{v:.4g}" if isinstance(v, float) else str(v))  # noqa: E731
        table.add_row(c["name"], fmt(c["value"]), c["unit"], fmt(c.get("reference")),
                      fmt(c.get("reference_value")), fmt(c.get("ratio")), fmt(c.get("goal")))
    Console().print(table)
