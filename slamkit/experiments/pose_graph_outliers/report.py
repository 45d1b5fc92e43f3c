"""The ``pose_graph_outliers`` pipeline's report: the table of means over seeds and the plots."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from slamkit.experiments.results import RunRecord, markdown_table
from slamkit.experiments.pose_graph_outliers.config import PoseGraphOutliersPipeline


def _report(config: PoseGraphOutliersPipeline, runs: list[RunRecord], clean, failures: list[str]) -> str:
    text = f"# Robust back-ends under false loop closures: {config.name or 'pose_graph_outliers'}\n\n"
    text += ("Vertigo-style false loop closures (slamkit.sim.outliers) added to each graph; every back-end "
             "starts from odometry dead reckoning and trusts the odometry edges. ATE is against ground "
             "truth (or the outlier-free least-squares optimum when there is none); ATE ratio is to the "
             "outlier-free least-squares solution's ATE (ground-truth datasets only); outlier recall = false loop closures rejected / "
             "all false ones; precision = false among the rejected; inlier recall = true edges kept. "
             "Means over seeds.\n\n")
    text += "Outlier-free least squares: " + ", ".join(
        f"{d} ATE {v[3]:.4g} m" for d, v in clean.items()) + "\n\n"
    header = ["dataset", "kind", "outliers", "back-end", "ATE (m)", "ATE ratio", "outlier recall",
              "outlier precision", "inlier recall", "iterations", "time (s)", "n"]
    groups: dict[tuple, list[RunRecord]] = {}
    for r in runs:
        groups.setdefault((r.dataset, r.params["kind"], r.params["outliers"], r.estimator), []).append(r)

    def mean(rs, m):
        v = [r.metrics[m] for r in rs if m in r.metrics and np.isfinite(r.metrics[m])]
        return float(np.mean(v)) if v else None

    rows = [[*key, mean(rs, "ate_rmse_m"), mean(rs, "ate_ratio"), mean(rs, "outlier_recall"),
             mean(rs, "outlier_precision"), mean(rs, "inlier_recall"), mean(rs, "iterations"),
             mean(rs, "time_solve_s"), len(rs)]
            for key, rs in groups.items()]
    text += markdown_table(header, rows) + "\n"
    if failures:
        text += "\n## Failed solves (no metrics)\n\n" + "\n".join(f"- {f}" for f in failures) + "\n"
    return text


def _plot(plots: Path, runs: list[RunRecord], backends: list[str]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    datasets = list(dict.fromkeys(r.dataset for r in runs if r.params["outliers"] > 0))
    kinds = list(dict.fromkeys(r.params["kind"] for r in runs if r.params["outliers"] > 0))
    if not datasets:
        return
    # one row per dataset, one column per outlier kind: a row compares the kinds on one graph
    fig, axes = plt.subplots(len(datasets), len(kinds), figsize=(4.6 * len(kinds), 3.8 * len(datasets)),
                             squeeze=False)
    for (row, dataset), (col, kind) in itertools.product(enumerate(datasets), enumerate(kinds)):
        ax = axes[row][col]
        for backend in backends:
            pts: dict[int, list[float]] = {}
            for r in runs:
                if (r.dataset == dataset and r.estimator == backend
                        and r.params["kind"] in (kind, "none")):
                    pts.setdefault(r.params["outliers"], []).append(r.metrics.get("ate_rmse_m", np.nan))
            xs = sorted(pts)
            ax.plot(xs, [np.nanmean(pts[x]) if np.isfinite(pts[x]).any() else np.nan for x in xs],
                    marker="o", label=backend)
        ax.set_xscale("symlog", linthresh=10)
        ax.set_yscale("log")
        ax.set_xlabel(f"{kind} false loop closures")
        ax.set_ylabel("ATE RMSE (m)")
        ax.set_title(f"{dataset}, {kind}")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(plots / "ate_vs_outliers.png", dpi=120)
    plt.close(fig)
