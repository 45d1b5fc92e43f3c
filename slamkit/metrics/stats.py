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
