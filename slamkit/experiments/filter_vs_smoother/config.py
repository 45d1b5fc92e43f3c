"""The ``filter_vs_smoother`` config: scenarios, estimators, seeds and workers as frozen values.

The pydantic model (:class:`slamkit.experiments.config_models.FilterVsSmootherPipeline`) has
already refused malformed configs before the pipeline runs; these parsers turn the checked
mapping into the values the Monte-Carlo runs use (and give the same errors to callers that
bypass the model, such as notebooks).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from slamkit.errors import ConfigError
from slamkit.experiments.estimators import REGISTRY
from slamkit.paths import path_component

#: the pipeline's registry name (``pipeline: filter_vs_smoother``)
NAME = "filter_vs_smoother"
#: simulated presets: landmark worlds (slamkit.sim.landmark_world) and inertial drives
#: (slamkit.sim.inertial_world)
LANDMARK_PRESETS = ("mild", "strong")
INERTIAL_PRESETS = ("car3d", "car3d_tactical")
PRESETS = LANDMARK_PRESETS + INERTIAL_PRESETS
#: what a scenario entry names (exactly one)
SOURCES = ("preset", "dataset", "scenario")


@dataclass(frozen=True)
class ScenarioSpec:
    """One of: a simulated ``preset`` (landmark world or inertial drive), a registry ``dataset``,
    or a ``scenario`` file (a scenario YAML, e.g. a grid world; ``params`` override its fields)."""

    name: str
    preset: str | None = None
    dataset: str | None = None
    params: Mapping[str, Any] = field(default_factory=dict)
    scenario: str | None = None
    #: estimator label -> params overriding the pipeline's on this scenario
    estimator_params: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    #: labels of the pipeline's estimators not run on this scenario (``label: false`` in the config)
    skipped_estimators: frozenset[str] = frozenset()

    def estimator_choices(self, choices: list["EstimatorChoice"]) -> tuple["EstimatorChoice", ...]:
        """The pipeline's estimators with this scenario's overrides merged into their params,
        without the ones this scenario skips."""
        return tuple(EstimatorChoice(c.label, c.type, {**c.params, **self.estimator_params.get(c.label, {})})
                     for c in choices if c.label not in self.skipped_estimators)

    @property
    def simulated(self) -> bool:
        return self.preset is not None or self.scenario is not None


@dataclass(frozen=True)
class EstimatorChoice:
    label: str
    type: str
    params: Mapping[str, Any] = field(default_factory=dict)


def parse_scenarios(config: Mapping[str, Any]) -> list[ScenarioSpec]:
    raw = config.get("scenarios")
    if not raw:
        raise ConfigError("filter_vs_smoother: 'scenarios' must list simulated presets or datasets")
    out: list[ScenarioSpec] = []
    for k, item in enumerate(raw):
        if isinstance(item, str):
            item = {"preset": item} if item in PRESETS else {"dataset": item}
        if not isinstance(item, Mapping) or sum(key in item for key in SOURCES) != 1:
            raise ConfigError(f"filter_vs_smoother: scenarios[{k}] needs exactly one of 'preset', "
                              f"'dataset' or 'scenario', got {item!r}")
        unknown = set(item) - {*SOURCES, "name", "params", "estimators"}
        if unknown:
            raise ConfigError(f"filter_vs_smoother: scenarios[{k}] has unknown key(s) {sorted(unknown)}")
        if "preset" in item and item["preset"] not in PRESETS:
            raise ConfigError(f"filter_vs_smoother: scenarios[{k}].preset must be one of {', '.join(PRESETS)}, "
                              f"got {item['preset']!r}")
        default_name = item.get("preset") or item.get("dataset") or Path(str(item.get("scenario"))).stem
        name = path_component(str(item.get("name") or default_name), f"filter_vs_smoother: scenarios[{k}] name")
        entries = item.get("estimators") or {}
        overrides = {str(k): dict(v or {}) for k, v in entries.items() if v is not False}
        skipped = frozenset(str(k) for k, v in entries.items() if v is False)
        out.append(ScenarioSpec(name, item.get("preset"), item.get("dataset"), dict(item.get("params") or {}),
                                item.get("scenario"), overrides, skipped))
    names = [s.name for s in out]
    if len(set(names)) != len(names):
        raise ConfigError(f"filter_vs_smoother: scenario names must be unique, got {names} (set 'name')")
    return out


def parse_estimators(config: Mapping[str, Any]) -> list[EstimatorChoice]:
    raw = config.get("estimators")
    if not raw:
        raise ConfigError("filter_vs_smoother: 'estimators' must name registry estimators "
                          f"({', '.join(REGISTRY)})")
    items: list[tuple[str, Mapping[str, Any]]] = []
    if isinstance(raw, Mapping):
        items = [(str(k), dict(v or {})) for k, v in raw.items()]
    else:
        for entry in raw:
            if isinstance(entry, str):
                items.append((entry, {}))
            elif isinstance(entry, Mapping) and len(entry) == 1:
                (k, v), = entry.items()
                items.append((str(k), dict(v or {})))
            else:
                raise ConfigError(f"filter_vs_smoother: bad estimators entry {entry!r}")
    out = []
    for label, params in items:
        params = dict(params)
        try:  # the registry's one message (with its suggestion); old spellings warn
            kind = REGISTRY.canonical(str(params.pop("type", label)))
        except ConfigError as exc:
            raise ConfigError(f"filter_vs_smoother: estimators.{label}: {exc}") from None
        out.append(EstimatorChoice(path_component(label, "filter_vs_smoother: estimator label"), kind, params))
    return out


def parse_seeds(config: Mapping[str, Any]) -> list[int]:
    """The run's seeds (one rule for every pipeline: :func:`config_models.seed_list`)."""
    from slamkit.experiments.config_models import seed_list

    return seed_list(config.get("seeds", 1))


def default_workers() -> int:
    return max(1, min(2, os.cpu_count() or 1))


def parse_workers(config: Mapping[str, Any]) -> int:
    """Local processes for the seeds after the first (1: everything in this process)."""
    workers = int(config.get("workers", default_workers()))
    if workers < 1:
        raise ConfigError(f"filter_vs_smoother: workers must be >= 1, got {workers}")
    return workers
