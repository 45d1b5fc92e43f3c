"""The ``navigation`` pipeline's run: every world x seed (development, then evaluation blocks) x
variant through :func:`~.episode.run_episode` on the robot's map, the episodes as run records with
their seed block."""

from __future__ import annotations

import dataclasses
from typing import Mapping

from slamkit.config import build
from slamkit.data.registry import path_of
from slamkit.experiments.config_models import seed_list
from slamkit.experiments.navigation.benchmark import (DEV_BLOCK, benchmark_markdown, block_of, benchmark_rows,
                                                      difficulty_rows, plot_benchmark, seed_blocks)
from slamkit.experiments.navigation.config import NavigationPipeline, NavigationScenarios, variants_of
from slamkit.experiments.navigation.episode import Episode, make_navigation_scenario, run_episode
from slamkit.experiments.navigation.map_source import MapSourceConfig, RobotMap, robot_map
from slamkit.experiments.navigation.report import plot, report_markdown
from slamkit.experiments.navigation.snapshot import _snapshots
from slamkit.experiments.observers import PipelineObserver
from slamkit.experiments.pipeline import PipelineOutput, StepProgress
from slamkit.experiments.results import ResultsFolder, RunRecord, summarise
from slamkit.sim.navigation_world import NavigationScenario


def willow_yaml(spec: str | None) -> str:
    """The Willow map YAML: a path, or the dataset registry's ``willow`` entry (None)."""
    if spec is None or spec == "willow":
        return str(path_of("willow", "maps_ros/willow-2010-02-18-0.10.yaml"))
    return str(spec)


def scenarios_of(scenarios: "NavigationScenarios") -> list[NavigationScenario]:
    """Every world x seed (development, then evaluation blocks) of a config's ``scenarios``."""
    seeds = [seed for _block, seed in seed_blocks_of(scenarios)]
    willow = willow_yaml(scenarios.willow_map) if "willow" in scenarios.worlds else None
    return [make_navigation_scenario(seed, w, willow, n_obstacles=scenarios.n_obstacles, agents=scenarios.agents)
            for w in scenarios.worlds for seed in seeds]


def seed_blocks_of(scenarios: "NavigationScenarios") -> list[tuple[str, int]]:
    """(block, seed) of every episode seed: ``scenarios.seeds`` as the development block, then
    the ``scenarios.evaluation`` blocks (:mod:`slamkit.experiments.navigation.benchmark`)."""
    evaluation = None if scenarios.evaluation is None else scenarios.evaluation.model_dump()
    return seed_blocks(seed_list(scenarios.seeds), evaluation)


def runs_of(episodes: list[Episode], blocks: Mapping[int, str] | None = None) -> list[RunRecord]:
    """The episodes as run records; ``params.block`` says which seed block each came from."""
    blocks = blocks or {}
    return [RunRecord(e.world, e.variant, dict(e.metrics), seed=e.seed,
                      params={"scenario": e.scenario, "block": blocks.get(e.seed, DEV_BLOCK)})
            for e in episodes]


def run(config: NavigationPipeline, folder: ResultsFolder, progress: StepProgress,
        observer: PipelineObserver | None = None) -> PipelineOutput[list[Episode]]:
    """Pipeline ``navigation`` on its validated, resolved model: worlds x seeds x variants ->
    runs, summary, report, plots."""
    variants = variants_of(config.navigation, config.episode, config.variants)
    map_config = build(MapSourceConfig, config.map, "map")
    scenarios = scenarios_of(config.scenarios)
    advance = progress.task("navigation episodes", len(scenarios) * len(variants))
    watch = observer is not None and observer.wants_steps
    episodes = []
    maps: dict[str, RobotMap] = {}
    for i, sc in enumerate(scenarios):
        maps[sc.name] = robot = robot_map(sc, map_config, folder.path / "maps")
        for name, nav, ep in variants:
            hook = _snapshots(observer, f"{name}/{sc.name}", sc) if watch and i < config.record_scenarios else None
            episode = run_episode(sc, nav, ep, name, hook, robot)
            episodes.append(dataclasses.replace(episode, metrics={**episode.metrics, **robot.metrics}))
            advance(1)
    blocks = seed_blocks_of(config.scenarios)
    runs = runs_of(episodes, {seed: block for block, seed in blocks})
    # development and evaluation seeds never share a mean (the protocol of navigation.benchmark)
    summary = summarise(runs, lambda r: {"dataset": r.dataset, "estimator": r.estimator,
                                         "seeds": "development" if block_of(r) == DEV_BLOCK else "evaluation"})
    plot(folder.plots, episodes, {s.name: s for s in scenarios})
    rows, by_difficulty = benchmark_rows(runs), difficulty_rows(runs)
    plot_benchmark(folder.plots / "benchmark.png", rows, by_difficulty)
    evaluation = config.scenarios.evaluation
    protocol = {"dev_seeds": [s for b, s in blocks if b == DEV_BLOCK],
                "evaluation": None if evaluation is None else evaluation.model_dump()}
    text = benchmark_markdown(rows, by_difficulty, protocol)
    return PipelineOutput(runs, report_markdown(config, episodes, summary, maps, text), summary,
                          extra={"benchmark": {"protocol": protocol, "rows": rows, "by_difficulty": by_difficulty}},
                          payload=episodes)
