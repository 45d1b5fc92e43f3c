"""Benchmarks: slamkit timed against a reference measured in the same run (raw GTSAM, a
per-particle Python loop, a default ``casadi.Opti`` build, heapq A*, pyastar2d, OMPL, a naive
nearest-neighbour ICP), one module per suite. ``ratio`` is always "how many times better than
the reference". Speed is measured here, never asserted in the test suite.

This layer sits beside ``experiments`` (it may import every algorithm package) and is the only
place besides ``backend``/``control`` that may import gtsam/casadi: its references are those
libraries used the plain way.
"""

from __future__ import annotations

import importlib
import os
import platform
import sys

from slamkit.errors import ConfigError

#: suite name -> "module:function"; each function takes ``quick: bool`` and returns BenchCases.
SUITES: dict[str, str] = {
    "pose-graph": "slamkit.bench.pose_graph:run",
    "raycast": "slamkit.bench.raycast:run",
    "filters": "slamkit.bench.filters_suite:run",
    "planning": "slamkit.bench.planning:run",
    "control": "slamkit.bench.control:run",
    "scan-matching": "slamkit.bench.scan_matching:run",
    "inertial": "slamkit.bench.inertial:run",
    "sweep": "slamkit.bench.sweep:run",
    "vision": "slamkit.bench.vision:run",
}


def run_bench(name: str, quick: bool = False) -> dict:
    """Run one suite and return the JSON-ready object ``{"bench", "machine", "cases"}``."""
    if name not in SUITES:
        raise ConfigError(f"unknown bench {name!r}; choose from {', '.join(sorted(SUITES))}")
    module_name, fn_name = SUITES[name].split(":")
    fn = getattr(importlib.import_module(module_name), fn_name)
    cases = fn(quick=quick)
    return {
        "bench": name,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "platform": sys.platform},
        "cases": [c.to_dict() for c in cases],
    }
