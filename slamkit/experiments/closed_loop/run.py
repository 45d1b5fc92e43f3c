"""The ``local_planning`` pipeline's run: every controller on every seeded scenario
(:func:`compare`), the episodes as run records; a pipeline observer gets a typed
:class:`LocalPlanningSnapshot` per step of the first ``record_scenarios`` scenarios."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Iterable, Mapping


from slamkit.control.registry import CONTROLLERS, make_controller
from slamkit.config import build
from slamkit.errors import ConfigError
from slamkit.experiments.closed_loop.config import LocalPlanningPipeline, LocalPlanningScenarios
from slamkit.experiments.closed_loop.episode import (ClosedLoopConfig, ControlStep, Episode, Scenario, make_scenario,
                                                     run_episode)
from slamkit.experiments.closed_loop.report import plot, report_markdown
from slamkit.experiments.config_models import seed_list, typed_config
from slamkit.experiments.observers import PipelineObserver, StepSnapshot
from slamkit.experiments.pipeline import PipelineOutput, StepProgress
from slamkit.experiments.results import ResultsFolder, RunRecord, summarise


# --------------------------------------------------------------------------- comparison


def scenario_list(scenarios: "LocalPlanningScenarios") -> list[Scenario]:
    """The seeded scenarios of a config's ``scenarios`` (kinds taken in turn over the seeds).

    ``obstacle_min_side_m``: how far from the path a shuttling obstacle may turn round: measured
    on 30 scenarios, 0.5 m left 17 % collisions for DWA and MPC, nearly all obstacles reversing
    beside the robot (a constant-velocity prediction cannot foresee it); 1 m gave 0-3 % but fits
    fewer obstacles."""
    kinds = scenarios.kinds
    speed = tuple(float(v) for v in scenarios.obstacle_speed_mps)
    return [make_scenario(seed, kinds[i % len(kinds)], scenarios.n_obstacles, obstacle_speed_mps=speed,
                          obstacle_min_side_m=scenarios.obstacle_min_side_m)
            for i, seed in enumerate(seed_list(scenarios.seeds))]


@dataclass(frozen=True)
class LocalPlanningSnapshot:
    """The state of a ``local_planning`` step snapshot (issue 30, item 4: a type, not a dict of
    string keys): the episode's scenario, the controller's name and the cycle's
    :class:`ControlStep` (values only: the pose, the controller's output, the obstacles)."""

    scenario: Scenario
    controller: str
    step: ControlStep


class _PipelineStepAdapter:
    """Forwards closed-loop steps to a pipeline observer (``slamkit.experiments.observers``) as
    ``StepSnapshot(kind="local_planning", run="<controller>/<scenario>", ...)`` whose state is a
    :class:`LocalPlanningSnapshot`."""

    def __init__(self, observer, controller: str, scenario: Scenario):
        self.observer, self.controller, self.scenario = observer, controller, scenario

    def on_episode(self, scenario: Scenario, controller: str) -> None:
        pass

    def on_step(self, snap: ControlStep) -> None:
        self.observer.on_step(StepSnapshot("local_planning", f"{self.controller}/{self.scenario.name}",
                                           snap.step, snap.t_s,
                                           LocalPlanningSnapshot(self.scenario, self.controller, snap)))


def compare(config: "LocalPlanningPipeline | Mapping[str, Any]", observer=None,
            progress: Callable[[int], None] | None = None) -> tuple[list[Episode], list[Scenario]]:
    """Every controller on every scenario of ``config`` (the pipeline's model; a plain mapping
    is made one by :func:`~slamkit.experiments.config_models.typed_config`). A pipeline
    ``observer`` that wants steps sees the episodes of the first ``record_scenarios`` scenarios
    (default 1, to keep recordings small)."""
    config = typed_config(LocalPlanningPipeline, config)
    controllers = config.controllers
    try:  # every name checked before the first episode runs
        names = [CONTROLLERS.canonical(c) for c in controllers]
    except ConfigError as exc:
        raise ConfigError(f"controllers: {exc}") from None
    params = config.controller_params
    loop = build(ClosedLoopConfig, config.closed_loop, "closed_loop")
    watch = observer is not None and observer.wants_steps
    episodes = []
    scenarios = scenario_list(config.scenarios)
    for typed, name in zip(controllers, names):
        ctl = make_controller(name, params.get(typed, params.get(name)))
        for i, sc in enumerate(scenarios):
            obs = [_PipelineStepAdapter(observer, name, sc)] if watch and i < config.record_scenarios else []
            episodes.append(run_episode(sc, ctl, loop, obs))
            if progress is not None:
                progress(1)
    return episodes, scenarios


def episodes_to_runs(episodes: Iterable[Episode]) -> list[RunRecord]:
    """One RunRecord per episode; dataset = "local_planning" so the summary groups by controller
    over all scenarios (the scenario name is kept in params)."""
    return [RunRecord("local_planning", e.controller, dict(e.metrics), seed=e.seed,
                      params={"scenario": e.scenario}) for e in episodes]


def run(config: LocalPlanningPipeline, folder: ResultsFolder, progress: StepProgress,
        observer: PipelineObserver | None = None) -> PipelineOutput[list[Episode]]:
    """Pipeline ``local_planning`` (``PIPELINE`` below) on its validated, resolved model:
    controllers x seeded scenarios -> results.json runs/summary, report.md and plots; the observer
    (the recorder the viz layer registers, ``slamkit.viz.control.LocalPlanningObserver``) records
    the steps."""
    n = len(seed_list(config.scenarios.seeds)) * len(config.controllers)
    advance = progress.task("closed-loop episodes", n)
    episodes, scenarios = compare(config, observer, advance)
    runs = episodes_to_runs(episodes)
    summary = summarise(runs)
    plot(folder.plots, episodes, {s.name: s for s in scenarios})
    return PipelineOutput(runs, report_markdown(config, episodes, summary), summary, payload=episodes)
