"""The benchmark case type shared by every ``slamkit bench`` suite.

Benchmarks compare slamkit against a reference measured in the same run and report
``ratio`` = how many times better slamkit is (reference_time / slamkit_time for times,
slamkit_rate / reference_rate for rates). They are never asserted in the test suite.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any, Callable


@dataclass(frozen=True)
class BenchCase:
    name: str
    value: float
    unit: str
    reference: str | None = None
    reference_value: float | None = None
    ratio: float | None = None
    goal: str | None = None
    extra: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        if d["extra"] is None:
            d.pop("extra")
        return d


def compare(name: str, value: float, unit: str, reference: str, reference_value: float,
            goal: str | None = None, higher_is_better: bool = False, **extra: Any) -> BenchCase:
    """Build a case whose ratio says how many times better ``value`` is than the reference."""
    if higher_is_better:
        ratio = value / reference_value if reference_value > 0 else float("inf")
    else:
        ratio = reference_value / value if value > 0 else float("inf")
    return BenchCase(name, float(value), unit, reference, float(reference_value), float(ratio), goal,
                     extra or None)


def best_of(fn: Callable[[], Any], repeat: int = 3) -> tuple[float, Any]:
    """Run ``fn`` ``repeat`` times; return (best wall time in seconds, last result)."""
    best = float("inf")
    result = None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result
