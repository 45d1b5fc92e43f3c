"""The ``pose_graph`` pipeline's run: every dataset x solver x initialisation through
:func:`~slamkit.experiments.pose_graph.optimize.optimize_source`, one run record each, the
solutions in ``trajectories/``."""

from __future__ import annotations

import itertools

from slamkit.backend.solvers import OptimizeConfig
from slamkit.config import build
from slamkit.errors import ConfigError
from slamkit.experiments.observers import PipelineObserver
from slamkit.experiments.pipeline import PipelineOutput, StepProgress
from slamkit.experiments.pose_graph.config import PoseGraphPipeline
from slamkit.experiments.pose_graph.optimize import OptimizeReport, optimize_source, write_outputs
from slamkit.experiments.pose_graph.report import _plot, _report_markdown
from slamkit.experiments.results import ResultsFolder, RunRecord


def run(config: PoseGraphPipeline, folder: ResultsFolder, progress: StepProgress,
        observer: PipelineObserver) -> PipelineOutput[list[OptimizeReport]]:
    """Pipeline ``pose_graph``: every dataset x solver x initialisation (initialisations that do
    not apply to a dataset's dimension -- LAGO is 2D, chordal is 3D -- are skipped and noted).
    ``config`` is the validated, resolved model (its ``options`` every OptimizeConfig field but
    the three each combination sets)."""
    combos = list(itertools.product(config.datasets, config.solvers, config.inits))
    robust = config.robust
    advance = progress.task("pose graphs", len(combos))
    runs: list[RunRecord] = []
    reports: list[OptimizeReport] = []
    skipped: list[str] = []
    for dataset, solver, init in combos:
        cfg = build(OptimizeConfig, config.options, "pose_graph.options",
                    base=OptimizeConfig(solver=solver, init=init, robust=robust))
        try:
            report = optimize_source(dataset, cfg, certify_mode=config.certify)
        except ConfigError as exc:
            skipped.append(f"{dataset} / {solver} / {init}: {exc}")
            advance()
            continue
        reports.append(report)
        metrics = {k: v for k, v in report.summary().items()
                   if isinstance(v, (int, float)) and not isinstance(v, bool) and k != "num_poses"}
        metrics.update(report.certificate_metrics())
        if report.retry is not None:
            metrics.update({f"retry_{k}": v for k, v in report.retry.certificate_metrics().items()})
            metrics["retry_final_error"] = report.retry.final_error
        runs.append(RunRecord(report.dataset, f"{solver}/{init}", metrics,
                              params={"solver": solver, "init": init, "robust": robust}))
        write_outputs(folder.trajectories, report, f"{report.dataset}_{solver}_{init}")
        advance()
    _plot(folder.plots, reports)
    return PipelineOutput(runs, _report_markdown(config, reports, skipped), payload=reports)
