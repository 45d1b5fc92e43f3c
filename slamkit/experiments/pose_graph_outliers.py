"""Robust back-ends under false loop closures: the ``pose_graph_outliers`` pipeline.

For every dataset x outlier kind x outlier count x seed, ``slamkit.sim.outliers`` adds seeded
Vertigo-style false loop closures and every back-end of ``slamkit.backend.robust`` solves the
corrupted graph. Scores per run: ATE against ground truth (``ate_rmse_m``; datasets without one
are scored against their outlier-free least-squares optimum), the ratio to the outlier-free
solution's ATE (``ate_ratio``, ground-truth datasets only), ATE against that optimum (``ate_to_clean_rmse_m``), outlier
recall (rejected false loop closures / all false ones), outlier precision (false among rejected),
inlier recall (true edges kept), iterations and solve time. Count 0 runs once per dataset.

Back-end ``pcm`` composes the front-end check ``slamkit.frontend.pcm`` (pairwise consistency
with the first-order cycle covariance, exact maximum clique) with least squares on the accepted
edges; ``pcm_gnc`` with GNC. Every back-end re-admits the rejected loop closures inside the chi2 gate at its solution (the
``readmit`` option of ``RobustSolveConfig``), PCM's rejections included.
"""

from __future__ import annotations

import itertools
from dataclasses import replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from slamkit.backend.robust import ROBUST_BACKENDS, RobustResult, RobustSolveConfig, solve_robust
from slamkit.frontend.pcm import pcm
from slamkit.config import build
from slamkit.data import registry
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import BackendError
from slamkit.experiments.config_models import PoseGraphOutliersPipeline
from slamkit.experiments.observers import PipelineObserver
from slamkit.experiments.pipeline import Pipeline, PipelineOutput, StepProgress
from slamkit.experiments.results import ResultsFolder, RunRecord, markdown_table, summarise
from slamkit.metrics.evaluate import trajectory_from_pose_graph
from slamkit.metrics.trajectory_score import ate_paired_by_stamp
from slamkit.sim.outliers import CorruptedGraph, OutlierConfig, add_outliers
from slamkit.metrics.outliers import detection_scores
from slamkit.timing import Stopwatch


def _trajectory(graph: PoseGraph, poses: np.ndarray):
    return trajectory_from_pose_graph(replace(graph, poses=poses, has_initial=True))


def run(config: PoseGraphOutliersPipeline, folder: ResultsFolder, progress: StepProgress,
        observer: PipelineObserver) -> PipelineOutput[list[dict[str, Any]]]:
    """Pipeline ``pose_graph_outliers`` on its validated, resolved model: every dataset x outlier
    kind x count x seed x back-end."""
    datasets = config.datasets
    counts = sorted(set(config.counts))
    kinds, backends, seeds = config.kinds, config.backends, config.seeds
    outlier_options, solve_options = config.outliers, config.solver
    cells = [(d, k, c, s) for d in datasets for k, c, s in itertools.product(kinds, counts, seeds)
             if c > 0 or (k == kinds[0] and s == seeds[0])]
    advance = progress.task("outlier cells", len(cells) * len(backends))
    runs: list[RunRecord] = []
    failures: list[str] = []
    clean: dict[str, tuple[PoseGraph, Any, RobustResult, float]] = {}
    for dataset, kind, count, seed in cells:
        if dataset not in clean:
            graph, entry = registry.load_pose_graph_source(dataset)
            gt = registry.ground_truth(entry.name) if entry is not None else None
            base = solve_robust(graph, _solve_config("none", solve_options))
            reference = gt if gt is not None else _trajectory(graph, base.poses)
            # without ground truth the reference is the outlier-free optimum itself: its ATE is 0
            # up to rounding (1e-15 m) and a ratio to it means nothing
            clean_ate = ate_paired_by_stamp(reference, _trajectory(graph, base.poses))[0] if gt is not None else 0.0
            clean[dataset] = (graph, reference, base, clean_ate)
        graph, reference, base, clean_ate = clean[dataset]
        corrupted = (CorruptedGraph(graph, np.zeros(graph.num_edges, bool), OutlierConfig(kind, 0), seed)
                     if count == 0 else
                     add_outliers(graph, build(OutlierConfig, outlier_options, "pose_graph_outliers.outliers",
                                                base=OutlierConfig(kind=kind, count=count)),
                                  np.random.default_rng(seed), seed))
        clean_traj = _trajectory(graph, base.poses)
        for backend in backends:
            try:
                result = _solve(corrupted.graph, backend, solve_options)
            except BackendError as exc:  # one failed solve is a result of the benchmark, not its end
                failures.append(f"{dataset} / {kind} / {count} / seed {seed} / {backend}: {exc}")
                runs.append(RunRecord(dataset, backend, {"failed": 1.0}, seed=seed,
                                      params={"kind": kind if count else "none", "outliers": count}))
                advance()
                continue
            est = _trajectory(corrupted.graph, result.poses)
            ate = ate_paired_by_stamp(reference, est)[0]
            metrics = {"ate_rmse_m": ate, "ate_ratio": ate / clean_ate if clean_ate > 0 else float("nan"),
                       "ate_to_clean_rmse_m": ate_paired_by_stamp(clean_traj, est)[0],
                       **detection_scores(corrupted.is_outlier, result.inlier),
                       "iterations": float(result.iterations), "time_solve_s": result.time_solve_s,
                       "failed": 0.0}
            runs.append(RunRecord(dataset, backend, metrics, seed=seed,
                                  params={"kind": kind if count else "none", "outliers": count}))
            advance()
    summary = summarise(runs, by=lambda r: {"dataset": r.dataset, "kind": r.params["kind"],
                                            "outliers": r.params["outliers"], "estimator": r.estimator})
    _plot(folder.plots, runs, backends)
    return PipelineOutput(runs, _report(config, runs, clean, failures), summary=summary,
                          payload=[r.to_dict() for r in runs])


#: every back-end the pipeline knows: the robust solvers plus PCM before least squares / GNC
BACKENDS = ROBUST_BACKENDS + ("pcm", "pcm_gnc")


def _solve_config(backend: str, solve_options: Mapping[str, Any]) -> RobustSolveConfig:
    return build(RobustSolveConfig, solve_options, "pose_graph_outliers.solver", base=RobustSolveConfig(backend=backend))


def _solve(graph: PoseGraph, backend: str, solve_options: Mapping[str, Any]) -> RobustResult:
    if not backend.startswith("pcm"):
        return solve_robust(graph, _solve_config(backend, solve_options))
    with Stopwatch() as sw:
        accepted = pcm(graph).accepted
        result = solve_robust(graph, _solve_config("gnc" if backend == "pcm_gnc" else "none", solve_options),
                              accepted=accepted)
    return replace(result, backend=backend, time_solve_s=sw.elapsed_s)


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


PIPELINE: Pipeline[PoseGraphOutliersPipeline, list[dict[str, Any]]] = Pipeline(
    "pose_graph_outliers", run, PoseGraphOutliersPipeline, list,
    "robust back-ends x Vertigo-style false loop closures (counts, kinds, seeds)")
