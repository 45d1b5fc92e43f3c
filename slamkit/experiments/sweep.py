"""``slamkit sweep SWEEP.yaml --out DIR``: one pipeline config run over axes of values, resumable.

A sweep file names a pipeline config and the axes to vary::

    name: ekf_range_noise            # default: the file's stem
    pipeline: filter_vs_smoother.yaml  # a config file (relative to this file) or an inline mapping
    mode: grid                       # grid: every combination of the axes; zip: i-th value of each
    seeds: 20                        # a seed axis (count, list or {start, count}), always crossed
    axes:                            # dotted paths into the pipeline config -> values
      estimators.ekf.sigma_range_m: [0.05, 0.1, 0.2]
      scenarios.0.params.duration_s: [10.0, 20.0]
    plugins: [my_lab.pipelines]      # modules imported in every worker (register_pipeline there)

A value for a field that the pipeline config holds as a list and that is not a list itself is
put in a one-element list (``datasets: [intel, m3500]`` as an axis gives one dataset per cell);
the seed axis sets ``seeds: [s]``. An axis value may itself be a list or mapping (``counts: [[0, 5],
[0, 10]]``): results, report and paired statistics key it by its JSON. Every cell's resolved config is validated with its pipeline's
model before anything runs (an error names the axis values and the field).

Each cell is one pipeline run (:func:`slamkit.experiments.pipeline.run_pipeline`) into
``<out>/cells/<key[:2]>/<key>`` (:func:`cell_path`), where ``key`` is a hash of the cell's resolved
config -- every default of the pipeline's model spelt out (:func:`config_models.with_defaults`),
and the algorithm sections it builds dataclasses from (``slam:``, ``navigation:``, ``options:``, a
preset's ``params`` ...: ``PipelineConfig.resolve``) with the dataclasses' defaults -- so a default
written out or left implicit is the same cell, and a cell whose algorithm defaults changed in the
code is a new cell; the keys of sweeps made before issue 30 hashed the config as written, those
made before the algorithm sections were resolved hashed them as written, and neither are found by
``--resume`` (the two-digit shard keeps each folder small: a results folder looks for its own
leftovers among its siblings, which in one flat folder of 10,000 cells made every cell scan all
the others); the cell folder
is written atomically by :class:`~slamkit.experiments.results.ResultsFolder`, so a sweep killed
at any moment (``kill -9``) holds complete cells and hidden partial leftovers only, and
``--resume`` runs exactly the cells whose folder is not complete. A cell that raises is stored
as a folder with ``error.json`` instead of ``results.json`` and counts as finished (``--resume
--retry-failed`` runs it again); the other cells go on.

The sweep folder ``<out>`` carries the results-folder marker (so ``--out`` never replaces a
user's folder or a run, and a run never replaces it; an earlier sweep there is continued with
``--resume`` or cleared and started afresh only with ``--overwrite``) and the lock of :func:`~slamkit.experiments.results.acquire_folder_lock` for the
sweep's life; ``results.json``, ``report.md`` and ``plots/`` are written there (each file
atomically) after the cells: every run of every finished cell with its axis values, and per
swept axis and value the mean and 95% confidence interval of each metric (over the runs of the
cells with that value: seeds and the other axes), with a plot of each metric against each axis.

Cells run on an :class:`~slamkit.experiments.executors.Executor`: local processes (default) or
Ray. The cell folders are written by the workers, so on a multi-machine Ray cluster ``--out``
must be on a file system every node mounts at the same path.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import itertools
import json
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Iterable, Literal, Mapping, Union

from pydantic import BaseModel, Field, StringConstraints, field_validator

import slamkit
from slamkit.config import STRICT, YamlDocument, load_yaml, validate
from slamkit.errors import ConfigError, OutputError
from slamkit.experiments.config_models import PlainName, Seeds, seed_list, with_defaults
from slamkit.experiments.executors import Executor, TaskFailure, make_executor
from slamkit.experiments.pipeline import PIPELINES, check_pipeline, load_config, run_pipeline
from slamkit.experiments.results import (MARKER, SWEEP_KIND, ResultsFolder, RunRecord, _jsonable,
                                         acquire_folder_lock, check_output_folder, is_results_folder, markdown_table,
                                         paired_comparisons, paired_markdown, release_folder_lock, summarise,
                                         summary_markdown)
from slamkit.naming import import_plugins
from slamkit.paths import atomic_file, file_in

#: the name of the seed axis in cells, results and reports
SEED_AXIS = "seed"

DottedPath = Annotated[str, StringConstraints(
    pattern=r"^[A-Za-z_][A-Za-z0-9_]*(\.([A-Za-z_][A-Za-z0-9_]*|[0-9]+))*$", max_length=300)]
ModuleName = Annotated[str, StringConstraints(pattern=r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")]
Values = Annotated[list[Any], Field(min_length=1, max_length=100_000)]


class SweepModel(BaseModel):
    """The typed shape of a sweep file (see the module docstring)."""

    model_config = STRICT
    name: PlainName | None = None
    pipeline: Union[str, dict[str, Any]]
    mode: Literal["grid", "zip"] = "grid"
    seeds: Seeds | None = None
    axes: dict[DottedPath, Values] = {}
    plugins: list[ModuleName] = []

    @field_validator("axes")
    @classmethod
    def _not_the_seed_axis(cls, v: dict[str, list[Any]]) -> dict[str, list[Any]]:
        if "seeds" in v:
            raise ValueError("vary the seed with the top-level 'seeds:' (a count, a list or {start, "
                             "count}), not as an axis")
        return v


@dataclass(frozen=True)
class Cell:
    """One pipeline run of a sweep: its axis values, resolved config and the key it is stored under."""

    key: str
    axes: Mapping[str, Any]
    config: Mapping[str, Any]

    @property
    def label(self) -> str:
        return ", ".join(f"{k}={_short(v)}" for k, v in self.axes.items())


@dataclass(frozen=True)
class Sweep:
    """A loaded, validated sweep: its name, model, base pipeline config and cells."""

    name: str
    model: SweepModel
    base: Mapping[str, Any]
    cells: list[Cell]

    @property
    def axis_names(self) -> list[str]:
        return list(self.model.axes) + ([SEED_AXIS] if self.model.seeds is not None else [])


def _short(v: Any) -> str:
    return v if isinstance(v, str) else json.dumps(_jsonable(v), separators=(",", ":"))


def config_key(config: Mapping[str, Any]) -> str:
    """The key a cell is stored under: 16 hex digits of the SHA-256 of its canonical JSON."""
    text = json.dumps(_jsonable(dict(config)), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def cell_path(cells_dir: Path, key: str) -> Path:
    """Where the cell ``key`` is stored: ``cells_dir/<first two hex digits>/<key>``."""
    return cells_dir / key[:2] / key


def set_path(config: dict[str, Any], path: str, value: Any) -> None:
    """Set the dotted ``path`` of ``config`` to ``value`` in place (see the module docstring for
    the one-element-list rule); missing mappings on the way are created, so that the pipeline's
    model reports an unknown field by its name. A ConfigError names the axis otherwise."""
    parts = path.split(".")
    node: Any = config
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        where = ".".join(parts[:depth]) or "(top level)"
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise ConfigError(f"axes.{path}: {where} is a list of {len(node)}; {part!r} is not an "
                                  "index in it")
            key: Any = int(part)
        elif isinstance(node, dict):
            key = part
        else:
            raise ConfigError(f"axes.{path}: {where} is {_short(node)}, not a mapping or list")
        if last:
            current = node[key] if isinstance(node, list) else node.get(key)
            node[key] = [value] if isinstance(current, list) and not isinstance(value, list) else value
        else:
            if isinstance(node, dict) and node.get(key) is None:
                node[key] = {}
            node = node[key]


def _combinations(model: SweepModel, source: str) -> list[dict[str, Any]]:
    paths = list(model.axes)
    if model.mode == "zip":
        lengths = {p: len(v) for p, v in model.axes.items()}
        if len(set(lengths.values())) > 1:
            raise ConfigError(f"{source}: axes: mode zip needs lists of one length, got "
                              + ", ".join(f"{p}: {n}" for p, n in lengths.items()))
        rows = [dict(zip(paths, values)) for values in zip(*model.axes.values())]
    else:
        rows = [dict(zip(paths, values)) for values in itertools.product(*model.axes.values())]
    rows = rows or [{}]
    if model.seeds is None:
        return rows
    return [{**row, SEED_AXIS: s} for row in rows for s in seed_list(model.seeds)]


def load_sweep(path: str | Path) -> Sweep:
    """Read a sweep file, load its pipeline config and validate every cell's resolved config."""
    path = Path(path)
    doc = load_yaml(path, "sweep")
    if not isinstance(doc.data, dict):
        raise ConfigError(f"{path}: a sweep is a mapping with 'pipeline' and 'axes' keys")
    model = validate(SweepModel, doc.data, doc, str(path))
    _import_plugins(model.plugins)
    base = _base_config(model, doc, path)
    cells: list[Cell] = []
    seen: dict[str, Cell] = {}
    for axes in _combinations(model, str(path)):
        config = json.loads(json.dumps(base))  # a deep copy of plain data
        for axis, value in axes.items():
            if axis == SEED_AXIS:
                config["seeds"] = [value]
            else:
                set_path(config, axis, value)
        label = ", ".join(f"{k}={_short(v)}" for k, v in axes.items()) or "(no axes)"
        try:
            # the cell runs on, writes and is keyed by its resolved config (defaults spelt out)
            config = with_defaults(config, check_pipeline(config, None, f"{path}: cell {label}"))
        except ConfigError as exc:
            raise ConfigError(str(exc) if str(exc).startswith(str(path)) else f"{path}: cell {label}: {exc}") from None
        cell = Cell(config_key(config), axes, config)
        if cell.key in seen:
            raise ConfigError(f"{path}: cells {seen[cell.key].label} and {cell.label} resolve to the same "
                              "config; remove the repeated axis value")
        seen[cell.key] = cell
        cells.append(cell)
    return Sweep(model.name or path.stem, model, base, cells)


def _base_config(model: SweepModel, doc: YamlDocument, path: Path) -> dict[str, Any]:
    if isinstance(model.pipeline, str):
        config_path = Path(model.pipeline)
        if not config_path.is_absolute():
            config_path = path.parent / config_path
        if not config_path.is_file():
            raise ConfigError(f"{doc.where(('pipeline',))}: pipeline: no config file {config_path}")
        return load_config(config_path)
    config = dict(model.pipeline)
    if "pipeline" not in config:
        raise ConfigError(f"{doc.where(('pipeline',))}: pipeline: an inline config needs a 'pipeline' key")
    check_pipeline(config, None, f"{path}: pipeline")
    config.setdefault("name", path.stem)
    return config


def _import_plugins(modules: Iterable[str]) -> None:
    # the one plug-in mechanism of every registry (slamkit.naming); a cell carries the list so a
    # worker on another machine imports them too
    import_plugins(modules, "plugins")


# --- one cell, in a worker ------------------------------------------------------------------------

@dataclass(frozen=True)
class CellTask:
    """What a worker needs to run one cell (small and picklable)."""

    key: str
    config: Mapping[str, Any]
    cell_dir: str
    plugins: tuple[str, ...] = ()


@dataclass(frozen=True)
class CellOutcome:
    """A finished cell as the coordinator keeps it: its runs (small), or its error."""

    key: str
    status: Literal["done", "failed"]
    runs: list[dict[str, Any]] = field(default_factory=list)
    error: str | None = None
    wall_s: float | None = None
    worker_max_rss_mb: float | None = None


ERROR_FILE = "error.json"


def run_cell(task: CellTask) -> CellOutcome:
    """Run one cell into ``task.cell_dir`` (in a worker process). An exception becomes a stored
    failure (the folder with ``config.yaml`` and ``error.json``) and a ``failed`` outcome."""
    import resource

    t0 = time.perf_counter()
    try:
        _import_plugins(task.plugins)
        # a cell folder is the sweep's own: --resume decides which to run again, so replacing is fine
        result = run_pipeline(dict(task.config), task.cell_dir, progress=False, overwrite=True)
        status, runs, error = "done", result.results["runs"], None
    except Exception as exc:  # noqa: BLE001 - one bad cell must not stop the sweep
        status, runs = "failed", []
        error = f"{type(exc).__name__}: {exc}"
        _store_failure(task, exc)
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return CellOutcome(task.key, status, runs, error, time.perf_counter() - t0, rss_mb)


def _cell_kind(config: Mapping[str, Any]) -> str:
    """The canonical pipeline name a cell folder records (what run_pipeline writes), so that a
    retried cell is a result of the same kind."""
    import warnings

    name = str(config.get("pipeline", ""))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an old spelling was reported when the cell ran
            return PIPELINES.canonical(name)
    except Exception:  # noqa: BLE001 - an unknown name is the failure being stored
        return name


def _store_failure(task: CellTask, exc: Exception) -> None:
    try:
        with ResultsFolder(task.cell_dir, pipeline=_cell_kind(task.config), overwrite=True) as folder:
            folder.write_config(task.config)
            folder.write_json(ERROR_FILE, {"error_type": type(exc).__name__, "message": str(exc),
                                           "traceback": traceback.format_exc()})
            folder.finalize(str(task.config.get("pipeline", "")))
    except (OSError, OutputError):
        pass  # not stored: the cell stays unfinished and --resume runs it again


def cell_state(cell_dir: Path) -> Literal["done", "failed"] | None:
    """``done`` (a complete results folder), ``failed`` (a stored error) or None (not finished)."""
    if not is_results_folder(cell_dir):
        return None
    try:
        complete = json.loads((cell_dir / MARKER).read_text()).get("complete", False)
    except (OSError, ValueError):
        return None
    if not complete:
        return None
    if (cell_dir / "results.json").is_file():
        return "done"
    return "failed" if (cell_dir / ERROR_FILE).is_file() else None


def stored_outcome(key: str, cell_dir: Path) -> CellOutcome | None:
    """The outcome of a finished cell read back from its folder (None when it is not finished)."""
    state = cell_state(cell_dir)
    if state == "done":
        return CellOutcome(key, "done", json.loads((cell_dir / "results.json").read_text())["runs"])
    if state == "failed":
        err = json.loads((cell_dir / ERROR_FILE).read_text())
        return CellOutcome(key, "failed", error=f"{err.get('error_type')}: {err.get('message')}")
    return None


# --- the sweep ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class SweepResult:
    out_dir: Path
    results: dict[str, Any]
    report_md: str
    #: cells run in this call, and how many of them failed
    ran: int
    failed: int


def _sweep_record(sweep: Sweep) -> dict[str, Any]:
    """What ``sweep.json`` holds: the sweep's name, its file's model and its base config."""
    return _jsonable({"name": sweep.name, "sweep": sweep.model.model_dump(mode="json"), "base": dict(sweep.base)})


def _sweep_folder(out: str | Path, resume: bool, overwrite: bool) -> tuple[Path, bool]:
    """The sweep folder ``out`` after the output-safety checks, and whether its earlier sweep is
    to be cleared first. New or empty: fine. A sweep folder: ``resume`` continues it (not a
    replacement: every finished cell is kept and reused, also by a grown sweep, since a cell's
    folder is keyed by its resolved config); a new start over it replaces it and needs
    ``overwrite`` (the earlier sweep is then cleared). A result of another kind is never
    replaced."""
    final = check_output_folder(out)
    if not is_results_folder(final):
        return final, False
    try:
        kind = json.loads((final / MARKER).read_text()).get("pipeline")
    except (OSError, ValueError, AttributeError):
        kind = None
    if kind != SWEEP_KIND:
        raise OutputError(f"{final} holds a slamkit run of {kind!r}, not a sweep; a sweep never replaces a result "
                          "of another kind: choose another --out")
    if resume:
        return final, False
    if overwrite:
        return final, True
    raise OutputError(f"{final} holds a sweep already; continue it with --resume, replace it with --overwrite, "
                      "or choose another --out")


def _clear_sweep(final: Path) -> None:
    """Remove what an earlier sweep wrote in ``final`` (the caller holds its lock and has checked
    it is a sweep folder): the marker last, so a kill midway leaves a sweep folder to clear again."""
    import shutil

    for p in sorted(final.iterdir(), key=lambda p: p.name == MARKER):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        else:
            p.unlink()


def _write_marker(out: Path, complete: bool) -> None:
    _write_atomic(out / MARKER, json.dumps({"slamkit_version": slamkit.__version__, "pipeline": SWEEP_KIND,
                                            "complete": complete}) + "\n")


def _write_atomic(path: Path, data: str | bytes) -> None:
    with atomic_file(path) as tmp:
        if isinstance(data, str):
            tmp.write_text(data)
        else:
            tmp.write_bytes(data)


def run_sweep(path: str | Path, out: str | Path, workers: int | None = None, executor: str | Executor = "local",
              address: str | None = None, resume: bool = False, retry_failed: bool = False,
              progress: bool = True, overwrite: bool = False) -> SweepResult:
    """Run the sweep file at ``path`` into the folder ``out`` (see the module docstring) and
    write its results.json, report.md and plots. ``executor`` is ``local``, ``ray`` or an
    :class:`Executor` the caller owns (it is not closed here)."""
    sweep = load_sweep(path)
    final, _ = _sweep_folder(out, resume, overwrite)
    final.mkdir(parents=True, exist_ok=True)
    lock = acquire_folder_lock(final)
    try:
        final, clear = _sweep_folder(final, resume, overwrite)  # again, now that we hold the lock
        if clear:
            _clear_sweep(final)
        _write_marker(final, complete=False)
        cells_dir = final / "cells"
        cells_dir.mkdir(exist_ok=True)
        _write_atomic(final / "sweep.json", json.dumps(_sweep_record(sweep), indent=2, allow_nan=False))
        outcomes: dict[str, CellOutcome] = {}
        todo: list[Cell] = []
        for cell in sweep.cells:
            stored = stored_outcome(cell.key, cell_path(cells_dir, cell.key))
            if stored is None or (retry_failed and stored.status == "failed"):
                todo.append(cell)
            else:
                outcomes[cell.key] = stored
        ran = failed = 0
        if todo:
            for shard in {cell_path(cells_dir, c.key).parent for c in todo}:
                shard.mkdir(exist_ok=True)
            tasks = [CellTask(c.key, c.config, str(cell_path(cells_dir, c.key)), tuple(sweep.model.plugins))
                     for c in todo]
            for outcome in _execute(tasks, executor, workers, address, len(sweep.cells), len(outcomes), progress):
                outcomes[outcome.key] = outcome
                ran += 1
                failed += outcome.status == "failed"
        results, report_md = aggregate(sweep, outcomes, final)
        _write_atomic(final / "results.json", json.dumps(results, indent=2, allow_nan=False))
        _write_atomic(final / "report.md", report_md)
        _write_marker(final, complete=True)
    finally:
        release_folder_lock(final, lock)
    return SweepResult(final, results, report_md, ran, failed)


def _execute(tasks: list[CellTask], executor: str | Executor, workers: int | None, address: str | None,
             total: int, finished: int, progress: bool) -> Iterable[CellOutcome]:
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn,
                               TimeRemainingColumn)

    owned = isinstance(executor, str)
    ex = make_executor(executor, workers, address) if isinstance(executor, str) else executor
    bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("failed {task.fields[failed]}"), TimeElapsedColumn(), TextColumn("ETA"),
                   TimeRemainingColumn(), console=Console(stderr=True), disable=not progress)
    failures = 0
    try:
        with bar:
            task_id = bar.add_task("cells", total=total, completed=finished, failed=0)
            for task in tasks:
                ex.submit(run_cell, task)
            for task, outcome in ex.as_completed():
                if isinstance(outcome, TaskFailure):  # the worker died: nothing was stored
                    outcome = CellOutcome(task.key, "failed", error=f"{outcome.error_type}: {outcome.message}")
                failures += outcome.status == "failed"
                bar.update(task_id, advance=1, failed=failures)
                yield outcome
    finally:
        if owned:
            ex.close()


# --- aggregation --------------------------------------------------------------------------------

def aggregate(sweep: Sweep, outcomes: Mapping[str, CellOutcome], out: Path) -> tuple[dict[str, Any], str]:
    """results.json and report.md of the sweep's finished cells; the plots go to ``out/plots``."""
    runs: list[dict[str, Any]] = []
    records: list[RunRecord] = []
    cells = []
    for cell in sweep.cells:
        outcome = outcomes.get(cell.key)
        status = outcome.status if outcome is not None else "not run"
        cells.append({"key": cell.key, "axes": dict(cell.axes), "status": status,
                      "error": outcome.error if outcome is not None else None,
                      "wall_s": outcome.wall_s if outcome is not None else None,
                      "worker_max_rss_mb": outcome.worker_max_rss_mb if outcome is not None else None})
        for run in (outcome.runs if outcome is not None else []):
            runs.append({**run, "cell": cell.key, "axes": dict(cell.axes)})
            records.append(RunRecord(run["dataset"], run["estimator"], run.get("metrics") or {},
                                     run.get("seed"), dict(cell.axes)))
    swept = list(sweep.model.axes)
    summary = [row for axis in swept for row in summarise(records, by=lambda r, a=axis: {
        "axis": a, "value": r.params[a], "dataset": r.dataset, "estimator": r.estimator})]
    overall = summarise(records)
    # estimators of one cell saw the same data; values of an axis are paired when the other axes match
    paired_estimators = paired_comparisons(records, treatment=lambda r: r.estimator, context=lambda r: {
        "dataset": r.dataset, **{a: r.params[a] for a in _context_axes(swept)}})
    paired_axes = [row for axis in swept for row in paired_comparisons(
        records, treatment=lambda r, a=axis: r.params[a], context=lambda r, a=axis: {
            "axis": a, "dataset": r.dataset, "estimator": r.estimator,
            **{o: r.params[o] for o in _context_axes(swept, a)}})]
    results = _jsonable({
        "pipeline": SWEEP_KIND, "sweep": sweep.name, "base_pipeline": sweep.base.get("pipeline"),
        "slamkit_version": slamkit.__version__,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "axes": {**{a: v for a, v in sweep.model.axes.items()},
                 **({SEED_AXIS: seed_list(sweep.model.seeds)} if sweep.model.seeds is not None else {})},
        "cells": cells, "runs": runs, "summary": summary, "overall": overall,
        "paired": {"estimators": paired_estimators, "axes": paired_axes},
    })
    plots = plot_axes(summary, out / "plots")
    return results, report_markdown(sweep, cells, summary, overall, plots, paired_estimators, paired_axes)


def _context_axes(swept: Iterable[str], compared: str | None = None) -> list[str]:
    """The axes that fix a paired comparison's context besides the run's dataset and estimator
    (an axis named ``dataset`` is already the run's dataset)."""
    return [a for a in swept if a != compared and a not in ("axis", "dataset", "estimator")]


def report_markdown(sweep: Sweep, cells: list[dict[str, Any]], summary: list[dict[str, Any]],
                    overall: list[dict[str, Any]], plots: list[str],
                    paired_estimators: list[dict[str, Any]] | None = None,
                    paired_axes: list[dict[str, Any]] | None = None) -> str:
    done = sum(c["status"] == "done" for c in cells)
    failed = [c for c in cells if c["status"] == "failed"]
    lines = [f"# Sweep {sweep.name}", "",
             f"Pipeline `{sweep.base.get('pipeline')}`, {len(cells)} cells ({sweep.model.mode} over "
             f"{', '.join(sweep.axis_names) or 'no axes'}): {done} done, {len(failed)} failed, "
             f"{len(cells) - done - len(failed)} not run. Values are mean ± half-width of the 95% "
             "confidence interval over the runs with that value.", ""]
    for axis in sweep.model.axes:
        lines += [f"## {axis}", "", summary_markdown([s for s in summary if s["axis"] == axis],
                                                     ["value", "dataset", "estimator"]), ""]
    lines += ["## All cells", "", summary_markdown(overall), ""]
    paired_intro = ("Paired on the seed (same simulated data): per run the difference to the best (best mean "
                    "of the metric), its mean with the 95% Student-t interval and the two-sided Wilcoxon "
                    "signed-rank p-value; significant at p < 0.05.")
    if paired_axes:
        lines += ["## Paired: axis values against the best value", "", paired_intro, ""]
        for axis in sweep.model.axes:
            rows = [r for r in paired_axes if r["axis"] == axis]
            if rows:
                lines += [f"### {axis}", "", paired_markdown(
                    rows, ["dataset", "estimator", *_context_axes(sweep.model.axes, axis)], "value"), ""]
    if paired_estimators:
        lines += ["## Paired: estimators against the best estimator", "", paired_intro, "",
                  paired_markdown(paired_estimators, ["dataset", *_context_axes(sweep.model.axes)]), ""]
    if failed:
        lines += ["## Failed cells", "", markdown_table(
            ["cell", "axes", "error"],
            [[c["key"], ", ".join(f"{k}={_short(v)}" for k, v in c["axes"].items()),
              (c["error"] or "").replace("|", "\\|").replace("\n", " ")[:300]] for c in failed]), ""]
    if plots:
        lines += ["## Plots", ""] + [f"![{p}](plots/{p})" for p in plots] + [""]
    return "\n".join(lines)


def plot_axes(summary: list[dict[str, Any]], plots_dir: Path) -> list[str]:
    """One PNG per metric x swept axis: the mean and 95% CI against the axis value, one line per
    dataset x estimator (numeric values on a numeric x axis, others evenly spaced). Returns the
    file names."""
    if not summary:
        return []
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plots_dir.mkdir(exist_ok=True)
    names = []
    pairs = list(dict.fromkeys((s["axis"], s["metric"]) for s in summary))
    for axis, metric in pairs:
        rows = [s for s in summary if s["axis"] == axis and s["metric"] == metric]
        values = list(dict.fromkeys(_short(s["value"]) for s in rows))
        numeric = all(isinstance(s["value"], (int, float)) and not isinstance(s["value"], bool) for s in rows)
        fig, ax = plt.subplots(figsize=(6, 4))
        for line in dict.fromkeys((s["dataset"], s["estimator"]) for s in rows):
            pts = [s for s in rows if (s["dataset"], s["estimator"]) == line and s["mean"] is not None]
            x = [s["value"] if numeric else values.index(_short(s["value"])) for s in pts]
            y = [s["mean"] for s in pts]
            err = [[m - (s["ci95"][0] if s["ci95"][0] is not None else m) for m, s in zip(y, pts)],
                   [(s["ci95"][1] if s["ci95"][1] is not None else m) - m for m, s in zip(y, pts)]]
            order = sorted(range(len(x)), key=lambda i: x[i])
            ax.errorbar([x[i] for i in order], [y[i] for i in order],
                        yerr=[[err[0][i] for i in order], [err[1][i] for i in order]],
                        marker="o", capsize=3, label=f"{line[1]} ({line[0]})")
        if not numeric:
            ax.set_xticks(range(len(values)), [v[:20] for v in values], rotation=20)
        ax.set_xlabel(axis)
        ax.set_ylabel(metric)
        ax.set_title(f"{metric} against {axis} (mean, 95% CI)", fontsize=10)
        ax.legend(fontsize=7)
        fig.tight_layout()
        path = file_in(plots_dir, f"{metric}_vs_{axis}", ".png", "metric and axis name")
        with atomic_file(path) as tmp:
            fig.savefig(tmp, dpi=90, format="png")
        plt.close(fig)
        names.append(path.name)
    return names
