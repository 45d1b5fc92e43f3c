"""The typed shape of pipeline configs (pydantic models), checked before anything runs.

One model per pipeline kind, named by the pipeline that uses it (``Pipeline.config_model`` in
:mod:`slamkit.experiments.pipeline`); each model's ``check_options`` validates the algorithm
options it nests against the models that :func:`slamkit.config.model_of` derives from the
algorithms' own config dataclasses, so a field exists, has a type and a bound in one place only.

This module holds what every model shares (:class:`PipelineConfig`, ``Seeds``, the nested-section
check and write-back, :func:`check_with`, :func:`with_defaults`, :func:`runtime_config`,
:func:`typed_config`, the checks the two pose-graph pipelines share); every pipeline's model lives
with its pipeline (issue 30): ``FilterVsSmootherPipeline`` in ``filter_vs_smoother.config``,
``PoseGraphPipeline`` in ``pose_graph.config``, ``PoseGraphOutliersPipeline`` in
``pose_graph_outliers.config``, ``LidarSlamPipeline`` in ``lidar_slam.config``,
``VisualOdometryPipeline`` in ``visual_odometry.config``, ``NavigationPipeline`` in ``navigation``,
``LocalPlanningPipeline`` in ``closed_loop.config``. This module imports no pipeline and the pipelines
import it, so there is no circle; the registry's :func:`slamkit.experiments.pipeline.check_pipeline`
finds a config's model and calls :func:`check_with`.
``seeds`` has one meaning in every pipeline: a count (``seeds: 6`` -> 0..5), a list of seeds, or
``{start, count}``; :func:`seed_list` turns it into the list.
"""

from __future__ import annotations

import os

from typing import Annotated, Any, Mapping, TypeVar, Union

import pydantic
from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from slamkit.config import STRICT, YamlDocument, model_of, validate, write_back
from slamkit.data import registry
from slamkit.data.perturb import PerturbationConfig
from slamkit.errors import ConfigError, SlamkitError
from slamkit.experiments.perturbation import perturbation_config
from slamkit.naming import import_plugins
from slamkit.paths import path_component

def _plain_name(v: str) -> str:
    try:
        return path_component(v, "name")
    except ConfigError as exc:
        raise ValueError(str(exc)) from None


#: a name that becomes a folder or file name (one plain path component, see slamkit.paths)
PlainName = Annotated[str, AfterValidator(_plain_name)]
Count = Annotated[int, Field(ge=1, le=100_000)]
Seed = Annotated[int, Field(ge=0, le=2**32 - 1)]


class SeedRange(BaseModel):
    model_config = STRICT
    start: Seed = 0
    count: Count


def _seeds_form(v: Any) -> str:
    if isinstance(v, dict) or isinstance(v, SeedRange):
        return "<range>"
    return "<list>" if isinstance(v, (list, tuple)) else "<count>"


#: a count (0..n-1), a list, or {start, count}; tags (filtered out of messages) pick the form
Seeds = Annotated[Union[Annotated[Count, pydantic.Tag("<count>")],
                        Annotated[list[Seed], Field(min_length=1, max_length=100_000), pydantic.Tag("<list>")],
                        Annotated[SeedRange, pydantic.Tag("<range>")]],
                  pydantic.Discriminator(_seeds_form)]


def seed_list(spec: Any) -> list[int]:
    """The seeds a validated ``seeds`` value means."""
    if isinstance(spec, SeedRange):
        return list(range(spec.start, spec.start + spec.count))
    if isinstance(spec, dict):
        return list(range(int(spec.get("start", 0)), int(spec.get("start", 0)) + int(spec["count"])))
    if isinstance(spec, int):
        return list(range(spec))
    return [int(s) for s in spec]


class PipelineConfig(BaseModel):
    """The fields every pipeline config has; a pipeline's model adds its own."""

    model_config = STRICT
    pipeline: str
    name: PlainName | None = None
    record: bool = True
    #: modules imported before anything is validated; importing one registers a user's estimators,
    #: planners, controllers, datasets or pipelines (slamkit.naming.import_plugins)
    plugins: list[Annotated[str, Field(min_length=1)]] = []

    def check_options(self, config: dict[str, Any], doc: YamlDocument | None, source: str) -> None:
        """Validate the algorithm options this config nests (``config`` is the raw mapping)."""

    def resolve(self, config: dict[str, Any]) -> dict[str, Any]:
        """``config`` (its model's defaults already spelt out) with the algorithm sections this
        pipeline keeps as free mappings spelt out too: each replaced by
        :func:`slamkit.config.resolved` of the dataclass the pipeline builds from it, so
        ``config.yaml`` names the dataclass defaults ``build`` filled in (issue 30). Rebuilt, a
        resolved section gives an equal dataclass, so the run is the same. The default keeps
        every section as written (a user's pipeline without such sections)."""
        return config



PipelineConfigT = TypeVar("PipelineConfigT", bound=PipelineConfig)


class _OpenPipeline(PipelineConfig):
    model_config = ConfigDict(extra="allow", allow_inf_nan=False)


# --- checks the pose-graph pipelines share (pose_graph.config, pose_graph_outliers.config) --------

def _refuse_pipeline_keys(section: dict[str, Any], name: str, owners: dict[str, str], doc: YamlDocument | None,
                          source: str) -> None:
    """The combinations are the pipeline's own lists: a section may not set them a second time
    (``owners``: field -> the pipeline key that sets it)."""
    for key, owner in owners.items():
        if key in section:
            where = doc.where((name, key)) if doc is not None else source
            raise ConfigError(f"{where}: {name}.{key}: set by the pipeline's '{owner}' (every "
                              f"combination runs); remove it from {name}")


def _refuse_moved_keys(section: dict[str, Any], prefix: tuple, moved: Mapping[str, str],
                       doc: YamlDocument | None, source: str) -> None:
    """A key of a config's former flat layout is refused with the place it moved to
    (``moved``: old key -> its dotted path now), not merely as unknown."""
    for key in section:
        if key in moved:
            where = doc.where(prefix + (key,)) if doc is not None else source
            dotted = ".".join(str(x) for x in prefix + (key,))
            raise ConfigError(f"{where}: {dotted}: moved into a section: {key} -> {moved[key]} "
                              f"(write it as {'.'.join(str(x) for x in prefix)}.{moved[key]})")


def _check_pose_graph_sources(datasets: list[str], doc: YamlDocument | None, source: str) -> None:
    """Every ``datasets`` entry is a registry name (under its naming rule) or an existing file:
    a misspelt one fails here, naming file and line, not after the others have been solved."""

    for k, name in enumerate(datasets):
        try:
            registry.resolve(name)
        except SlamkitError as exc:
            where = doc.where(("datasets", k)) if doc is not None else source
            raise ConfigError(f"{where}: datasets.{k}: {exc}") from None


# --- checks pipelines share -------------------------------------------------------------------

def _check_perturbations(values: Any, doc: YamlDocument | None, source: str) -> None:
    """``perturbations`` (the pipelines that rerun their data on seeded twins,
    slamkit.experiments.perturbation) against the fields of PerturbationConfig."""
    if values is None:
        return

    _nested(model_of(PerturbationConfig), values, doc, source, ("perturbations",))

    try:
        perturbation_config(values)
    except ConfigError as exc:
        where = doc.where(("perturbations",)) if doc is not None else source
        raise ConfigError(f"{where}: {exc}") from None


def _nested(model: type, data: Any, doc: YamlDocument | None, source: str, prefix: tuple) -> None:
    validated = validate(model, data if data is not None else {}, doc, source, prefix)
    _VALIDATED.append((prefix, validated))


#: (path, validated model) of every nested section checked by the running check_pipeline call,
#: written back into the raw config when the checks pass (slamkit.config.write_back)
_VALIDATED: list[tuple[tuple, Any]] = []


def _write_back(config: dict[str, Any], checked: list[tuple[tuple, Any]]) -> None:
    for prefix, validated in checked:
        node: Any = config
        for key in prefix:
            if isinstance(node, dict) and key in node:
                node = node[key]
            elif isinstance(node, list) and isinstance(key, int) and 0 <= key < len(node):
                node = node[key]
            else:
                node = None
                break
        write_back(node, validated)


def check_with(model_cls: type[PipelineConfig] | None, config: dict[str, Any], doc: YamlDocument | None = None,
               source: str = "<config>") -> PipelineConfig:
    """Validate ``config`` with its pipeline's model ``model_cls`` (None: a pipeline registered
    without one, whose config gets the common fields checked), then the algorithm options it
    nests, and write back what validation understood; returns the model. The pipeline registry's
    :func:`slamkit.experiments.pipeline.check_pipeline` finds the model and calls this."""
    model = validate(model_cls or _OpenPipeline, config, doc, source)
    start = len(_VALIDATED)
    try:
        model.check_options(config, doc, source)
        _write_back(config, _VALIDATED[start:])
    finally:
        del _VALIDATED[start:]
    return model


def import_config_plugins(config: dict[str, Any], doc: YamlDocument | None = None, source: str = "<config>") -> None:
    """Import the modules a config's ``plugins`` names (first: a plug-in may register the very
    pipeline the config names); a module may sit beside the config file."""
    plugins = config.get("plugins")
    if plugins is None:
        return
    where = doc.where(("plugins",)) if doc is not None else source
    if not isinstance(plugins, list):
        raise ConfigError(f"{where}: plugins: a list of module names, got {plugins!r}")
    config_dir = [os.path.dirname(os.path.abspath(source))] if os.path.isfile(source) else []
    import_plugins(plugins, f"{where}: plugins", config_dir)


def with_defaults(config: Mapping[str, Any], model: pydantic.BaseModel) -> dict[str, Any]:
    """``config`` (as validated and written back by :func:`check_pipeline`) with every field its
    model leaves at a default spelt out -- what ``config.yaml`` of a run holds and what the
    pipeline runs on, so the folder says every setting that was used (issue 30). Given values are
    kept as written; a field missing (or null) gets its model default, recursively into nested
    models (``scenarios: {kinds: [...]}`` gains ``seeds``, ``n_obstacles`` ...); defaults that are
    None stay absent (None means "not set"). Then the pipeline model's
    :meth:`PipelineConfig.resolve` spells out the algorithm sections it keeps as free mappings
    (``slam:``, ``navigation:``, ``options:`` ...) with their dataclass defaults."""
    out = _model_defaults(config, model)
    return model.resolve(out) if isinstance(model, PipelineConfig) else out


def runtime_config(model_cls: type[PipelineConfig] | None, resolved_config: Mapping[str, Any]) -> PipelineConfig:
    """The model a pipeline's ``run`` receives: ``resolved_config`` (:func:`with_defaults` of a
    config :func:`check_with` accepted, exactly what ``config.yaml`` says) as its typed model,
    so the run is configured by the very values the folder records. ``check_with`` has named
    file, line and field for anything wrong; building the model of its resolved form cannot fail
    unless ``resolve`` is wrong, which is then a bug reported as such. A sweep or executor worker
    that is handed the resolved mapping gets the same model from it."""
    try:
        return (model_cls or _OpenPipeline).model_validate(dict(resolved_config))
    except pydantic.ValidationError as exc:
        raise ConfigError(f"the resolved config of pipeline {resolved_config.get('pipeline')!r} does not "
                          f"validate again (a bug in its resolve()): {exc}") from None


def typed_config(model_cls: type[PipelineConfigT], config: "PipelineConfigT | Mapping[str, Any]") -> PipelineConfigT:
    """The model a pipeline runs on, from a plain mapping too (a notebook's, a test's;
    ``pipeline:`` may be left out): checked and resolved as ``slamkit run`` does it
    (:func:`check_with`, :func:`with_defaults`, :func:`runtime_config`), so a pipeline's Python
    API and the CLI run on the same values. A model is returned as it is."""
    if isinstance(config, model_cls):
        return config
    data = {"pipeline": model_cls.model_fields["pipeline"].annotation.__args__[0], **config}
    return runtime_config(model_cls, with_defaults(data, check_with(model_cls, data)))


def _model_defaults(config: Mapping[str, Any], model: pydantic.BaseModel) -> dict[str, Any]:
    out = dict(config)
    for name in type(model).model_fields:
        value = getattr(model, name)
        if value is None:
            continue
        given = out.get(name)
        if given is None:
            out[name] = _dumped(value)
        elif isinstance(value, pydantic.BaseModel) and isinstance(given, Mapping):
            out[name] = _model_defaults(given, value)
        elif isinstance(value, list) and isinstance(given, list) and len(value) == len(given):
            out[name] = [_model_defaults(g, v) if isinstance(v, pydantic.BaseModel) and isinstance(g, Mapping) else g
                         for g, v in zip(given, value)]
    return out


def _dumped(value: Any) -> Any:
    if isinstance(value, pydantic.BaseModel):
        return value.model_dump(mode="json", exclude_none=True)
    if isinstance(value, (list, tuple)):
        return [_dumped(v) for v in value]
    if isinstance(value, dict):
        return {k: _dumped(v) for k, v in value.items()}
    return value
