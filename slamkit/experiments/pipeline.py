"""``slamkit run PIPELINE.yaml``: load a pipeline config, dispatch to its kind, write the results
folder (config.yaml, results.json, report.md, plots/, trajectories/, recording.rrd).

``config.yaml`` is the resolved config (:func:`config_models.with_defaults`): the validated
config with every default of its model spelt out, and the algorithm sections the pipeline keeps
as free mappings (``slam:``, ``navigation:``, ``options:`` ...) with the defaults of the frozen
dataclasses built from them (the model's ``resolve``, :func:`slamkit.config.resolved`); the
pipeline's ``run`` receives that same config as its typed model
(:func:`config_models.runtime_config`), so the folder says every setting that was used and the
run reads typed fields, not a mapping's keys with restated defaults (issue 30).

Architecture note (issue 18): a pipeline kind is a :class:`Pipeline`, declared by its own module
(``PIPELINE = Pipeline(...)`` in ``slamkit.experiments.pose_graph`` ...): its registry name, its
config model (a pydantic model of :mod:`slamkit.experiments.config_models`, whose
``check_options`` validates what the pipeline nests), the type of the payload its
:class:`PipelineOutput` carries to observers, and its ``run`` function. :data:`PIPELINES` is the
one table of pipeline kinds (a :class:`slamkit.naming.Registry` of lazy ``module:PIPELINE``
targets, so importing this module stays cheap); :func:`register_pipeline` adds a user's own,
and so does an entry point of the group ``slamkit.pipelines`` whose object is a
:class:`Pipeline` (or a config's ``plugins:`` module calling ``register_pipeline``).

Recording is not done here (experiments never import viz): the viz layer registers a recorder
factory against a pipeline with :func:`register_recorder` (``slamkit.viz.pipelines`` does it for
the built-in kinds), and ``run_pipeline``'s ``observer_factory(kind, recording_path)`` (the viz
layer's ``observer_for``) builds it. The recorder is a ``PipelineObserver`` that sees the run's
steps and its output.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Generic, Mapping, Protocol, TypeVar

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from slamkit.config import YamlDocument, load_yaml
from slamkit.errors import ConfigError
from slamkit.experiments.config_models import (PipelineConfig, check_with, import_config_plugins, runtime_config,
                                               with_defaults)
from slamkit.experiments.observers import NullObserver, PipelineObserver
from slamkit.experiments.perturbation import with_perturbation_report
from slamkit.experiments.results import ResultsFolder, RunRecord
from slamkit.naming import Registry, load_target
from slamkit.paths import path_component

PayloadT = TypeVar("PayloadT")
ConfigT = TypeVar("ConfigT", bound=PipelineConfig)


@dataclass(frozen=True)
class PipelineOutput(Generic[PayloadT]):
    runs: list[RunRecord]
    report_md: str
    summary: list[dict[str, Any]] | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)
    #: in-memory results for observers (not written to results.json): the pipeline's payload type
    payload: PayloadT | None = None


@dataclass(frozen=True)
class PipelineResult:
    out_dir: Path
    results: dict[str, Any]
    report_md: str


class StepProgress(Protocol):
    """What a pipeline reports progress to: ``task(label, total)`` returns ``advance(n=1)``."""

    def task(self, label: str, total: int) -> Callable[..., None]: ...


class RunFunction(Protocol[ConfigT, PayloadT]):
    def __call__(self, config: ConfigT, folder: ResultsFolder, progress: StepProgress,
                 observer: PipelineObserver) -> PipelineOutput[PayloadT]: ...


@dataclass(frozen=True)
class Pipeline(Generic[ConfigT, PayloadT]):
    """One pipeline kind, declared by the module that implements it.

    ``config_model`` validates the config before anything runs (None: only the fields every
    pipeline has are checked, extra keys allowed -- a user's quick pipeline, whose ``run`` finds
    them in ``config.model_extra``); ``run`` receives that validated model, the runtime config
    (issue 30): its defaults filled, its algorithm sections resolved
    (:func:`~slamkit.experiments.config_models.runtime_config`), so a run reads
    ``config.seeds``, never ``config.get("seeds", 3)``. ``payload_type`` is what ``run`` returns
    in ``PipelineOutput.payload`` for observers (None: nothing)."""

    name: str
    run: RunFunction[ConfigT, PayloadT]
    config_model: type[ConfigT] | None = None
    payload_type: type[PayloadT] | None = None
    description: str = ""


#: what the viz layer registers against a pipeline: ``factory(recording_path, spawn=False)``
RecorderFactory = Callable[..., PipelineObserver]


class _Entry:
    """A registered pipeline: its lazy ``module:attribute`` target (or the object itself) and
    the recorder factory registered against it (also lazy)."""

    def __init__(self, target: "str | Pipeline"):
        self.target = target
        self._pipeline = target if isinstance(target, Pipeline) else None
        self.recorder: str | RecorderFactory | None = None

    def same_as(self, other: object) -> bool:
        """Whether ``other`` wraps the very same target (a plug-in's pipeline both imported and
        found as an entry point is registered once; see ``Registry.register``)."""
        return isinstance(other, _Entry) and other.target is self.target

    def pipeline(self, name: str) -> Pipeline:
        if self._pipeline is None:
            loaded = load_target(str(self.target))
            if not isinstance(loaded, Pipeline) or loaded.name != name:
                raise TypeError(f"{self.target} must be a Pipeline named {name!r}, got {loaded!r}")
            self._pipeline = loaded
        return self._pipeline


def _adapt(name: str, entry: Any) -> _Entry:
    if not isinstance(entry, Pipeline) or entry.name != name:
        raise ConfigError(f"a pipeline entry point names a Pipeline (slamkit.experiments.pipeline) called "
                          f"{name!r}, got {entry!r}")
    return _Entry(entry)


#: every pipeline kind by registry name
PIPELINES: Registry[_Entry] = Registry("pipeline", {
    "pose_graph": _Entry("slamkit.experiments.pose_graph:PIPELINE"),
    "pose_graph_outliers": _Entry("slamkit.experiments.pose_graph_outliers:PIPELINE"),
    "filter_vs_smoother": _Entry("slamkit.experiments.filter_vs_smoother:PIPELINE"),
    "local_planning": _Entry("slamkit.experiments.closed_loop:PIPELINE"),
    "lidar_slam": _Entry("slamkit.experiments.lidar_slam:PIPELINE"),
    "visual_odometry": _Entry("slamkit.experiments.visual_odometry:PIPELINE"),
    "navigation": _Entry("slamkit.experiments.navigation:PIPELINE"),
}, group="slamkit.pipelines", adapt=_adapt)


def pipeline_of(kind: str) -> Pipeline:
    """The :class:`Pipeline` registered as ``kind`` (imported on first use)."""
    name = PIPELINES.canonical(kind)
    return PIPELINES[name].pipeline(name)


def check_pipeline(config: dict[str, Any], doc: YamlDocument | None = None, source: str = "<config>"
                   ) -> PipelineConfig:
    """Validate a pipeline config with the model its pipeline declares (top level, then the
    algorithm options it nests: :func:`~slamkit.experiments.config_models.check_with`); returns
    the model. ``config['pipeline']`` is set to the registered spelling (an old one is accepted
    with a deprecation warning). Raises ConfigError naming file, line and field."""
    if not isinstance(config, dict):
        raise ConfigError(f"{source}: a pipeline config is a mapping with a 'pipeline' key, got "
                          f"{type(config).__name__}")
    import_config_plugins(config, doc, source)
    try:
        config["pipeline"] = PIPELINES.canonical(config.get("pipeline"))
    except ConfigError as exc:
        where = doc.where(("pipeline",)) if doc is not None else source
        raise ConfigError(f"{where}: pipeline: {exc}") from None
    return check_with(pipeline_of(config["pipeline"]).config_model, config, doc, source)


def has_config_field(kind: str, field_name: str) -> bool:
    """Whether pipeline ``kind``'s config model declares ``field_name`` (e.g. ``perturbations``)."""
    model = pipeline_of(kind).config_model
    return model is not None and field_name in model.model_fields


def register_pipeline(pipeline: Pipeline) -> None:
    """Make ``pipeline`` runnable by name (``pipeline: <name>`` in a config)."""
    PIPELINES.register(pipeline.name, _Entry(pipeline))


def register_recorder(kind: str, factory: str | RecorderFactory) -> None:
    """Register the recorder of pipeline ``kind``: ``factory(recording_path, spawn=False)``
    returns its ``PipelineObserver`` (a ``module:attribute`` string is imported when used)."""
    PIPELINES[kind].recorder = factory


def recorder_of(kind: str) -> RecorderFactory | None:
    """The recorder factory registered against ``kind`` (None when there is none)."""
    factory = PIPELINES[kind].recorder
    return load_target(factory) if isinstance(factory, str) else factory


class ProgressReporter:
    """Thin wrapper over rich progress so pipelines report steps without knowing the console.

    ``task(label, total)`` returns an ``advance(n=1)`` callable. Silent when ``enabled`` is False.
    """

    def __init__(self, enabled: bool = True, console: Console | None = None):
        self.enabled = enabled
        self._progress = Progress(
            TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
            console=console or Console(stderr=True), disable=not enabled, transient=False,
        )

    def __enter__(self) -> "ProgressReporter":
        self._progress.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self._progress.__exit__(*exc)

    def task(self, label: str, total: int) -> Callable[[int], None]:
        task_id = self._progress.add_task(label, total=total)
        return lambda n=1: self._progress.advance(task_id, n)


def load_config(path: str | Path) -> dict[str, Any]:
    """Read and validate a pipeline config file (see :mod:`slamkit.experiments.config_models`):
    every error names the file, line and field before anything runs."""
    return _load_checked(path)[0]


def _load_checked(path: str | Path) -> tuple[dict[str, Any], PipelineConfig]:
    """The validated config of the file at ``path`` and its model (validated once)."""
    path = Path(path)
    doc = load_yaml(path, "pipeline config")
    config = doc.data
    if not isinstance(config, dict) or "pipeline" not in config:
        raise ConfigError(f"{path}: a pipeline config is a mapping with a 'pipeline' key")
    model = check_pipeline(config, doc, str(path))
    config.setdefault("name", path.stem)
    return config, model


def validate_pipeline_config(path: str | Path) -> dict[str, Any]:
    """The validated config of the file at ``path`` (what ``slamkit run`` checks first)."""
    return load_config(path)


ObserverFactory = Callable[[str, Path], PipelineObserver]


def run_pipeline(config: str | Path | Mapping[str, Any], out_dir: str | Path | None = None,
                 progress: bool = True, overrides: Mapping[str, Any] | None = None,
                 observer_factory: ObserverFactory | None = None, overwrite: bool = False) -> PipelineResult:
    """Run a pipeline config (path or mapping) and write its results folder atomically.

    An existing result of the same pipeline at ``out_dir`` is replaced only with ``overwrite``
    (``slamkit run --overwrite``); one of another kind never (:func:`results.check_replace`).

    With ``observer_factory`` and ``record: true`` in the config (the default), the observer
    writes ``recording.rrd`` inside the folder before it is committed."""
    model: PipelineConfig | None = None
    if isinstance(config, (str, Path)):
        cfg, model = _load_checked(config)   # validated once, naming the file's lines
    else:
        cfg = dict(config)
    if overrides:
        cfg.update(overrides)
        model = None
    if "pipeline" not in cfg:
        raise ConfigError("a pipeline config needs a 'pipeline' key")
    # what runs is what config.yaml says: the validated config with every default spelt out
    cfg = with_defaults(cfg, model if model is not None else check_pipeline(cfg))
    pipeline = pipeline_of(cfg["pipeline"])
    if out_dir is None:
        out_dir = Path("runs") / path_component(cfg.get("name", cfg["pipeline"]), "the config's name")
    with ResultsFolder(out_dir, pipeline=pipeline.name, overwrite=overwrite) as folder, ProgressReporter(enabled=progress) as reporter:
        folder.write_config(cfg)
        record = observer_factory is not None and bool(cfg.get("record", True))
        if observer_factory is None and cfg.get("record") is True:
            # asked for explicitly: say why no recording.rrd appears (experiments never import viz)
            warnings.warn(f"pipeline {cfg['pipeline']!r}: record: true, but run_pipeline was given no "
                          "observer_factory, so no recording.rrd is written; pass "
                          "observer_factory=slamkit.viz.pipelines.observer_for (slamkit run does)",
                          UserWarning, stacklevel=2)
        observer = observer_factory(cfg["pipeline"], folder.recording_path) if record else NullObserver()
        try:
            runtime = runtime_config(pipeline.config_model, cfg)
            output = with_perturbation_report(pipeline.run(runtime, folder, reporter, observer), folder.plots)
            if not output.runs:
                # e.g. inits: [chordal] on 2D graphs only: nothing to report is an error, not a result
                raise ConfigError(f"pipeline {cfg['pipeline']!r} ran nothing: every combination it lists was "
                                  "skipped or empty; see the config")
            observer.on_output(output)
        finally:
            observer.close()
        final = folder.commit(cfg["pipeline"], output.runs, output.report_md, output.summary,
                              output.extra)
    return PipelineResult(final, folder.results, output.report_md)
