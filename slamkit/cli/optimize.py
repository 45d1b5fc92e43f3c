"""``slamkit optimize SOURCE``: solve a pose graph from the registry or a file."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from slamkit.cli.app import app, dumps_json, positive


@app.command()
def optimize(
    source: str = typer.Argument(..., help="registry name (see `slamkit data list`) or a g2o/TORO/iSAM file"),
    solver: str = typer.Option("lm", help="lm | gn | dogleg | isam2"),
    init: str = typer.Option("file", help="file | odometry | lago (2D) | chordal (3D)"),
    robust: str = typer.Option("none", help="none | huber | cauchy | dcs"),
    robust_k: float = typer.Option(None, "--robust-k", help="kernel width (default: GTSAM's)", callback=positive),
    max_iterations: int = typer.Option(100, "--max-iterations", min=1),
    marginals: bool = typer.Option(False, "--marginals", help="compute marginal covariances"),
    out: Path = typer.Option(None, "--out", help="folder for the optimised graph, TUM trajectory, config and metrics.json"),
    overwrite: bool = typer.Option(False, "--overwrite", help="replace an earlier optimize result in --out"),
    rrd: Path = typer.Option(None, "--rrd", help="write a Rerun recording"),
    spawn: bool = typer.Option(False, "--spawn", help="open a Rerun viewer"),
    certify: str = typer.Option("auto", "--certify", help="SE-Sync optimality certificate: auto (least squares, "
                                "up to 40k rotation unknowns) | on | off; an uncertified result is re-solved "
                                "from chordal (3D) / LAGO (2D) initialisation and both are reported"),
    as_json: bool = typer.Option(False, "--json", help="print one JSON object on stdout"),
) -> None:
    """Optimise a pose graph; report GTSAM error, chi2, SE-Sync objective, iterations, times, ATE
    and SE-Sync's optimality certificate."""
    from slamkit.backend.solvers import OptimizeConfig
    from slamkit.experiments.pose_graph import optimize_source

    config = OptimizeConfig(solver=solver, init=init, robust=robust, robust_k=robust_k,
                            max_iterations=max_iterations, compute_marginals=marginals)
    report = optimize_source(source, config, out=out, keep_iterates=rrd is not None or spawn,
                             certify_mode=certify, overwrite=overwrite)
    if rrd is not None or spawn:
        from slamkit.viz.pose_graph import record_optimization

        record_optimization(report, rrd, spawn)
    summary = report.summary()
    if as_json:
        print(dumps_json(summary))
        return
    table = Table(title=f"slamkit optimize {report.dataset}", show_header=False)
    for key, value in summary.items():
        # the certificate's outcome is its verdict (certified / not optimal / not verified), said
        # below with the solution it is about; a bare 'certified False' hid 'not verified'
        if key in ("warnings", "certificate", "retry", "written", "certified"):
            continue
        table.add_row(key, f"{value:.6g}" if isinstance(value, float) else str(value))
    for prefix, r in (("certificate", report), ("retry", report.retry)):
        if r is None or r.certificate is None:
            continue
        if prefix == "retry":
            table.add_row("retry init", r.init)
            table.add_row("retry final_error", f"{r.final_error:.6g}")
        for key, value in r.certificate.summary().items():
            if key == "certified":
                continue
            table.add_row(f"{prefix}.{key}", f"{value:.6g}" if isinstance(value, float) else str(value))
    console = Console()
    console.print(table)
    for line in certificate_lines(report, out):
        typer.echo(line)  # plain lines: file names must not be wrapped
    for w in report.warnings:
        console.print(f"[yellow]warning:[/yellow] {w}")


def certificate_lines(report, out: Path | None = None) -> list[str]:
    """What the certificate says, about which solution, and which poses went to which files."""
    lines = []
    for label, r in (("certificate", report), (f"retry from {report.retry.init if report.retry else ''}", report.retry)):
        if r is None:
            continue
        if r.certificate is not None:
            lines.append(f"{label}: {r.certificate.describe()}")
        elif r.certify_skipped:
            lines.append(f"{label}: none ({r.certify_skipped})")
    about = {"solution": lambda r: (f"the {r.solver} solution from {r.init} initialisation (GTSAM error "
                                    f"{r.final_error:.6g}, SE-Sync F {r.sesync_objective:.6g})"),
             "refined": lambda r: (f"the refined solution the certificate is about ({r.certificate.verdict}, "
                                   f"SE-Sync F {r.certificate.objective:.6g})")}
    for key, files in report.written.items():
        r, kind = (report.retry, key[len("retry_"):]) if key.startswith("retry_") else (report, key)
        lines.append(f"wrote {', '.join(str(out / f) if out is not None else f for f in files)}: {about[kind](r)}")
    if not report.written:
        lines.append("poses not written (--out FOLDER writes the solution and, with a certificate, the "
                     "refined poses it is about)")
    return lines
