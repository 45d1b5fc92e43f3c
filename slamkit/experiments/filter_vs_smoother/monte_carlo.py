"""The ``filter_vs_smoother`` Monte-Carlo runs: one task per scenario x seed, each building its
sequence, running every estimator through :func:`slamkit.experiments.runner.run_estimators`,
scoring them and writing their trajectories.

Where the work happens: the first seed of every scenario runs in this process, with the
pipeline's observer (it is the run the recording shows, so it keeps its sequence and estimates);
the other seeds run on the sweep layer's :class:`~slamkit.experiments.executors.LocalExecutor`
(``workers`` spawned processes with BLAS pinned to one thread each; ``workers: 1`` runs
everything here) and come back as finished :class:`TaskResult`s, which no observer sees step by
step.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from slamkit.config import build
from slamkit.data import registry
from slamkit.data.formats.kitti_imu_gps import load_kitti_imu_gps
from slamkit.data.formats.landmark_datasets import load_landmark_sequence
from slamkit.data.formats.plaza import load_plaza_sequence
from slamkit.data.formats.tum import write_tum
from slamkit.data.inertial import is_inertial
from slamkit.data.perturb import PerturbationConfig, perturb
from slamkit.data.sequence import Sequence
from slamkit.errors import ConfigError, EstimationError
from slamkit.experiments.estimators import factory, spec
from slamkit.experiments.executors import LocalExecutor, TaskFailure
from slamkit.experiments.config_models import seed_list
from slamkit.experiments.filter_vs_smoother.config import (INERTIAL_PRESETS, NAME, EstimatorChoice,
                                                            FilterVsSmootherPipeline, ScenarioSpec,
                                                            default_workers, estimators_of, scenarios_of,
                                                            typed_config)
from slamkit.experiments.observers import PipelineObserver
from slamkit.experiments.perturbation import perturbation_config, twin_params, twin_suffix
from slamkit.experiments.results import RunRecord
from slamkit.experiments.runner import EstimatorRun, ErrorSeries, run_estimators, score
from slamkit.metrics.inertial import inertial_metrics
from slamkit.paths import file_in
from slamkit.sim.inertial_world import PRESETS as INERTIAL_SCENARIOS, InertialScenario, simulate_inertial_sequence
from slamkit.sim.landmark_world import PRESETS as LANDMARK_SCENARIOS, LandmarkScenario, simulate_landmark_sequence
from slamkit.sim.scenario import load_scenario, simulate


def build_sequence(scenario: ScenarioSpec, seed: int) -> Sequence:
    """The sequence of one scenario and seed (datasets ignore the seed)."""
    if scenario.scenario is not None:
        return simulate(load_scenario(scenario.scenario, {"name": scenario.name, **scenario.params}), seed).sequence
    if scenario.preset in INERTIAL_PRESETS:
        config = build(InertialScenario, {**scenario.params, "name": scenario.name},
                       f"filter_vs_smoother: scenario {scenario.name!r}", base=INERTIAL_SCENARIOS[scenario.preset]())
        return simulate_inertial_sequence(config, np.random.default_rng(seed))
    if scenario.simulated:
        # the preset with the params over it (a sensor section over the preset's sensor)
        config = build(LandmarkScenario, {**scenario.params, "name": scenario.name},
                       f"filter_vs_smoother: scenario {scenario.name!r}", base=LANDMARK_SCENARIOS[scenario.preset]())
        return simulate_landmark_sequence(config, np.random.default_rng(seed))
    try:
        return _load_dataset(scenario)
    except ConfigError as exc:  # a parameter the reader refused (bounds that need the data)
        raise ConfigError(f"filter_vs_smoother: scenario {scenario.name!r}: params: {exc}") from None


def _load_dataset(scenario: ScenarioSpec) -> Sequence:
    if registry.get(scenario.dataset).kind == "inertial":
        return load_kitti_imu_gps(scenario.dataset, label=scenario.name, **dict(scenario.params))
    if registry.get(scenario.dataset).format == "plaza":
        return load_plaza_sequence(scenario.dataset, **dict(scenario.params))
    return load_landmark_sequence(scenario.dataset, **dict(scenario.params))


@dataclass(frozen=True)
class Task:
    scenario: ScenarioSpec
    seed: int
    estimators: tuple[EstimatorChoice, ...]
    trajectories_dir: str | None
    keep_full: bool = False
    #: which seeded twin of the sequence (slamkit.experiments.perturbation; 0: as built)
    perturbation: int = 0
    perturbations: PerturbationConfig = PerturbationConfig()


@dataclass(frozen=True)
class TaskResult:
    scenario: str
    seed: int
    records: list[RunRecord]
    series: dict[str, ErrorSeries]
    notes: list[str]
    reference: str
    perturbation: int = 0
    #: only with keep_full (the run the recording shows)
    sequence: Sequence | None = None
    runs: dict[str, EstimatorRun] | None = None


#: what a landmark-sequence run estimates: the pose against the known map, the pose alone with
#: no map (odometry, a user's map-free estimator), or the map too
SETTINGS = {"localisation": "localisation (map known)", "pose_only": "pose only (no map given or estimated)",
            "slam": "SLAM (map estimated)"}


def setting_of(estimator_type: str, sequence: Sequence) -> str | None:
    """'localisation' for an estimator given the sequence's landmark map, 'slam' for one that
    estimates it, 'pose_only' for one that does neither (its registry spec's ``estimates``);
    None on sequences without landmarks (inertial, grid worlds)."""
    if not sequence.world_p_landmarks:
        return None
    s = spec(estimator_type)
    if s.needs_landmark_map:
        return "localisation"
    return "slam" if s.estimates == "pose_and_map" else "pose_only"


def run_task(task: Task, observer: PipelineObserver | None = None) -> TaskResult:
    """Build the sequence, run every estimator, score them (and write their trajectories)."""
    sequence = perturb(build_sequence(task.scenario, task.seed), task.perturbation, task.perturbations)
    factories = {c.label: factory(c.type, c.params, seed=task.seed) for c in task.estimators}
    runs = run_estimators(sequence, factories, observer=observer, kind=NAME,
                          run_label=f"{task.scenario.name}/seed{task.seed}")
    reference, reference_name, is_truth = sequence.ground_truth, "ground_truth", True
    batch = next((r for c, r in zip(task.estimators, runs.values())
                  if c.type == "batch" and r.estimate is not None), None)
    if reference is None and batch is not None:
        reference, reference_name, is_truth = batch.estimate.trajectory, f"{batch.name} solution", False
    if reference is None and batch is None:
        reference_name = ("withheld GPS fixes" if sequence.metadata.get("withheld_gps") is not None
                          else "none")
    records, series, notes = [], {}, []
    for choice in task.estimators:
        run = runs[choice.label]
        scored = score(run, reference, sequence.world_p_landmarks, reference_is_truth=is_truth)
        if run.estimate is not None and is_inertial(sequence):
            scored.metrics.update(inertial_metrics(run.estimate, sequence.metadata))
        params = {"type": choice.type, "kind": run.kind, "reference": reference_name, **choice.params}
        setting = setting_of(choice.type, sequence)
        if setting is not None:
            params["setting"] = setting
        if run.failed:
            params["failed"] = run.failed
        params.update(twin_params(task.perturbation))
        records.append(RunRecord(task.scenario.name, choice.label, scored.metrics, task.seed, params))
        notes.extend(scored.notes)
        if scored.series is not None:
            series[choice.label] = scored.series
        if task.trajectories_dir is not None and run.estimate is not None:
            twin = twin_suffix(task.perturbation)
            write_tum(file_in(task.trajectories_dir, f"{task.scenario.name}_{choice.label}_seed{task.seed}{twin}", ".tum",
                              "scenario name / estimator label"),
                      run.estimate.trajectory)
    return TaskResult(task.scenario.name, task.seed, records, series, notes, reference_name,
                      task.perturbation, sequence if task.keep_full else None, runs if task.keep_full else None)


def run_monte_carlo(config: FilterVsSmootherPipeline | Mapping[str, Any], trajectories_dir: Path | None = None,
                    progress=None, observer: PipelineObserver | None = None
                    ) -> tuple[list[TaskResult], list[ScenarioSpec], list[EstimatorChoice]]:
    """Every scenario x seed (datasets once); the first seed of every scenario runs in this
    process with ``observer`` (and keeps its sequence and estimates), the rest in the pool.
    ``config``: the pipeline's model (a plain mapping is made one by :func:`typed_config`)."""
    config = typed_config(config)
    scenarios = scenarios_of(config.scenarios)
    choices = tuple(estimators_of(config.estimators))
    seeds = seed_list(config.seeds)
    workers = default_workers() if config.workers is None else config.workers
    tdir = None if trajectories_dir is None else str(trajectories_dir)
    twins = perturbation_config(config.perturbations)
    tasks = [Task(s, seed, s.estimator_choices(list(choices)), tdir, keep_full=(k == 0 and twin == 0),
                  perturbation=twin, perturbations=twins)
             for s in scenarios for k, seed in enumerate(seeds if s.simulated else seeds[:1])
             for twin in range(twins.count + 1)]
    advance = progress.task("filter vs smoother", len(tasks)) if progress is not None else (lambda n=1: None)
    main_tasks = [t for t in tasks if t.keep_full]
    pool_tasks = [t for t in tasks if not t.keep_full]
    results: list[TaskResult] = []
    if workers == 1 or not pool_tasks:
        for t in main_tasks:
            results.append(run_task(t, observer))
            advance()
        for t in pool_tasks:
            results.append(run_task(t))
            advance()
    else:
        with LocalExecutor(workers) as pool:
            for t in pool_tasks:
                pool.submit(run_task, t)
            for t in main_tasks:
                results.append(run_task(t, observer))
                advance()
            for t, outcome in pool.as_completed():
                if isinstance(outcome, TaskFailure):
                    # an estimator's own failure is recorded inside run_task; this is the task itself
                    raise EstimationError(f"{t.scenario.name} seed {t.seed}: {outcome.error_type}: "
                                          f"{outcome.message}")
                results.append(outcome)
                advance()
    order = {(t.scenario.name, t.seed, t.perturbation): k for k, t in enumerate(tasks)}
    results.sort(key=lambda r: order[(r.scenario, r.seed, r.perturbation)])
    return results, scenarios, list(choices)
