"""The one shape every run leaves behind (ARCHITECTURE.md section 6), written atomically.

A run is assembled in a hidden sibling folder ``.<name>.partial-<id>`` and renamed onto
``<out>`` only when complete, so a crashed or interrupted run never leaves a folder that looks
finished. ``results.json`` holds ``runs`` (one record per dataset x estimator x seed) and
``summary`` (mean and 95% confidence interval per dataset x estimator x metric).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import shutil
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np
import yaml
from scipy import stats as _stats

import slamkit


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


def summarise(runs: Iterable[RunRecord]) -> list[dict[str, Any]]:
    """One summary row per (dataset, estimator, metric) over seeds, in first-seen order."""
    groups: dict[tuple[str, str, str], list[float]] = {}
    for r in runs:
        for metric, value in r.metrics.items():
            if isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool):
                groups.setdefault((r.dataset, r.estimator, metric), []).append(float(value))
    out = []
    for (dataset, estimator, metric), values in groups.items():
        mean, ci, n = mean_ci95(values)
        out.append({"dataset": dataset, "estimator": estimator, "metric": metric,
                    "mean": _jsonable(mean), "ci95": [_jsonable(ci[0]), _jsonable(ci[1])], "n": n})
    return out


def markdown_table(header: list[str], rows: list[list[Any]]) -> str:
    def fmt(v: Any) -> str:
        if isinstance(v, float):
            return "nan" if not math.isfinite(v) else f"{v:.6g}"
        return "" if v is None else str(v)

    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def summary_markdown(summary: list[dict[str, Any]]) -> str:
    """The summary as a table: one row per dataset x estimator, one column per metric."""
    metrics: list[str] = []
    cells: dict[tuple[str, str], dict[str, str]] = {}
    for s in summary:
        if s["metric"] not in metrics:
            metrics.append(s["metric"])
        mean, (lo, hi), n = s["mean"], s["ci95"], s["n"]
        text = "" if mean is None else f"{mean:.4g}"
        if n > 1 and lo is not None and hi is not None:
            text += f" ± {(hi - lo) / 2:.2g}"
        cells.setdefault((s["dataset"], s["estimator"]), {})[s["metric"]] = text
    rows = [[d, e] + [c.get(m, "") for m in metrics] for (d, e), c in cells.items()]
    return markdown_table(["dataset", "estimator"] + metrics, rows)


class ResultsFolder:
    """Assemble a run folder under a temporary name; ``commit`` renames it into place.

    Use as a context manager: on an exception the partial folder is removed and any earlier
    complete folder at ``out`` is left untouched.
    """

    def __init__(self, out: str | Path):
        self.final = Path(out).resolve()
        self.final.parent.mkdir(parents=True, exist_ok=True)
        self.path = self.final.parent / f".{self.final.name}.partial-{uuid.uuid4().hex[:8]}"
        self.path.mkdir()
        self.committed = False

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
        (self.path / "results.json").write_text(json.dumps(results, indent=2, allow_nan=False))
        (self.path / "report.md").write_text(report_md)
        return self.finalize()

    def write_json(self, name: str, data: Mapping[str, Any]) -> Path:
        path = self.path / name
        path.write_text(json.dumps(_jsonable(dict(data)), indent=2, allow_nan=False))
        return path

    def finalize(self) -> Path:
        """Move the assembled folder onto its final name (replacing an earlier one)."""
        if self.final.exists():
            # keep the previous complete result until the new one is in place
            old = self.final.parent / f".{self.final.name}.old-{uuid.uuid4().hex[:8]}"
            os.replace(self.final, old)
            os.replace(self.path, self.final)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(self.path, self.final)
        self.committed = True
        return self.final

    def discard(self) -> None:
        if not self.committed:
            shutil.rmtree(self.path, ignore_errors=True)

    def __enter__(self) -> "ResultsFolder":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None or not self.committed:
            self.discard()
