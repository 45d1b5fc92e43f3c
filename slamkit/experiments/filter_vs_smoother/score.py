"""``filter_vs_smoother`` scoring across seeds: the Monte-Carlo NEES consistency table and the
payload observers and plots receive.

Each run is scored by :func:`slamkit.experiments.runner.score` inside its task; here the runs of
one scenario x estimator are combined: the average NEES over the M seeds at every step against
the two-sided 95% band of chi2(d M) / M (Bar-Shalom, Li & Kirubarajan 2001, sec. 5.4.2), and a
verdict per row.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from slamkit.data.sequence import Sequence
from slamkit.errors import DataError
from slamkit.experiments.filter_vs_smoother.config import EstimatorChoice, ScenarioSpec
from slamkit.experiments.filter_vs_smoother.monte_carlo import TaskResult
from slamkit.experiments.runner import EstimatorRun, ErrorSeries, monte_carlo_nees


class NeesCurve(NamedTuple):
    """The Monte-Carlo average NEES of one scenario x estimator over time."""

    stamps_s: np.ndarray
    anees: np.ndarray
    #: (lower, upper) of the two-sided 95% band of chi2(d M) / M
    band: tuple[float, float]
    #: M, the runs averaged
    runs: int
    #: d, the pose dimension (3 planar, 6 in 3D): the expected value of the average NEES
    dof: int


#: above this fraction of steps without a positive-definite covariance no verdict is given
DEGENERATE_VERDICT_LIMIT = 0.1


def nees_verdict(anees_mean: float, band: tuple[float, float], degenerate_fraction: float) -> str:
    """inside / above: overconfident / below: conservative, or 'degenerate' when too many steps
    have a covariance that is not positive definite (a collapsed particle set is not conservative)."""
    if degenerate_fraction > DEGENERATE_VERDICT_LIMIT or not np.isfinite(anees_mean):
        return f"degenerate covariance ({100 * degenerate_fraction:.0f}% of steps)"
    if band[0] <= anees_mean <= band[1]:
        return "inside"
    return "above: overconfident" if anees_mean > band[1] else "below: conservative"


def consistency_table(results: list[TaskResult], scenarios: list[ScenarioSpec],
                      choices: list[EstimatorChoice]
                      ) -> tuple[list[dict[str, Any]], dict[tuple[str, str], NeesCurve]]:
    """Per scenario x estimator: the time-mean of the Monte-Carlo average NEES, its chi2(d M)/M
    95% band, whether it lies inside, and the fraction of steps whose average NEES does."""
    rows: list[dict[str, Any]] = []
    curves: dict[tuple[str, str], NeesCurve] = {}
    for s in scenarios:
        for c in choices:
            series = [r.series[c.label] for r in results
                      if r.scenario == s.name and c.label in r.series and r.series[c.label].nees is not None]
            if not series:
                continue
            try:
                stamps, anees, band = monte_carlo_nees(series)
            except DataError:
                continue
            degenerate = float(np.mean([np.mean(~np.isfinite(x.nees)) for x in series]))
            finite = np.isfinite(anees)
            mean = float(np.mean(anees[finite])) if finite.any() else float("nan")
            inside = float(np.mean((anees[finite] >= band[0]) & (anees[finite] <= band[1]))) if finite.any() else 0.0
            rows.append({"dataset": s.name, "estimator": c.label, "runs": len(series),
                         "anees_mean": mean, "band95": [band[0], band[1]],
                         "inside_band": bool(finite.any() and band[0] <= mean <= band[1]),
                         "steps_in_band_fraction": inside, "degenerate_fraction": degenerate,
                         "verdict": nees_verdict(mean, band, degenerate)})
            curves[(s.name, c.label)] = NeesCurve(stamps, anees, band, len(series), series[0].dof)
    return rows, curves


@dataclass(frozen=True)
class ScenarioOutcome:
    """What the observer and the plots need of one scenario: its first seed's sequence, runs
    and error series, and the Monte-Carlo NEES curve of every estimator that has one."""

    name: str
    sequence: Sequence
    runs: dict[str, EstimatorRun]
    series: dict[str, ErrorSeries]
    anees: dict[str, NeesCurve]


@dataclass(frozen=True)
class FilterVsSmootherPayload:
    """The pipeline's payload (``Pipeline.payload_type``): one outcome per scenario."""

    scenarios: list[ScenarioOutcome]
    estimators: list[str]


def payload_of(results: list[TaskResult], scenarios: list[ScenarioSpec], choices: list[EstimatorChoice],
               curves: dict[tuple[str, str], NeesCurve]) -> FilterVsSmootherPayload:
    outcomes = []
    for s in scenarios:
        full = next(r for r in results if r.scenario == s.name and r.sequence is not None)
        outcomes.append(ScenarioOutcome(
            s.name, full.sequence, full.runs, full.series,
            {c: curves[(s.name, c)] for (sn, c) in curves if sn == s.name}))
    return FilterVsSmootherPayload(outcomes, [c.label for c in choices])
