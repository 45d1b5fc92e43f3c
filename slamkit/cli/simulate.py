"""``slamkit simulate SCENARIO.yaml --seed N --out FILE [--rrd FILE]``: a seeded dataset with
ground truth, written in the slamkit sequence format (``slamkit.data.formats.sequence``).

A thin shell over :func:`slamkit.sim.scenario.simulate_to_file` and
``slamkit.viz.sim.record_simulation``; the same seed always writes the same bytes.
"""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console

from slamkit.cli.app import app, dumps_json


@app.command()
def simulate(
    scenario: Path = typer.Argument(..., help="scenario YAML (see pipelines/scenarios/)"),
    seed: int = typer.Option(0, "--seed", help="seed of numpy.random.default_rng"),
    out: Path = typer.Option(..., "--out", help="output .slamseq file"),
    rrd: Path = typer.Option(None, "--rrd", help="also write a Rerun recording here"),
    as_json: bool = typer.Option(False, "--json", help="print the summary as one JSON object"),
) -> None:
    """Simulate a scenario into a sequence file with ground truth (same seed, same bytes)."""
    from slamkit.sim.scenario import simulate_to_file

    written = simulate_to_file(scenario, seed, out)
    if rrd is not None:
        from slamkit.viz.sim import record_simulation

        record_simulation(rrd, written.simulation.sequence, written.simulation.grid)
    summary = {**written.summary(), "rrd": None if rrd is None else str(rrd)}
    if as_json:
        print(dumps_json(summary, indent=2))
        return
    console = Console()
    console.print(f"[bold]{summary['name']}[/bold] seed {seed}: {summary['num_events']} events over "
                  f"{summary['duration_s']:.1f} s, {summary['path_length_m']:.1f} m driven")
    for kind, n in summary["events"].items():
        console.print(f"  {kind:14s} {n}")
    console.print(f"wrote {summary['out']} (sha256 {summary['sha256'][:16]}...)")
    if rrd is not None:
        console.print(f"recording {summary['rrd']}")
