"""``slamkit run PIPELINE.yaml``: load a pipeline config, dispatch to its kind, write the results
folder (config.yaml, results.json, report.md, plots/, trajectories/, recording.rrd).

A pipeline kind is a function ``run(config, folder, progress, observer) -> PipelineOutput``
registered in ``PIPELINES`` by import path, so importing this module stays cheap. Recording is
not done here: ``observer_factory(kind, recording_path)`` (the viz layer supplies one) returns a
``PipelineObserver`` that sees the run's steps and its output.
"""

from __future__ import annotations

import importlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from slamkit.config import load_yaml
from slamkit.errors import ConfigError
from slamkit.experiments.config_models import check_pipeline
from slamkit.paths import path_component
from slamkit.experiments.observers import NullObserver, PipelineObserver
from slamkit.experiments.results import ResultsFolder, RunRecord

PIPELINES: dict[str, str] = {
    "pose_graph": "slamkit.experiments.pose_graph:run",
    "filter_vs_smoother": "slamkit.experiments.filter_vs_smoother:run",
    "local_planning": "slamkit.experiments.closed_loop:run",
    "lidar_slam": "slamkit.experiments.lidar_slam:run",
}


@dataclass(frozen=True)
class PipelineOutput:
    runs: list[RunRecord]
    report_md: str
    summary: list[dict[str, Any]] | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)
    #: in-memory results for observers (not written to results.json)
    payload: Any = None


@dataclass(frozen=True)
class PipelineResult:
    out_dir: Path
    results: dict[str, Any]
    report_md: str


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
    path = Path(path)
    doc = load_yaml(path, "pipeline config")
    config = doc.data
    if not isinstance(config, dict) or "pipeline" not in config:
        raise ConfigError(f"{path}: a pipeline config is a mapping with a 'pipeline' key")
    check_pipeline(config, doc, str(path))
    config.setdefault("name", path.stem)
    return config


def validate_pipeline_config(path: str | Path) -> dict[str, Any]:
    """The validated config of the file at ``path`` (what ``slamkit run`` checks first)."""
    return load_config(path)


def resolve_pipeline(kind: str) -> Callable[..., PipelineOutput]:
    if kind not in PIPELINES:
        raise ConfigError(f"unknown pipeline {kind!r}; known: {', '.join(sorted(PIPELINES))}")
    module_name, fn_name = PIPELINES[kind].split(":")
    return getattr(importlib.import_module(module_name), fn_name)


ObserverFactory = Callable[[str, Path], PipelineObserver]


def run_pipeline(config: str | Path | Mapping[str, Any], out_dir: str | Path | None = None,
                 progress: bool = True, overrides: Mapping[str, Any] | None = None,
                 observer_factory: ObserverFactory | None = None) -> PipelineResult:
    """Run a pipeline config (path or mapping) and write its results folder atomically.

    With ``observer_factory`` and ``record: true`` in the config (the default), the observer
    writes ``recording.rrd`` inside the folder before it is committed."""
    cfg = load_config(config) if isinstance(config, (str, Path)) else dict(config)
    if overrides:
        cfg.update(overrides)
    if "pipeline" not in cfg:
        raise ConfigError("a pipeline config needs a 'pipeline' key")
    check_pipeline(cfg)
    fn = resolve_pipeline(cfg["pipeline"])
    if out_dir is None:
        out_dir = Path("runs") / path_component(cfg.get("name", cfg["pipeline"]), "the config's name")
    with ResultsFolder(out_dir, pipeline=str(cfg["pipeline"])) as folder, ProgressReporter(enabled=progress) as reporter:
        folder.write_config(cfg)
        record = observer_factory is not None and bool(cfg.get("record", True))
        observer = observer_factory(cfg["pipeline"], folder.recording_path) if record else NullObserver()
        try:
            output = fn(cfg, folder, reporter, observer)
            if not output.runs:
                # e.g. inits: [chordal] on 2D graphs only: nothing to report is an error, not a result
                raise ConfigError(f"pipeline {cfg['pipeline']!r} ran nothing: every combination it lists was "
                                  "skipped or empty; see the config")
            observer.on_output(output)
        finally:
            observer.close()
        final = folder.commit(cfg["pipeline"], output.runs, output.report_md, output.summary,
                              output.extra)
    results = json.loads((final / "results.json").read_text())
    return PipelineResult(final, results, output.report_md)
