"""``slamkit bench sweep``: what running a sweep's cells on an executor costs (issue 17).

* ``sweep_filter_cells_2_workers``: a sweep of short ``filter_vs_smoother`` runs (one EKF on a 10 s
  simulated landmark world, one seed per cell; each cell a whole pipeline run with its plots and
  trajectories) on 2 local workers against the same sweep on 1 worker; ``ratio`` is the speed-up,
  ``efficiency`` = speed-up / 2 (goal >= 80%). Memory: the largest worker RSS.
  ``utilisation``: the fraction of the workers' time spent inside cells.
* ``sweep_noop_cell_local_ms`` against Ray: the wall time per cell of the sweep machinery alone
  (a pipeline that does nothing: validation, the cell folder's atomic commit, the round trip to
  the worker, aggregation) on the local pool (2 workers) and on a local Ray instance (2 CPUs),
  both with their workers already started.
* ``sweep_coordinator_rss_mb_per_1000_cells``: the coordinator's peak RSS (its own process, not the
  workers') for no-op sweeps of increasing size, each in a fresh process; the value is the slope
  of peak RSS against cells (least squares), the per-size peaks are in the case's fields. What
  grows is what the sweep must hold: each cell's resolved config and key, and each finished
  cell's small summary (its runs' metrics).

The machine is shared (other processes load the cores), so the numbers are what this run saw.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from slamkit.bench.cases import BenchCase, compare

#: the module that registers the no-op pipeline (a sweep plugin: imported in every worker)
NOOP_PLUGIN = "slamkit.bench._noop_pipeline"


def _timed_sweep(path: Path, out: Path, **kwargs) -> tuple[float, dict]:
    from slamkit.experiments.sweep import run_sweep

    t0 = time.perf_counter()
    result = run_sweep(path, out, progress=False, **kwargs)
    return time.perf_counter() - t0, result.results


def _filter_sweep(tmp: Path, cells: int) -> Path:
    # JSON is YAML: this layer writes its sweep files without a YAML library
    (tmp / "fvs.yaml").write_text(json.dumps({
        "pipeline": "filter_vs_smoother", "workers": 1, "record": False, "seeds": 1,
        "scenarios": [{"preset": "mild", "params": {"duration_s": 10.0}}], "estimators": {"ekf": {}}}))
    path = tmp / "filters.yaml"
    path.write_text(json.dumps({"pipeline": "fvs.yaml", "seeds": cells}))
    return path


def _noop_sweep(tmp: Path, cells: int) -> Path:
    path = tmp / f"noop{cells}.yaml"
    path.write_text(json.dumps({"pipeline": {"pipeline": "bench_noop"}, "plugins": [NOOP_PLUGIN],
                                    "axes": {"x": list(range(cells))}}))
    return path


def _per_cell_ms(tmp: Path, tag: str, executor, warm: int, cells: int) -> float:
    """Wall time per cell of a sweep of ``cells`` no-op cells on ``executor`` once its workers
    have started (a first sweep of ``warm`` cells starts them)."""
    _timed_sweep(_noop_sweep(tmp, warm), tmp / f"{tag}_warm", executor=executor)
    t, _ = _timed_sweep(_noop_sweep(tmp, cells), tmp / f"{tag}_timed", executor=executor)
    return 1e3 * t / cells


def _utilisation(results: dict, workers: int, wall_s: float) -> float:
    """The fraction of the workers' time spent inside cells (1: the sweep layer costs nothing)."""
    return sum(c["wall_s"] or 0.0 for c in results["cells"]) / (workers * wall_s)


def _coordinator_peak_rss_mb(tmp: Path, cells: int) -> float:
    """Peak RSS (MB) of a fresh coordinator process running a no-op sweep of ``cells`` cells on 2
    local workers (ru_maxrss of the process itself: the workers are its children)."""
    path = _noop_sweep(tmp, cells)
    code = ("import resource, sys, importlib\n"
            f"importlib.import_module({NOOP_PLUGIN!r})\n"
            "from slamkit.experiments.sweep import run_sweep\n"
            "if __name__ == '__main__':\n"
            "    run_sweep(sys.argv[1], sys.argv[2], workers=2, progress=False)\n"
            "    print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)\n")
    done = subprocess.run([sys.executable, "-c", code, str(path), str(tmp / f"rss{cells}")],
                          capture_output=True, text=True, check=True)
    return float(done.stdout.split()[-1])


def run(quick: bool = False) -> list[BenchCase]:
    from slamkit.experiments.executors import LocalExecutor

    import importlib

    importlib.import_module(NOOP_PLUGIN)
    cells = 40 if quick else 200
    warm, noop_cells = (10, 40) if quick else (20, 200)
    cases = []
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        sweep = _filter_sweep(tmp, cells)
        t1, r1 = _timed_sweep(sweep, tmp / "w1", workers=1)
        t2, r2 = _timed_sweep(sweep, tmp / "w2", workers=2)
        rss = max(c["worker_max_rss_mb"] or 0.0 for c in r2["cells"])
        cases.append(compare("sweep_filter_cells_2_workers", t2, "s", "the same sweep on 1 worker", t1,
                             goal=">= 1.6 (efficiency >= 80%)", cells=cells, efficiency=t1 / (2 * t2),
                             utilisation_1_worker=_utilisation(r1, 1, t1),
                             utilisation_2_workers=_utilisation(r2, 2, t2), worker_max_rss_mb=rss))
        with LocalExecutor(2) as ex:
            local_ms = _per_cell_ms(tmp, "local", ex, warm, noop_cells)
        sizes = (100, 300, 1000) if quick else (100, 1000, 3000, 10000)
        peaks = [_coordinator_peak_rss_mb(tmp, n) for n in sizes]
        slope = 1000.0 * float(np.polyfit(sizes, peaks, 1)[0])
        cases.append(BenchCase("sweep_coordinator_rss_mb_per_1000_cells", slope, "MB",
                               extra={f"peak_rss_mb_{n}_cells": p for n, p in zip(sizes, peaks)}))
        try:
            import ray  # noqa: F401 - only whether it is installed
        except ImportError:
            cases.append(BenchCase("sweep_noop_cell_local_ms", local_ms, "ms"))
            return cases
        from slamkit.experiments.executors import RayExecutor, start_local_ray

        instance = start_local_ray(num_cpus=2)
        try:
            with RayExecutor() as ex:
                ray_ms = _per_cell_ms(tmp, "ray", ex, warm, noop_cells)
        finally:
            instance.shutdown()
        cases.append(compare("sweep_noop_cell_local_ms", local_ms, "ms", "Ray, local instance, 2 CPUs", ray_ms))
    return cases
