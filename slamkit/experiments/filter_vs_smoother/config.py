"""The ``filter_vs_smoother`` config: its pydantic model and the frozen values the runs use.

The model (:class:`FilterVsSmootherPipeline`, at the end of this module) refuses malformed
configs before the pipeline runs, naming file and line; the pipeline runs on that model
(issue 30: ``config.seeds``, ``config.workers``, never a mapping's keys with restated defaults),
and :func:`typed_config` gives a notebook's plain mapping the same model by the same path.
:func:`scenarios_of` and :func:`estimators_of` turn its ``scenarios`` and ``estimators`` into
:class:`ScenarioSpec` and :class:`EstimatorChoice` values with :func:`slamkit.config.build` (the
entries' own rules -- exactly one source, a known preset, plain names, a registered estimator --
are the dataclasses', checked once for the config check and the run alike; callers that bypass
the model, such as notebooks, get the same errors).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal, Mapping, Sequence, Union

import pydantic
from pydantic import BaseModel, Field

from slamkit.config import STRICT, YamlDocument, build, dump, model_of, params_model_of, resolved, validate
from slamkit.data import registry
from slamkit.data.formats import landmark_datasets as lm
from slamkit.data.formats.kitti_imu_gps import read_kitti_imu_gps
from slamkit.data.formats.plaza import read_plaza_sequence
from slamkit.data.noise import SENSOR_SIGMAS
from slamkit.errors import ConfigError, SlamkitError
from slamkit.experiments.config_models import PipelineConfig, Seeds, _check_perturbations, _nested
from slamkit.experiments.config_models import typed_config as typed_model
from slamkit.experiments.estimators import REGISTRY, config_class
from slamkit.paths import path_component
from slamkit.sim.inertial_world import PRESETS as INERTIAL_SCENARIOS, InertialScenario
from slamkit.sim.landmark_world import PRESETS as LANDMARK_SCENARIOS, LandmarkScenario
from slamkit.sim.scenario import load_scenario

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
    or a ``scenario`` file (a scenario YAML, e.g. a grid world; ``params`` override its fields).
    The fields are a ``scenarios`` entry's keys, built with :func:`slamkit.config.build`; the
    rules of an entry (exactly one source, a known preset, a plain name) are checked here, once,
    for the config check and the run alike."""

    #: "" -> the preset's, the dataset's or the scenario file's name
    name: str = ""
    preset: str | None = None
    dataset: str | None = None
    params: Mapping[str, Any] = field(default_factory=dict)
    scenario: str | None = None
    #: estimator label -> params overriding the pipeline's on this scenario, or False: the
    #: pipeline's estimator is not run on this scenario
    estimators: Mapping[str, Mapping[str, Any] | bool | None] = field(default_factory=dict)

    def __post_init__(self) -> None:
        sources = {key: getattr(self, key) for key in SOURCES if getattr(self, key) is not None}
        if len(sources) != 1:
            raise ConfigError(f"needs exactly one of 'preset', 'dataset' or 'scenario', got {sources or 'none'}")
        if self.preset is not None and self.preset not in PRESETS:
            raise ConfigError(f"preset must be one of {', '.join(PRESETS)}, got {self.preset!r}")
        default = self.preset or self.dataset or Path(str(self.scenario)).stem
        object.__setattr__(self, "name", path_component(str(self.name or default), "name"))

    @property
    def estimator_params(self) -> dict[str, dict[str, Any]]:
        """Estimator label -> params overriding the pipeline's on this scenario."""
        return {str(k): dict(v or {}) for k, v in self.estimators.items() if v is not False}

    @property
    def skipped_estimators(self) -> frozenset[str]:
        """Labels of the pipeline's estimators not run on this scenario (``label: false``)."""
        return frozenset(str(k) for k, v in self.estimators.items() if v is False)

    def estimator_choices(self, choices: list["EstimatorChoice"]) -> tuple["EstimatorChoice", ...]:
        """The pipeline's estimators with this scenario's overrides merged into their params,
        without the ones this scenario skips."""
        overrides, skipped = self.estimator_params, self.skipped_estimators
        return tuple(EstimatorChoice(c.label, c.type, {**c.params, **overrides.get(c.label, {})})
                     for c in choices if c.label not in skipped)

    @property
    def simulated(self) -> bool:
        return self.preset is not None or self.scenario is not None


@dataclass(frozen=True)
class EstimatorChoice:
    """An ``estimators`` entry: its label (a file name), its registry type (the label unless
    ``type`` says otherwise; an old spelling becomes the registered one) and its params."""

    label: str
    type: str
    params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        path_component(self.label, "estimator label")
        # the registry's one message (with its suggestion); old spellings warn
        object.__setattr__(self, "type", REGISTRY.canonical(str(self.type)))


def scenario_entries(raw: Any) -> list[dict[str, Any]]:
    """A config's ``scenarios`` as mappings of :class:`ScenarioSpec` fields: a bare name is a
    preset if it is one, else a dataset."""
    return [({"preset": item} if item in PRESETS else {"dataset": item}) if isinstance(item, str) else item
            for item in raw or []]


def scenarios_of(entries: Sequence[Any]) -> list[ScenarioSpec]:
    """A config's ``scenarios`` entries (names, mappings or the model's :class:`ScenarioEntry`;
    :func:`scenario_entries`), each built by :func:`slamkit.config.build`; their names are unique."""
    plain = [e.model_dump(exclude_none=True) if isinstance(e, BaseModel) else e for e in entries]
    out = [build(ScenarioSpec, item, f"filter_vs_smoother: scenarios[{k}]")
           for k, item in enumerate(scenario_entries(plain))]
    names = [s.name for s in out]
    if len(set(names)) != len(names):
        raise ConfigError(f"filter_vs_smoother: scenario names must be unique, got {names} (set 'name')")
    return out


def preset_scenario(preset: str) -> tuple[type, Any]:
    """The scenario class of a simulated ``preset`` and the preset's scenario: a ``scenarios``
    entry's ``params`` are that class's fields over the preset."""
    if preset in INERTIAL_PRESETS:
        return InertialScenario, INERTIAL_SCENARIOS[preset]()
    return LandmarkScenario, LANDMARK_SCENARIOS[preset]()


def params_changed(scenario: ScenarioSpec) -> dict[str, Any]:
    """A scenario's ``params`` less those equal to its preset's values (all of them for a
    dataset or scenario file): what the report names, now that ``config.yaml`` spells every
    preset field out."""
    if scenario.preset is None:
        return dict(scenario.params)
    return _changed(dump(dict(scenario.params)), dump(preset_scenario(scenario.preset)[1]))


def _changed(values: Mapping[str, Any], base: Mapping[str, Any]) -> dict[str, Any]:
    """The entries of ``values`` that differ from ``base``'s, nested sections by their fields."""
    out = {}
    for key, value in values.items():
        was = base.get(key)
        if isinstance(value, Mapping) and isinstance(was, Mapping):
            value = _changed(value, was)
            if value:
                out[key] = value
        elif value != was:
            out[key] = value
    return out


def estimator_items(raw: Any) -> list[tuple[str, dict[str, Any]]]:
    """(label, params) of a config's ``estimators`` (a mapping or a list of names / 1-key maps)."""
    if isinstance(raw, Mapping):
        return [(str(k), dict(v or {})) for k, v in raw.items()]
    items = []
    for entry in raw or []:
        if isinstance(entry, str):
            items.append((entry, {}))
        elif isinstance(entry, Mapping) and len(entry) == 1:
            (k, v), = entry.items()
            items.append((str(k), dict(v or {})))
        else:
            raise ConfigError(f"filter_vs_smoother: bad estimators entry {entry!r}")
    return items


def estimators_of(entries: Any) -> list[EstimatorChoice]:
    """A config's ``estimators`` (a mapping or a list of names / 1-key maps), each built by
    :func:`slamkit.config.build`."""
    out = []
    for label, params in estimator_items(entries):
        params = dict(params)
        kind = params.pop("type", label)
        out.append(build(EstimatorChoice, {"label": label, "type": kind, "params": params},
                         f"filter_vs_smoother: estimators.{label}"))
    return out


def default_workers() -> int:
    """``workers`` left unset: local processes for the seeds after the first, at most 2."""
    return max(1, min(2, os.cpu_count() or 1))


# --- the config model (slamkit.experiments.config_models.PipelineConfig): checked before anything runs


class OutsideReference(BaseModel):
    """A figure measured elsewhere on the same setting (a paper, another tool, an outside check),
    shown in the report beside slamkit's mean of the same metric."""
    model_config = STRICT
    scenario: str
    metric: str
    value: Annotated[float, Field(allow_inf_nan=False)]
    #: who measured it and what it is (e.g. "outside check: dead reckoning")
    source: str
    #: slamkit's estimators to put beside it (empty: every estimator of the scenario)
    estimators: list[str] = []


class ScenarioEntry(BaseModel):
    model_config = STRICT
    #: landmark-world presets (slamkit.sim.landmark_world) and inertial ones (slamkit.sim.inertial_world)
    preset: Literal["mild", "strong", "car3d", "car3d_tactical"] | None = None
    dataset: str | None = None
    #: a scenario YAML (slamkit.sim.scenario), e.g. pipelines/scenarios/office_tour.yaml
    scenario: str | None = None
    name: str | None = None
    params: dict[str, Any] = {}
    #: estimator label -> params overriding the pipeline's for this scenario only, or false to
    #: leave that estimator out on this scenario
    estimators: dict[str, Union[dict[str, Any], Literal[False]]] = {}


class FilterVsSmootherPipeline(PipelineConfig):
    pipeline: Literal["filter_vs_smoother"]
    seeds: Seeds = 1
    #: seeded twins of every dataset (slamkit.experiments.perturbation)
    perturbations: dict[str, Any] | None = None
    workers: Annotated[int, Field(ge=1, le=256)] | None = None
    scenarios: Annotated[list[Union[str, ScenarioEntry]], Field(min_length=1)]
    estimators: Union[dict[str, Union[dict[str, Any], None]], Annotated[list[Union[str, dict[str, Any]]], Field(min_length=1)]]
    outside_references: list[OutsideReference] = []

    def check_options(self, config: dict[str, Any], doc: YamlDocument | None, source: str) -> None:
        _check_estimators(config.get("estimators"), doc, source)
        _check_scenarios(self, doc, source)
        _check_perturbations(self.perturbations, doc, source)

    def resolve(self, config: dict[str, Any]) -> dict[str, Any]:
        # a simulated preset's params spelt out: every field of its scenario class, the preset's
        # values where the entry sets none (what monte_carlo.build_sequence builds); datasets and
        # scenario files keep their params as written (reader keywords, a scenario file's
        # overrides); estimator params too: a filter's unset sensor sigmas come from each
        # sequence's metadata and a smoother's noise from the sequence, so they are not constants
        # of the config (and they are the runs' params in results.json)
        entries = []
        raw = list(config.get("scenarios") or [])
        for k, (given, entry) in enumerate(zip(raw, scenario_entries(raw))):
            if not (isinstance(entry, Mapping) and entry.get("preset") in PRESETS):
                entry = given  # as written (a bare dataset name stays one)
            else:
                spec = build(ScenarioSpec, entry, f"filter_vs_smoother: scenarios[{k}]")
                cls, preset = preset_scenario(spec.preset)
                params = resolved(cls, {**spec.params, "name": spec.name},
                                  f"filter_vs_smoother: scenario {spec.name!r}", base=preset, exclude=("name",))
                entry = {**entry, "params": params}
            entries.append(entry)
        return {**config, "scenarios": entries}


def _check_estimators(raw: Any, doc: YamlDocument | None, source: str,
                      path: tuple = ("estimators",)) -> None:
    for label, params in estimator_items(raw):
        try:
            kind = REGISTRY.canonical(str(params.pop("type", label)))
        except ConfigError as exc:  # the registry's one message, with its suggestion
            where = doc.where((*path, label)) if doc is not None else source
            raise ConfigError(f"{where}: {'.'.join(map(str, path))}.{label}: {exc}") from None
        cls = config_class(kind)
        fields = model_of(cls).model_fields if cls is not None else {}
        noise = {k: (Annotated[float, Field(gt=0, le=1e6)] | None, None) for k in SENSOR_SIGMAS}
        model = pydantic.create_model(f"{kind}Params", __config__=STRICT,
                                      **{k: (f.annotation, None) for k, f in fields.items()}, **noise)
        validate(model, params, doc, source, (*path, label))


def dataset_reader(dataset: str) -> tuple[Any, tuple[str, ...]]:
    """The reader whose keyword parameters a ``dataset:`` scenario's ``params`` are (as
    :func:`~slamkit.experiments.filter_vs_smoother.monte_carlo.build_sequence` reaches it through
    the registry loaders) and the parameters the loader sets itself; the config check validates
    ``params`` against them (one place for names and bounds: the reader's signature)."""
    entry = registry.get(dataset)
    if entry.kind == "inertial":
        return read_kitti_imu_gps, ("name",)
    if entry.format == "plaza":
        return read_plaza_sequence, ("name",)
    if entry.name in ("citytrees10000", "victoria-park"):
        return lm.read_isam_landmark_sequence, ("name", "ground_truth_path", "covariance_entries")
    if entry.name == "mrclam5a":
        return lm.read_pyfg_landmark_sequence, ("name",)
    if entry.name == "mrclam1":
        return lm.read_mrclam_sequence, ("name",)
    raise ConfigError(f"dataset {dataset!r} is not a dataset filter_vs_smoother reads as a sequence; use one "
                      f"of {', '.join(lm.LANDMARK_DATASETS)}, the Plaza runs or kitti-imu-gps")


def _check_dataset_params(entry: ScenarioEntry, k: int, doc: YamlDocument | None, source: str) -> None:
    """A ``dataset:`` scenario's ``params`` against its reader's keyword parameters (names, types,
    NaN/inf, suffix bounds: :func:`slamkit.config.params_model_of`)."""
    where = doc.where(("scenarios", k, "dataset")) if doc is not None else source
    try:
        registry.get(entry.dataset)
        reader, exclude = dataset_reader(entry.dataset)
    except SlamkitError as exc:
        raise ConfigError(f"{where}: scenarios.{k}.dataset: {exc}") from None
    _nested(params_model_of(reader, exclude), entry.params, doc, source, ("scenarios", k, "params"))


def _check_scenarios(model: FilterVsSmootherPipeline, doc: YamlDocument | None, source: str) -> None:
    pipeline_estimators = dict(estimator_items(model.estimators))

    for k, entry in enumerate(model.scenarios):
        if isinstance(entry, str) and entry not in PRESETS:
            # a bare name that is not a preset is a dataset (scenario_entries):
            # a misspelt one fails here, naming file and line, not after the presets have run
            _check_dataset_params(ScenarioEntry(dataset=entry), k, doc, source)
        if isinstance(entry, ScenarioEntry):
            where = doc.where(("scenarios", k)) if doc is not None else source
            build(ScenarioSpec, entry.model_dump(exclude_none=True), f"{where}: scenarios.{k}")
            # per-scenario estimator overrides: labels of the pipeline's estimators, whose
            # merged params must still be the estimator's
            unknown = sorted(set(entry.estimators) - set(pipeline_estimators))
            if unknown:
                where = doc.where(("scenarios", k, "estimators")) if doc is not None else source
                raise ConfigError(f"{where}: scenarios.{k}.estimators: {unknown} are not estimators of this "
                                  f"pipeline ({', '.join(pipeline_estimators)})")
            _check_estimators({label: {**pipeline_estimators[label], **params}
                               for label, params in entry.estimators.items() if params is not False},
                              doc, source, ("scenarios", k, "estimators"))
            if entry.preset is not None:
                scenario = InertialScenario if entry.preset in INERTIAL_PRESETS else LandmarkScenario
                _nested(model_of(scenario), entry.params, doc, source, ("scenarios", k, "params"))
            if entry.dataset is not None:
                _check_dataset_params(entry, k, doc, source)
            if entry.scenario is not None:
                where = doc.where(("scenarios", k)) if doc is not None else source
                try:  # the file exists and its fields with the overrides make a scenario
                    load_scenario(entry.scenario, entry.params)
                except ConfigError as exc:
                    raise ConfigError(f"{where}: scenarios.{k}: {exc}") from None



def typed_config(config: "FilterVsSmootherPipeline | Mapping[str, Any]") -> "FilterVsSmootherPipeline":
    """The model the pipeline runs on; a plain mapping (a notebook's, a test's; ``pipeline:`` may
    be left out) is checked and resolved as ``slamkit run`` does it
    (:func:`slamkit.experiments.config_models.typed_config`)."""
    return typed_model(FilterVsSmootherPipeline, config)
