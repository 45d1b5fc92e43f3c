"""The perturbation harness: every figure beside its median and worst over seeded twins of the data.

A pipeline that supports it (``lidar_slam``, ``filter_vs_smoother``) takes
``perturbations: {count: 5, kinds: [start_offset, range_jitter], range_jitter_m: 1.0e-6, seed: 0}``
(or ``slamkit run CFG --perturbations 5``) and reruns every dataset on ``count`` twins made by
:func:`slamkit.data.perturb.perturb` -- changes that cannot alter what a good algorithm
concludes. Each run's record carries ``params['perturbation']`` (0: the data as given).

:func:`with_perturbation_report` (called by the runner for every pipeline) then turns the records
into one row per dataset x estimator x metric (means over seeds): the unperturbed value, the median and the
worst over the perturbed runs (worst in the metric's direction, see
:func:`slamkit.experiments.results.metric_direction`; metrics without one report their largest
deviation from the unperturbed value), written to ``results.json`` (``perturbation``), the report
and ``plots/perturbation_<metric>.png``. The ordinary summary stays over the unperturbed runs.

Why (issue 28): a figure that flips when a log starts one scan later is a knife edge. From now on a
claimed figure is the worst over at least 5 perturbations, with the median beside it.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence as Seq

import numpy as np

from slamkit.config import build
from slamkit.data.perturb import PerturbationConfig
from slamkit.experiments.results import RunRecord, _jsonable, markdown_table, metric_direction, summarise
from slamkit.paths import file_in

PARAM = "perturbation"


def perturbation_config(section: Mapping[str, Any] | None) -> PerturbationConfig:
    """A pipeline config's validated ``perturbations`` section (None: none) as its dataclass."""
    return build(PerturbationConfig, section, "perturbations")


def perturbation_indices(twins: PerturbationConfig) -> list[int]:
    """0 (the data as given) then 1..``twins.count``."""
    return list(range(twins.count + 1))


def twin_suffix(index: int) -> str:
    """The file-name suffix of twin ``index`` (none for the data as given)."""
    return "" if index == 0 else f"_p{index}"


def twin_params(index: int) -> dict[str, int]:
    """What a run record of twin ``index`` adds to its params (nothing for the data as given)."""
    return {} if index == 0 else {PARAM: int(index)}


def index_of(run: RunRecord) -> int:
    return int(run.params.get(PARAM, 0)) if run.params else 0


def unperturbed(runs: Iterable[RunRecord]) -> list[RunRecord]:
    return [r for r in runs if index_of(r) == 0]


def _group_key(r: RunRecord) -> tuple:
    params = {k: v for k, v in (r.params or {}).items() if k != PARAM}
    return (r.dataset, r.estimator, json.dumps(_jsonable(params), sort_keys=True))


def _numeric(v: Any) -> bool:
    return isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool)


def _mean_over_seeds(runs: list[RunRecord], metric: str) -> float:
    x = np.array([float(r.metrics[metric]) if _numeric(r.metrics.get(metric)) else np.nan for r in runs])
    return float(x.mean()) if len(x) else float("nan")


def perturbation_rows(runs: Iterable[RunRecord]) -> list[dict[str, Any]]:
    """Per dataset x estimator (x other params) x metric: ``unperturbed``, ``median`` and
    ``worst`` over the perturbed runs, their ``min``/``max``, ``perturbed`` (how many twins), the
    metric's ``direction`` and ``values`` (one per twin). A claimed figure is a mean over seeds, so
    runs of several seeds are averaged per twin first (``seeds``: how many; a seed that lost the
    metric makes that twin's mean NaN). Groups with no perturbed run are left out."""
    groups: dict[tuple, dict[int, list[RunRecord]]] = {}
    for r in runs:
        groups.setdefault(_group_key(r), {}).setdefault(index_of(r), []).append(r)
    rows = []
    for (dataset, estimator, _), by_index in groups.items():
        base = by_index.get(0)
        twins = [by_index[k] for k in sorted(by_index) if k > 0]
        if not base or not twins:
            continue
        metrics = [m for m, v in base[0].metrics.items() if _numeric(v)]
        for metric in metrics:
            value = _mean_over_seeds(base, metric)
            x = np.array([_mean_over_seeds(t, metric) for t in twins])
            finite = x[np.isfinite(x)]
            direction = metric_direction(metric)
            if len(finite) == 0:
                worst = median = lo = hi = float("nan")
            else:
                median, lo, hi = float(np.median(finite)), float(finite.min()), float(finite.max())
                if direction == "lower":
                    worst = hi
                elif direction == "higher":
                    worst = lo
                else:
                    worst = float(finite[np.argmax(np.abs(finite - value))])
            if len(finite) < len(x):
                worst = float("nan")  # a perturbed run that lost the metric is the worst case
            rows.append({"dataset": dataset, "estimator": estimator, "seeds": len(base), "metric": metric,
                         "direction": direction, "unperturbed": value, "median": median,
                         "worst": worst, "min": lo, "max": hi, "perturbed": len(x),
                         "values": [float(v) for v in x]})
    return rows


def perturbation_markdown(rows: list[dict[str, Any]], metrics: Seq[str]) -> str:
    """The rows of ``metrics`` as a table: unperturbed, median, worst, range."""
    picked = [r for r in rows if r["metric"] in metrics]
    if not picked:
        return ""
    seeds = any(r["seeds"] > 1 for r in picked)
    n = max(r["perturbed"] for r in picked)
    table = [[r["dataset"], r["estimator"], *([r["seeds"]] if seeds else []), r["metric"], r["unperturbed"],
              r["median"], r["worst"], f"[{r['min']:.4g}, {r['max']:.4g}]"] for r in picked]
    text = (f"\n## Perturbations\n\nEvery dataset rerun on {n} seeded twins "
            "(slamkit.data.perturb: started later, micrometre range jitter, ...) that cannot change what a "
            "good algorithm concludes. 'worst' is the worst perturbed run in the metric's direction "
            "(nan: a perturbed run lost the metric); a claimed figure is that worst case, the median "
            "beside it." + (" With several seeds each value is the mean over the seeds, as the summary's."
                            if seeds else "") + "\n\n")
    header = ["dataset", "estimator", *(["seeds"] if seeds else []), "metric", "unperturbed", "median", "worst",
              "range"]
    return text + markdown_table(header, table) + "\n"


def plot_perturbation_spread(plots: Path, rows: list[dict[str, Any]], metrics: Seq[str]) -> list[Path]:
    """One strip plot per metric: every perturbed value (dots) and the unperturbed one (a cross)
    per dataset x estimator."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for metric in metrics:
        picked = [r for r in rows if r["metric"] == metric]
        if not picked:
            continue
        fig, ax = plt.subplots(figsize=(max(5.0, 0.6 * len(picked) + 2.0), 4.0))
        for k, r in enumerate(picked):
            vals = np.asarray(r["values"], float)
            ax.plot(np.full(len(vals), k), vals, "o", color="tab:blue", alpha=0.6, ms=5,
                    label="perturbed" if k == 0 else None)
            ax.plot([k], [r["unperturbed"]], "x", color="tab:red", ms=9, mew=2,
                    label="unperturbed" if k == 0 else None)
        few = len(picked) <= 6
        # few groups: upright labels, the estimator's path broken at its slashes
        labels = [f"{r['dataset']}\n" + (r["estimator"].replace("/", "/\n") if few else r["estimator"])
                  for r in picked]
        ax.set_xticks(range(len(picked)), labels, rotation=0 if few else 60, ha="center" if few else "right",
                      fontsize=7)
        ax.set_xlim(-0.5, len(picked) - 0.5)
        ax.set_ylabel(metric)
        positive = [v for r in picked for v in [*r["values"], r["unperturbed"]] if math.isfinite(v) and v > 0]
        if positive and max(positive) / max(min(positive), 1e-300) > 30:
            ax.set_yscale("log")
        ax.set_title(f"{metric}: {max(r['perturbed'] for r in picked)} perturbations", fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        path = file_in(plots, f"perturbation_{metric}", ".png", "metric name")
        fig.savefig(path, dpi=100)
        plt.close(fig)
        written.append(path)
    return written


#: metrics shown in the report's perturbation table when a pipeline names none
DEFAULT_REPORT_METRICS = ("ate_rmse_m", "rpe_rmse_m", "nees_mean", "relation_trans_mean_m",
                          "relation_trans_std_m", "relation_rot_mean_deg", "map_consistency_mean_m",
                          "map_consistency_same_pass_mean_m",
                          "num_loop_closures", "real_time_factor_cpu")


def with_perturbation_report(output, plots: Path, metrics: Seq[str] = DEFAULT_REPORT_METRICS):
    """``output`` (a PipelineOutput) with the perturbation table appended to its report, the rows
    in ``extra['perturbation']``, the spread plotted, and its summary over the unperturbed runs
    only; unchanged when no run was perturbed."""
    if not any(index_of(r) > 0 for r in output.runs):
        return output
    rows = perturbation_rows(output.runs)
    shown = [m for m in metrics if any(r["metric"] == m for r in rows)]
    plot_perturbation_spread(plots, rows, shown)
    summary = output.summary if output.summary is not None else summarise(unperturbed(output.runs))
    return dataclasses.replace(output, report_md=output.report_md + perturbation_markdown(rows, shown),
                               summary=summary, extra={**dict(output.extra), PARAM: rows})
