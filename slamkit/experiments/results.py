"""The one shape every run leaves behind (ARCHITECTURE.md section 6), written atomically.

A run is assembled in a hidden sibling folder ``.<name>.partial-<id>`` and swapped onto
``<out>`` only when complete, so a crashed or interrupted run never leaves a folder that looks
finished, and only folders slamkit wrote are ever replaced (see :class:`ResultsFolder`). ``results.json`` holds ``runs`` (one record per dataset x estimator x seed) and
``summary`` (mean and 95% confidence interval per dataset x estimator x metric).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import shutil
import sys
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Literal, Mapping

import numpy as np
import yaml
from scipy import stats as _stats

import slamkit
from slamkit.errors import OutputError
from slamkit.paths import check_no_file_above


@dataclass(frozen=True)
class RunRecord:
    """One estimator (or planner, controller) on one dataset with one seed."""

    dataset: str
    estimator: str
    metrics: Mapping[str, float]
    seed: int | None = None
    params: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"dataset": self.dataset, "estimator": self.estimator, "seed": self.seed,
                             "metrics": {k: _jsonable(v) for k, v in self.metrics.items()}}
        if self.params:
            d["params"] = {k: _jsonable(v) for k, v in self.params.items()}
        return d


def _jsonable(v: Any) -> Any:
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return f if math.isfinite(f) else None
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, np.ndarray):
        return [_jsonable(x) for x in v.tolist()]
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    return v


def mean_ci95(values: Iterable[float]) -> tuple[float, tuple[float, float], int]:
    """Mean and two-sided 95% Student-t confidence interval of the mean (NaNs dropped)."""
    x = np.asarray([v for v in values if v is not None], dtype=float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n == 0:
        return float("nan"), (float("nan"), float("nan")), 0
    mean = float(x.mean())
    if n == 1:
        return mean, (mean, mean), 1
    half = float(_stats.t.ppf(0.975, n - 1) * x.std(ddof=1) / math.sqrt(n))
    return mean, (mean - half, mean + half), n


def _canonical(v: Any) -> str:
    """A hashable key for a plain value, lists and mappings included: its canonical JSON."""
    return json.dumps(_jsonable(v), sort_keys=True)


def _by_dataset_estimator(r: RunRecord) -> dict[str, Any]:
    return {"dataset": r.dataset, "estimator": r.estimator}


def summarise(runs: Iterable[RunRecord],
              by: Callable[[RunRecord], Mapping[str, Any]] = _by_dataset_estimator
              ) -> list[dict[str, Any]]:
    """One summary row per group x metric over the runs of the group, in first-seen order.

    A group is what ``by(run)`` returns (default: dataset and estimator, so the rows are over
    seeds); its fields lead the row, which goes on with ``metric``, ``mean``, ``ci95``, ``n``."""
    groups: dict[tuple, list[float]] = {}
    fields: dict[tuple, Mapping[str, Any]] = {}
    for r in runs:
        group = by(r)
        key = tuple((k, _canonical(v)) for k, v in group.items())
        fields.setdefault(key, group)
        for metric, value in r.metrics.items():
            if isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool):
                groups.setdefault(key + (metric,), []).append(float(value))
    out = []
    for key, values in groups.items():
        mean, ci, n = mean_ci95(values)
        out.append({**_jsonable(dict(fields[key[:-1]])), "metric": key[-1],
                    "mean": _jsonable(mean), "ci95": [_jsonable(ci[0]), _jsonable(ci[1])], "n": n})
    return out


#: unit suffixes of error, size and time metrics: a smaller value is better
_LOWER_IS_BETTER_SUFFIXES = ("_m", "_rad", "_deg", "_ms", "_s", "_mps", "_mps2", "_radps", "_mb")
#: words of rates of success: a larger value is better
_HIGHER_IS_BETTER_WORDS = ("success", "recall", "precision", "inlier_ratio", "real_time_factor", "certified")


def metric_direction(metric: str) -> Literal["lower", "higher"] | None:
    """Whether a smaller or a larger value of ``metric`` is better, from its name (errors, times
    and sizes carry a unit suffix: lower; success rates, recall, precision: higher), or None for
    metrics with no better side (NEES, counts, fractions of a band)."""
    if any(w in metric for w in _HIGHER_IS_BETTER_WORDS):
        return "higher"
    if metric.endswith(_LOWER_IS_BETTER_SUFFIXES):
        return "lower"
    return None


def paired_difference(values: Iterable[float], reference: Iterable[float]) -> dict[str, Any]:
    """The paired difference ``values - reference`` (same data and seed at the same index): its
    mean with the 95% Student-t interval and the two-sided Wilcoxon signed-rank p-value (exact for
    small samples, scipy's default). Pairs with a NaN on either side are dropped, zero differences
    do not enter the test, and all-zero differences give p = 1."""
    a = np.asarray(list(values), dtype=float)
    b = np.asarray(list(reference), dtype=float)
    if a.shape != b.shape:
        raise ValueError(f"paired samples differ in length: {a.shape} vs {b.shape}")
    d = (a - b)[np.isfinite(a) & np.isfinite(b)]
    mean, ci, n = mean_ci95(d)
    if n == 0 or not np.any(d != 0):
        p = float("nan") if n == 0 else 1.0
    else:
        # zero differences (ties with the reference) carry no sign: dropped, as Wilcoxon proposed
        p = float(_stats.wilcoxon(d[d != 0]).pvalue)
    return {"mean_difference": mean, "ci95": list(ci), "wilcoxon_p": p, "pairs": n}


def paired_comparisons(runs: Iterable[RunRecord], treatment: Callable[[RunRecord], Any],
                       context: Callable[[RunRecord], Mapping[str, Any]] = lambda r: {"dataset": r.dataset},
                       pair: Callable[[RunRecord], Any] = lambda r: r.seed, alpha: float = 0.05,
                       min_pairs: int = 2) -> list[dict[str, Any]]:
    """Every treatment against the best one, paired on shared runs, per context x metric.

    Runs are grouped by ``context(run)`` (default: the dataset); inside a group, the runs of a
    ``treatment(run)`` (an estimator, a swept value) are matched to the best treatment's on
    ``pair(run)`` (default: the seed, so both saw the same data). The best is the treatment with
    the best mean over the pairs every treatment has, in the metric's :func:`metric_direction`
    (metrics without one are skipped; so are groups with fewer than ``min_pairs`` shared runs: one
    recording is no sample). Each row holds the context's fields, ``metric``,
    ``treatment``, ``best``, the :func:`paired_difference` of treatment minus best and
    ``significant`` (p < alpha; with fewer than 6 pairs the exact test cannot reach 0.05)."""
    # treatments and pairs are keyed by their canonical JSON: a swept value may be a list or a
    # mapping (``counts: [[0, 5], [0, 10]]``), which is not hashable; ``values`` maps back
    table: dict[tuple, dict[str, dict[str, float]]] = {}
    fields: dict[tuple, Mapping[str, Any]] = {}
    values: dict[str, Any] = {}
    for r in runs:
        ctx = context(r)
        key = tuple((k, _canonical(v)) for k, v in ctx.items())
        fields.setdefault(key, ctx)
        t = _canonical(treatment(r))
        values.setdefault(t, treatment(r))
        for metric, value in r.metrics.items():
            if (metric_direction(metric) is None or isinstance(value, bool)
                    or not isinstance(value, (int, float, np.floating, np.integer))):
                continue
            table.setdefault(key + (metric,), {}).setdefault(t, {})[_canonical(pair(r))] = float(value)
    out = []
    for key, by_treatment in table.items():
        if len(by_treatment) < 2:
            continue
        metric = key[-1]
        shared = set.intersection(*(set(v) for v in by_treatment.values()))
        if len(shared) < min_pairs:
            continue
        order = sorted(shared)
        means = {t: float(np.nanmean([v[p] for p in order])) for t, v in by_treatment.items()}
        finite = {t: m for t, m in means.items() if math.isfinite(m)}
        if not finite:
            continue
        sign = 1.0 if metric_direction(metric) == "lower" else -1.0
        best = min(finite, key=lambda t: sign * finite[t])
        for t, v in by_treatment.items():
            if t == best:
                continue
            diff = paired_difference([v[p] for p in order], [by_treatment[best][p] for p in order])
            out.append({**_jsonable(dict(fields[key[:-1]])), "metric": metric, "treatment": _jsonable(values[t]),
                        "best": _jsonable(values[best]), **_jsonable(diff),
                        "significant": bool(math.isfinite(diff["wilcoxon_p"]) and diff["wilcoxon_p"] < alpha)})
    return out


def _cell_text(v: Any) -> Any:
    """A value as a table cell: a list or mapping (a swept list value) as compact JSON."""
    return json.dumps(_jsonable(v), separators=(",", ":")) if isinstance(v, (list, tuple, dict)) else v


def paired_markdown(rows: list[dict[str, Any]], lead: list[str], treatment_name: str = "estimator") -> str:
    """The paired comparisons as a table: per ``lead`` fields and metric, each treatment's
    difference to the best with its 95% CI, the Wilcoxon p-value and whether it is significant."""
    table = []
    for r in rows:
        lo, hi = r["ci95"]
        table.append([*(_cell_text(r[k]) for k in lead), r["metric"], _cell_text(r["treatment"]),
                      _cell_text(r["best"]), r["pairs"],
                      r["mean_difference"], "" if lo is None else f"[{lo:.3g}, {hi:.3g}]",
                      r["wilcoxon_p"], "**yes**" if r["significant"] else "no"])
    return markdown_table([*lead, "metric", treatment_name, "best", "pairs", "difference to best", "95% CI",
                           "Wilcoxon p", "significant"], table)


def markdown_table(header: list[str], rows: list[list[Any]]) -> str:
    def fmt(v: Any) -> str:
        if isinstance(v, float):
            return "nan" if not math.isfinite(v) else f"{v:.6g}"
        return "" if v is None else str(v)

    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def summary_markdown(summary: list[dict[str, Any]], lead: list[str] = ["dataset", "estimator"]) -> str:
    """The summary as a table: one row per value of the ``lead`` fields (default dataset x
    estimator), one column per metric, each cell mean ± half-width of the 95% CI."""
    metrics: list[str] = []
    cells: dict[tuple, dict[str, str]] = {}
    for s in summary:
        if s["metric"] not in metrics:
            metrics.append(s["metric"])
        mean, (lo, hi), n = s["mean"], s["ci95"], s["n"]
        text = "" if mean is None else f"{mean:.4g}"
        if n > 1 and lo is not None and hi is not None:
            text += f" ± {(hi - lo) / 2:.2g}"
        key = tuple(v if isinstance(v, str) else json.dumps(_jsonable(v), separators=(",", ":"))
                    for v in (s[k] for k in lead))
        cells.setdefault(key, {})[s["metric"]] = text
    rows = [list(key) + [c.get(m, "") for m in metrics] for key, c in cells.items()]
    return markdown_table(list(lead) + metrics, rows)


#: the file that proves a folder is a slamkit results folder (written first, into the partial)
MARKER = ".slamkit-results"
#: the marker's ``pipeline`` in a sweep folder (``slamkit sweep``)
SWEEP_KIND = "sweep"


def _rename_exchange():
    """``renameat2(..., RENAME_EXCHANGE)`` from libc, or None where the kernel/libc lack it."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    at_fdcwd, rename_exchange = -100, 2

    def exchange(a: Path, b: Path) -> bool:
        """Atomically swap two existing paths; False when the file system refuses (EINVAL...)."""
        if fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
            return True
        err = ctypes.get_errno()
        if err in (22, 38, 95):  # EINVAL, ENOSYS, EOPNOTSUPP: not supported here
            return False
        raise OSError(err, os.strerror(err), str(b))

    return exchange


_EXCHANGE = _rename_exchange() if sys.platform.startswith("linux") else None


def is_results_folder(path: Path) -> bool:
    return path.is_dir() and not path.is_symlink() and (path / MARKER).is_file()


def check_output_folder(out: str | Path) -> Path:
    """The absolute path of ``out`` if slamkit may (re)place a results folder there: it does not
    exist, or is an empty folder, or is a results folder slamkit wrote (it holds the marker).
    Anything else -- a regular file, a symbolic link, a folder of someone else's files -- is an
    OutputError, and nothing is touched."""
    final = Path(os.path.abspath(out))
    check_no_file_above(final)
    if final.is_symlink():
        raise OutputError(f"{final} is a symbolic link; slamkit writes results only to a real "
                          "folder: choose another --out")
    if not final.exists():
        return final
    if not final.is_dir():
        raise OutputError(f"{final} is a file, not a results folder; slamkit will not replace it: "
                          "choose another --out")
    if is_results_folder(final) or not any(final.iterdir()):
        return final
    raise OutputError(f"{final} exists and is not a slamkit results folder (no {MARKER} marker); "
                      "slamkit only replaces folders it wrote: remove it or choose another --out")


def folder_kind(path: Path) -> str | None:
    """The ``pipeline`` a results folder's marker records (``sweep`` for a sweep folder), or None
    when ``path`` is not a results folder or its marker is unreadable."""
    if not is_results_folder(path):
        return None
    try:
        kind = json.loads((path / MARKER).read_text()).get("pipeline")
    except (OSError, ValueError, AttributeError):
        return None
    return kind if isinstance(kind, str) else None


def check_replace(final: Path, pipeline: str, overwrite: bool) -> None:
    """May a result of kind ``pipeline`` replace what is at ``final``? A results folder of another
    kind, never (a sweep is hours of cells; a run of another pipeline is another experiment); one
    of the same kind only with ``overwrite`` (the CLI's ``--overwrite``), as users of result
    folders expect. Nothing there, or an empty folder, is always fine."""
    if not is_results_folder(final):
        return
    kind = folder_kind(final)
    if kind == SWEEP_KIND and pipeline != SWEEP_KIND:
        raise OutputError(f"{final} is a sweep folder (written by slamkit sweep); a run would replace the "
                          "whole sweep: choose another --out")
    if kind != pipeline:
        raise OutputError(f"{final} holds a result of {kind!r}; a {pipeline!r} result never replaces one of "
                          "another kind: choose another --out")
    if not overwrite:
        raise OutputError(f"{final} holds a result of {kind!r} already; pass --overwrite to replace it, or "
                          "choose another --out")


def _lock_path(final: Path) -> Path:
    return final.parent / f".{final.name}.lock"


def acquire_folder_lock(final: Path) -> int:
    """Hold ``.<name>.lock`` (``flock``) beside the output folder ``final``; the descriptor is
    released by :func:`release_folder_lock`. A second writer gets an OutputError at once."""
    import fcntl

    lock = _lock_path(final)
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise OutputError(f"another slamkit run is writing {final} (it holds {lock}); wait "
                              "for it to finish or choose another --out") from None
        # the holder before us may have unlinked the lock file after we opened it: make
        # sure we locked the file that is at the path now
        try:
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:
            return fd
        os.close(fd)


def release_folder_lock(final: Path, fd: int) -> None:
    _lock_path(final).unlink(missing_ok=True)
    os.close(fd)


class ResultsFolder:
    """Assemble a run folder under a temporary name; ``commit`` swaps it into place.

    The rules (issue 10: never lose a user's files):

    * only a folder slamkit can prove it wrote (the :data:`MARKER` file) or an empty folder is
      replaced; anything else is refused with an :class:`~slamkit.errors.OutputError`; a results
      folder is never replaced by a result of another kind (its marker's ``pipeline``: a sweep
      folder's is ``sweep``), and one of the same kind only with ``overwrite``
      (:func:`check_replace`);
    * a run holds ``.<name>.lock`` (``flock``) beside the folder for its whole life; a second run
      into the same folder is refused with a clear message while the first is running;
    * the folder is assembled in ``.<name>.partial-<id>`` (marker first) and swapped with the
      previous result by ``renameat2(RENAME_EXCHANGE)``, so ``<out>`` holds the old complete
      result or the new complete one at every instant; where the exchange is unavailable the
      old result is renamed aside (``.<name>.old-<id>``) first, and a run killed between the two
      renames is repaired by the next run, which renames it back;
    * leftovers of killed runs (hidden partial or old folders that carry the marker) are removed
      by the next run into the same folder, while it holds the lock.

    Use as a context manager: on an exception the partial folder is removed and any earlier
    complete folder at ``out`` is left untouched.
    """

    def __init__(self, out: str | Path, pipeline: str = "", overwrite: bool = False):
        self.final = check_output_folder(out)
        check_replace(self.final, pipeline, overwrite)
        self.final.parent.mkdir(parents=True, exist_ok=True)
        self._lock_fd = self._acquire_lock()
        self.committed = False
        #: the results.json written by :meth:`commit`, parsed (None before)
        self.results: dict[str, Any] | None = None
        try:
            self.final = check_output_folder(self.final)  # again, now that we hold the lock
            check_replace(self.final, pipeline, overwrite)
            self.kind = pipeline
            self._clean_leftovers()
            self.path = self.final.parent / f".{self.final.name}.partial-{uuid.uuid4().hex[:8]}"
            self.path.mkdir()
            self._write_marker(pipeline, complete=False)
        except BaseException:
            self._release_lock()
            raise

    # -- bookkeeping ---------------------------------------------------------------------------

    def _acquire_lock(self) -> int:
        return acquire_folder_lock(self.final)

    def _release_lock(self) -> None:
        if self._lock_fd is None:
            return
        release_folder_lock(self.final, self._lock_fd)
        self._lock_fd = None

    def _leftovers(self, kind: str) -> list[Path]:
        return sorted(p for p in self.final.parent.glob(f".{glob_escape(self.final.name)}.{kind}-*")
                      if is_results_folder(p))

    def _clean_leftovers(self) -> None:
        olds = self._leftovers("old")
        if olds and not self.final.exists():
            # killed between the two renames of the fallback path: put the old result back
            os.replace(olds.pop(), self.final)
        for p in olds + self._leftovers("partial"):
            shutil.rmtree(p, ignore_errors=True)

    def _write_marker(self, pipeline: str, complete: bool) -> None:
        marker = {"slamkit_version": slamkit.__version__, "pipeline": pipeline, "complete": complete}
        (self.path / MARKER).write_text(json.dumps(marker) + "\n")

    # -- contents ------------------------------------------------------------------------------

    @property
    def plots(self) -> Path:
        p = self.path / "plots"
        p.mkdir(exist_ok=True)
        return p

    @property
    def trajectories(self) -> Path:
        p = self.path / "trajectories"
        p.mkdir(exist_ok=True)
        return p

    @property
    def recording_path(self) -> Path:
        return self.path / "recording.rrd"

    def write_config(self, config: Mapping[str, Any]) -> None:
        (self.path / "config.yaml").write_text(yaml.safe_dump(_jsonable(dict(config)), sort_keys=False))

    def commit(self, pipeline: str, runs: list[RunRecord], report_md: str,
               summary: list[dict[str, Any]] | None = None, extra: Mapping[str, Any] | None = None
               ) -> Path:
        summary = summarise(runs) if summary is None else summary
        results = {
            "pipeline": pipeline,
            "slamkit_version": slamkit.__version__,
            "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "runs": [r.to_dict() for r in runs],
            "summary": summary,
        }
        if extra:
            results.update(_jsonable(dict(extra)))
        text = json.dumps(results, indent=2, allow_nan=False)
        (self.path / "results.json").write_text(text)
        self.results = json.loads(text)  # as a reader of the file gets it, without reading it back
        (self.path / "report.md").write_text(report_md)
        return self.finalize(pipeline)

    def write_json(self, name: str, data: Mapping[str, Any]) -> Path:
        path = self.path / name
        path.write_text(json.dumps(_jsonable(dict(data)), indent=2, allow_nan=False))
        return path

    def finalize(self, pipeline: str = "") -> Path:
        """Put the assembled folder at its final name, replacing an earlier result atomically."""
        # the kind the folder was opened for (the one check_replace compares) wins over a spelling
        self._write_marker(self.kind or pipeline, complete=True)
        _fsync_tree(self.path)
        if self.final.exists():
            if _EXCHANGE is not None and _EXCHANGE(self.path, self.final):
                shutil.rmtree(self.path)  # now holds the previous result
            else:
                self._replace_by_two_renames()
        else:
            os.replace(self.path, self.final)
        self.committed = True
        self._release_lock()
        return self.final

    def _replace_by_two_renames(self) -> None:
        old = self.final.parent / f".{self.final.name}.old-{uuid.uuid4().hex[:8]}"
        os.replace(self.final, old)
        os.replace(self.path, self.final)
        shutil.rmtree(old, ignore_errors=True)

    def discard(self) -> None:
        if not self.committed:
            shutil.rmtree(self.path, ignore_errors=True)
        self._release_lock()

    def __enter__(self) -> "ResultsFolder":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None or not self.committed:
            self.discard()


def glob_escape(name: str) -> str:
    """``name`` with glob metacharacters escaped (a folder may be called ``runs[1]``)."""
    import glob

    return glob.escape(name)


def _fsync_tree(root: Path) -> None:
    """Flush the assembled files before the rename makes them the result (a power cut must not
    leave a complete-looking folder of empty files)."""
    for dirpath, _, files in os.walk(root):
        for name in files:
            fd = os.open(os.path.join(dirpath, name), os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
