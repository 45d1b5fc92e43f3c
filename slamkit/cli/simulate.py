"""``slamkit simulate SCENARIO.yaml --seed N --out FILE [--rrd FILE]``: a seeded dataset with
ground truth, written in the slamkit sequence format (``slamkit.data.formats.sequence``).

A thin shell over :func:`slamkit.sim.scenario.simulate`, ``save_sequence`` and
``slamkit.viz.sim.record_simulation``; the same seed always writes the same bytes.
"""

from __future__ import annotations

import hashlib
from collections import Counter
from pathlib import Path

import typer
from rich.console import Console

from slamkit.cli.app import app, dumps_json


def simulate_to_files(scenario_path: Path, seed: int, out: Path, rrd: Path | None = None) -> dict:
    """Simulate, save and optionally record; returns the summary the command prints."""
    from slamkit.data.formats.sequence import save_sequence
    from slamkit.sim.scenario import load_scenario, simulate

    result = simulate(load_scenario(scenario_path), seed)
    seq = result.sequence
    path = save_sequence(out, seq)
    if rrd is not None:
        from slamkit.viz.sim import record_simulation

        record_simulation(rrd, seq, result.grid)
    gt = seq.ground_truth
    return {
        "scenario": str(scenario_path),
        "name": seq.name,
        "seed": seed,
        "out": str(path),
        "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
        "num_events": len(seq),
        "events": dict(sorted(Counter(type(e).__name__ for e in seq).items())),
        "duration_s": float(gt.stamps_s[-1] - gt.stamps_s[0]) if gt is not None else 0.0,
        "path_length_m": gt.path_length_m() if gt is not None else 0.0,
        "num_landmarks": len(seq.world_p_landmarks or {}),
        "rrd": None if rrd is None else str(rrd),
    }


@app.command()
def simulate(
    scenario: Path = typer.Argument(..., help="scenario YAML (see pipelines/scenarios/)"),
    seed: int = typer.Option(0, "--seed", help="seed of numpy.random.default_rng"),
    out: Path = typer.Option(..., "--out", help="output .slamseq file"),
    rrd: Path = typer.Option(None, "--rrd", help="also write a Rerun recording here"),
    as_json: bool = typer.Option(False, "--json", help="print the summary as one JSON object"),
) -> None:
    """Simulate a scenario into a sequence file with ground truth (same seed, same bytes)."""
    summary = simulate_to_files(scenario, seed, out, rrd)
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
