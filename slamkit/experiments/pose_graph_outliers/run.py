"""The ``pose_graph_outliers`` pipeline's run: each dataset solved clean once, then every
corrupted cell by every back-end (PCM composed with least squares or GNC), scored against ground
truth (or the clean optimum) and by its outlier detection."""

from __future__ import annotations

import itertools
from dataclasses import replace
from typing import Any, Mapping

import numpy as np

from slamkit.backend.robust import ROBUST_BACKENDS, RobustResult, RobustSolveConfig, solve_robust
from slamkit.frontend.pcm import pcm
from slamkit.config import build
from slamkit.data import registry
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import BackendError
from slamkit.experiments.observers import PipelineObserver
from slamkit.experiments.pipeline import PipelineOutput, StepProgress
from slamkit.experiments.results import ResultsFolder, RunRecord, summarise
from slamkit.metrics.evaluate import trajectory_from_pose_graph
from slamkit.metrics.trajectory_score import ate_paired_by_stamp
from slamkit.sim.outliers import CorruptedGraph, OutlierConfig, add_outliers
from slamkit.metrics.outliers import detection_scores
from slamkit.timing import Stopwatch
from slamkit.experiments.pose_graph_outliers.config import PoseGraphOutliersPipeline
from slamkit.experiments.pose_graph_outliers.report import _plot, _report


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
