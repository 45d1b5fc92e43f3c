"""Summary statistics of per-pose (or per-pair) errors, with evo's definitions.

``std`` is the population standard deviation (``np.std``, ddof=0) and ``rmse`` is
sqrt(mean(e^2)), exactly as ``evo.core.metrics.PE.get_statistic`` computes them, so numbers can be
compared with evo's one to one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slamkit.errors import DataError, NoResultError

STAT_NAMES = ("rmse", "mean", "median", "std", "min", "max", "sse")


@dataclass(frozen=True)
class ErrorStats:
    """rmse, mean, median, std, min, max and sum of squares of ``num`` non-negative errors."""

    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    sse: float
    num: int

    @classmethod
    def from_errors(cls, errors: np.ndarray) -> "ErrorStats":
        e = np.asarray(errors, dtype=float).reshape(-1)
        if e.size == 0:
            raise DataError("no errors to summarise (empty error vector)")
        squared = np.power(e, 2)
        if not (np.isfinite(squared).all() and np.isfinite(squared.sum())):
            # an Infinity is not a score: a pose of 1e308 gives inf errors, not a result
            bad = np.flatnonzero(~np.isfinite(squared))
            where = f"error {int(bad[0])} is {float(e[bad[0]])!r}" if len(bad) else "their sum of squares overflows"
            raise NoResultError(f"the error statistics are not finite ({where}): check the trajectories "
                                "for NaN or astronomically large coordinates")
        return cls(
            rmse=float(math.sqrt(np.mean(squared))),
            mean=float(np.mean(e)),
            median=float(np.median(e)),
            std=float(np.std(e)),
            min=float(np.min(e)),
            max=float(np.max(e)),
            sse=float(np.sum(squared)),
            num=int(e.size),
        )

    def to_dict(self) -> dict[str, float | int]:
        return {name: getattr(self, name) for name in STAT_NAMES + ("num",)}


def rmse(errors: np.ndarray) -> float:
    return ErrorStats.from_errors(errors).rmse


# --------------------------------------------------------------------------- rates of events

#: the binomial intervals :func:`rate_interval` knows
INTERVAL_METHODS = ("wilson", "clopper_pearson")


@dataclass(frozen=True)
class RateInterval:
    """``events`` of ``trials`` (a success rate, a collision rate) with its two-sided interval
    ``[low, high]`` at ``confidence`` by ``method``; ``rate`` is nan (and the interval [0, 1]) with
    no trials: nothing was measured."""

    events: int
    trials: int
    rate: float
    low: float
    high: float
    confidence: float
    method: str

    def to_dict(self) -> dict[str, float | int | str]:
        return {"events": self.events, "trials": self.trials, "rate": self.rate, "ci_low": self.low,
                "ci_high": self.high, "confidence": self.confidence, "method": self.method}

    def text(self, digits: int = 3) -> str:
        """``0.967 [0.833, 0.994] (29/30)``: how a table shows it."""
        if self.trials == 0:
            return "- (0 runs)"
        return f"{self.rate:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}] ({self.events}/{self.trials})"


def _check_counts(events: int, trials: int, confidence: float) -> None:
    if isinstance(events, bool) or isinstance(trials, bool) or int(events) != events or int(trials) != trials:
        raise DataError(f"a rate needs whole counts, got {events!r} of {trials!r}")
    if not 0 <= events <= trials:
        raise DataError(f"a rate needs 0 <= events <= trials, got {events} of {trials}")
    if not (isinstance(confidence, (int, float)) and 0.0 < confidence < 1.0):
        raise DataError(f"confidence must lie in (0, 1), got {confidence!r}")


def wilson_interval(events: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson's score interval (Wilson, JASA 22, 1927; Newcombe, Stat. Med. 17, 1998, method 3):
    the rates p whose score test |p_hat - p| / sqrt(p (1 - p) / n) <= z does not reject. Unlike
    the normal (Wald) interval it never leaves [0, 1] and is not zero-width at 0 or n events,
    which is where a collision rate lives. (0, 1) with no trials."""
    _check_counts(events, trials, confidence)
    if trials == 0:
        return 0.0, 1.0
    from scipy.stats import norm

    z = float(norm.ppf(0.5 + confidence / 2.0))
    n, p = float(trials), events / trials
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    # at 0 or n events one bound is exactly 0 or 1; the formula gets there only up to rounding
    low = 0.0 if events == 0 else max(0.0, centre - half)
    high = 1.0 if events == trials else min(1.0, centre + half)
    return low, high


def clopper_pearson_interval(events: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """The exact (Clopper & Pearson, Biometrika 26, 1934) interval from the beta quantiles of the
    binomial tails: coverage at least ``confidence`` for every true rate (conservative: wider
    than Wilson's). (0, 1) with no trials."""
    _check_counts(events, trials, confidence)
    if trials == 0:
        return 0.0, 1.0
    from scipy.stats import beta

    alpha = 1.0 - confidence
    low = 0.0 if events == 0 else float(beta.ppf(alpha / 2, events, trials - events + 1))
    high = 1.0 if events == trials else float(beta.ppf(1 - alpha / 2, events + 1, trials - events))
    return low, high


def rate_interval(events: int, trials: int, confidence: float = 0.95, method: str = "wilson") -> RateInterval:
    """The rate ``events / trials`` with its binomial interval (``method`` of
    :data:`INTERVAL_METHODS`)."""
    if method not in INTERVAL_METHODS:
        raise DataError(f"unknown interval method {method!r}; choose from {INTERVAL_METHODS}")
    low, high = (wilson_interval if method == "wilson" else clopper_pearson_interval)(events, trials, confidence)
    rate = events / trials if trials else float("nan")
    return RateInterval(int(events), int(trials), rate, low, high, float(confidence), method)


def rate_of(flags, confidence: float = 0.95, method: str = "wilson") -> RateInterval:
    """:func:`rate_interval` of a sequence of 0/1 outcomes (NaN entries are not trials: an
    episode that did not measure the event)."""
    x = np.asarray(list(flags), dtype=float).reshape(-1)
    x = x[np.isfinite(x)]
    if np.any((x != 0) & (x != 1)):
        raise DataError(f"rate_of expects 0/1 outcomes, got {sorted(set(x[(x != 0) & (x != 1)].tolist()))[:5]}")
    return rate_interval(int(x.sum()), int(x.size), confidence, method)
