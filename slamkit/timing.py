"""Wall-clock timing helper for algorithm code (the solvers' build/init/solve split)."""

from __future__ import annotations

import time


class Stopwatch:
    """``with Stopwatch() as sw: ...; sw.elapsed_s``"""

    def __enter__(self) -> "Stopwatch":
        self._t0 = time.perf_counter()
        self.elapsed_s = 0.0
        return self

    def __exit__(self, *exc: object) -> None:
        self.elapsed_s = time.perf_counter() - self._t0
