"""Pipeline ``filter_vs_smoother``: filters and smoothers on the same sequences, scored by the
same metrics, Monte-Carlo over seeds.

Config (``pipelines/filter_vs_smoother.yaml``)::

    pipeline: filter_vs_smoother
    seeds: 4                 # an int n (seeds 0..n-1) or a list of seeds
    workers: 2               # local processes (default min(2, cpu count)); 1 runs in-process
    scenarios:
      - preset: mild         # simulated landmark world: mild | strong (slamkit.sim.landmark_world)
        name: mild           # optional label
        params: {duration_s: 40}   # LandmarkScenario fields; sensor: {RangeBearingSensor fields}
      - dataset: citytrees10000    # a registry name (slamkit.data.formats.landmark_datasets)
        params: {max_poses: 300}
    estimators:              # registry name -> params (or a list of names); ``type`` lets one
      ekf: {}                # estimator appear twice: pf_small: {type: pf, n_particles: 200}
      pf: {n_particles: 500}
      batch: {}

Inertial scenarios (issue 13) run through the same loop: the presets ``car3d`` and
``car3d_tactical`` (:mod:`slamkit.sim.inertial_world`) and the dataset ``kitti-imu-gps`` (params
``outage_s``, ``gap_s``, ``first_outage_after_s``, ``max_duration_s``: GPS withheld in windows),
with the estimators ``es_ekf``, ``isam2_imu``, ``fixed_lag_imu``; their runs add the metrics of
:mod:`slamkit.metrics.inertial` (position error at withheld fixes, bias error against the
simulator's truth) and the report the "GPS outages" and "IMU biases" tables
(``pipelines/filter_vs_smoother_inertial.yaml``).

Simulated scenarios are drawn once per seed; datasets are deterministic and run once (seed 0
seeds the particle methods). A dataset without ground truth is scored against the batch
solution when ``batch`` is configured (NEES is then not computed: the batch solution is not the
truth).

Output: ``results.json`` (runs + mean and 95% CI per scenario x estimator x metric, plus
``consistency``: the Monte-Carlo average NEES against its chi2(3M)/M band), ``report.md``,
``plots/`` (error over time with 3-sigma bounds, average NEES with its band, ATE with CI),
``trajectories/<scenario>_<estimator>_seed<k>.tum``. The payload handed to the observer holds,
per scenario, the first seed's sequence, runs and error series.

Modules, each readable on its own (issue 18 split the former 480-line module):
:mod:`.config` (the config model, and the checked config built into frozen values), :mod:`.monte_carlo` (sequences,
tasks, the process pool; which seeds an observer sees live), :mod:`.score` (Monte-Carlo NEES
consistency, the payload), :mod:`.report` (Markdown and plots). This module composes them into
the :class:`~slamkit.experiments.pipeline.Pipeline` ``PIPELINE``.
"""

from __future__ import annotations

from typing import Any, Mapping

from slamkit.experiments.filter_vs_smoother.config import (NAME, EstimatorChoice, FilterVsSmootherPipeline,
                                                            ScenarioSpec, default_workers, estimators_of,
                                                            scenarios_of, typed_config)
from slamkit.experiments.filter_vs_smoother.monte_carlo import (Task, TaskResult, build_sequence,
                                                                 run_monte_carlo, run_task)
from slamkit.experiments.filter_vs_smoother.report import plot_all, report_markdown
from slamkit.experiments.filter_vs_smoother.score import (DEGENERATE_VERDICT_LIMIT, FilterVsSmootherPayload,
                                                           NeesCurve, ScenarioOutcome, consistency_table,
                                                           nees_verdict, payload_of)
from slamkit.experiments.observers import PipelineObserver
from slamkit.experiments.pipeline import Pipeline, PipelineOutput, StepProgress
from slamkit.experiments.results import ResultsFolder, paired_comparisons, summarise

__all__ = [
    "DEGENERATE_VERDICT_LIMIT", "EstimatorChoice", "FilterVsSmootherPayload", "NeesCurve", "PIPELINE",
    "ScenarioOutcome", "ScenarioSpec", "Task", "TaskResult", "assemble", "build_sequence",
    "consistency_table", "default_workers", "estimators_of", "nees_verdict", "scenarios_of",
    "typed_config", "plot_all", "report_markdown", "run", "run_monte_carlo", "run_task",
]


def run(config: FilterVsSmootherPipeline, folder: ResultsFolder, progress: StepProgress,
        observer: PipelineObserver) -> PipelineOutput[FilterVsSmootherPayload]:
    """Pipeline ``filter_vs_smoother`` (see the module docstring) on its validated, resolved model."""
    results, scenarios, choices = run_monte_carlo(config, folder.trajectories, progress, observer)
    output = assemble(config, results, scenarios, choices)
    setting = {(rec.dataset, rec.estimator): rec.params.get("setting") for rec in output.runs}
    plot_all(folder.plots, output.payload, output.summary, setting)
    return output


def assemble(config: FilterVsSmootherPipeline | Mapping[str, Any], results: list[TaskResult],
             scenarios: list[ScenarioSpec], choices: list[EstimatorChoice]
             ) -> PipelineOutput[FilterVsSmootherPayload]:
    """The pipeline's output from its task results: runs, summary, consistency, report, payload.
    Everything but ``runs`` is over the data as given; perturbed twins only enter the runner's
    perturbation table (slamkit.experiments.perturbation). ``config`` as for ``run_monte_carlo``."""
    config = typed_config(config)
    every_record = [rec for r in results for rec in r.records]
    results = [r for r in results if r.perturbation == 0]
    records = [rec for r in results for rec in r.records]
    summary = summarise(records)
    # the best estimator is looked for within a setting: localisation and SLAM never compete
    paired = paired_comparisons(records, treatment=lambda r: r.estimator,
                                context=lambda r: {"dataset": r.dataset, "setting": r.params.get("setting")})
    rows, curves = consistency_table(results, scenarios, choices)
    payload = payload_of(results, scenarios, choices, curves)
    notes = sorted({n for r in results for n in r.notes})
    references = {r.scenario: r.reference for r in results}
    report = report_markdown(config, summary, rows, scenarios, references, notes, results, paired)
    return PipelineOutput(every_record, report, summary, {"consistency": rows, "paired": paired}, payload)


PIPELINE: Pipeline[FilterVsSmootherPipeline, FilterVsSmootherPayload] = Pipeline(
    NAME, run, FilterVsSmootherPipeline, FilterVsSmootherPayload,
    "filters and smoothers on the same sequences, Monte-Carlo over seeds")
