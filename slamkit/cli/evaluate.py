"""``slamkit eval ate|rpe --ref FILE --est FILE ...``: trajectory metrics from files.

A thin shell over :func:`slamkit.metrics.evaluate_files`, which returns an
:class:`~slamkit.metrics.EvaluationResult`; ``--json`` prints its ``to_dict()`` (rmse, mean,
median, std, min, max, sse, num_pairs, align, ...) as one JSON object on stdout.
"""

from __future__ import annotations

from enum import Enum
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from slamkit.cli.app import app, dumps_json, non_negative, positive

eval_app = typer.Typer(
    name="eval",
    help="Trajectory metrics (evo's definitions): ATE and RPE of an estimate against a reference.",
    no_args_is_help=True,
    add_completion=False,
)
app.add_typer(eval_app, name="eval")


class Format(str, Enum):
    auto = "auto"
    tum = "tum"
    kitti = "kitti"
    g2o = "g2o"


class Align(str, Enum):
    none = "none"
    origin = "origin"
    se2 = "se2"
    se3 = "se3"
    sim3 = "sim3"


class DeltaUnit(str, Enum):
    frames = "frames"
    m = "m"


class Relation(str, Enum):
    trans = "trans"
    angle_deg = "angle_deg"
    angle_rad = "angle_rad"


REF = typer.Option(..., "--ref", help="reference (ground-truth) trajectory file")
EST = typer.Option(..., "--est", help="estimated trajectory file")
FORMAT = typer.Option(Format.auto, "--format", help="file format of both files (auto: .g2o suffix -> "
                      "g2o, 12 numbers a line -> kitti, else tum)")
ALIGN = typer.Option(Align.none, "--align", help="alignment of the estimate before scoring")
RELATION = typer.Option(Relation.trans, "--relation", help="what the statistics measure: translation "
                        "(m) or rotation angle (deg / rad)")
MAX_DIFF = typer.Option(0.01, "--max-diff", help="max. stamp difference (s) for association",
                        callback=non_negative)
N_FIRST = typer.Option(None, "--n-first", help="align using only the first N pose pairs", min=1)
JSON = typer.Option(False, "--json", help="print one JSON object on stdout")


def _run(metric: str, ref: Path, est: Path, fmt: Format, align: Align, relation: Relation,
         max_diff: float, n_first: int | None, as_json: bool, **rpe_args) -> None:
    from slamkit.metrics import evaluate_files

    result = evaluate_files(ref, est, metric=metric, fmt=fmt.value, align=align.value,
                            relation=relation.value, max_diff_s=max_diff, n_first=n_first,
                            **rpe_args)
    out = result.to_dict()
    if as_json:
        print(dumps_json(out))
        return
    title = f"{metric.upper()} ({relation.value}, {out['unit']}), align={align.value}"
    if metric == "rpe":
        title += f", delta={out['delta']:g} {out['delta_unit']}"
    table = Table(title=title)
    table.add_column("statistic")
    table.add_column("value", justify="right")
    for name in ("rmse", "mean", "median", "std", "min", "max", "sse"):
        table.add_row(name, f"{out[name]:.6g}")
    table.add_row("num_pairs", str(out["num_pairs"]))  # the JSON's name: one quantity, one name
    if align == Align.sim3:
        table.add_row("scale", f"{out['scale']:.6g}")
    Console().print(table)


@eval_app.command("ate")
def ate_command(
    ref: Path = REF, est: Path = EST, fmt: Format = FORMAT, align: Align = ALIGN,
    relation: Relation = RELATION, max_diff: float = MAX_DIFF, n_first: int = N_FIRST,
    as_json: bool = JSON,
) -> None:
    """Absolute trajectory error: per-pose position (or rotation) error after alignment (no
    --delta: pose-pair spacing is RPE's, and an option that changes nothing is not offered)."""
    _run("ate", ref, est, fmt, align, relation, max_diff, n_first, as_json)


@eval_app.command("rpe")
def rpe_command(
    ref: Path = REF, est: Path = EST, fmt: Format = FORMAT, align: Align = ALIGN,
    relation: Relation = RELATION, max_diff: float = MAX_DIFF, n_first: int = N_FIRST,
    delta: float = typer.Option(1.0, "--delta", help="pose-pair spacing, in --delta-unit", callback=positive),
    delta_unit: DeltaUnit = typer.Option(DeltaUnit.frames, "--delta-unit", help="frames or metres of path"),
    all_pairs: bool = typer.Option(False, "--all-pairs", help="every pair delta apart, not only consecutive ones"),
    as_json: bool = JSON,
) -> None:
    """Relative pose error over pose pairs delta frames or metres apart (drift)."""
    _run("rpe", ref, est, fmt, align, relation, max_diff, n_first, as_json, delta=delta,
         delta_unit=delta_unit.value, all_pairs=all_pairs)


@eval_app.command("relations")
def relations_command(
    est: Path = EST,
    relations: Path = typer.Option(..., "--relations", help="relations file (t1 t2 x y z roll pitch yaw), e.g. "
                                   "the SLAM benchmark's intel.relations"),
    fmt: Format = FORMAT,
    tolerance: float = typer.Option(1e-3, "--tolerance", help="max. stamp difference (s) between a relation "
                                    "stamp and an estimate pose", callback=positive),
    as_json: bool = JSON,
) -> None:
    """Relation error (Kuemmerle et al. 2009): the estimate's relative displacements against the
    benchmark's manually verified ones; translational (m) and rotational (deg) mean and std."""
    from slamkit.metrics.evaluate import load_trajectory
    from slamkit.metrics.relations import evaluate_relations

    result = evaluate_relations(load_trajectory(est, fmt.value), relations, tolerance)
    out = result.to_dict()
    if as_json:
        print(dumps_json(out))
        return
    table = Table(title=f"relation error of {est.name} on {relations.name}")
    table.add_column("metric")
    table.add_column("value", justify="right")
    for key, value in out.items():
        table.add_row(key, f"{value:.6g}" if isinstance(value, float) else str(value))
    Console().print(table)
