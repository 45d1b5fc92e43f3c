"""Sweeps (issue 17): cells from axes, validated up front, stored under a key of their resolved
config, run on an executor, resumable after kill -9, aggregated per axis value.

The cells run the ``sweep_probe`` pipeline (tests/experiments/sweep_probe.py, a sweep plugin):
``value_m = 2 x + seed / 10``, so every aggregate has a worked value."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from slamkit.errors import ConfigError, OutputError
from slamkit.experiments.executors import LocalExecutor
from slamkit.experiments.pipeline import PIPELINES
from slamkit.experiments.results import MARKER
from slamkit.experiments.sweep import cell_path, cell_state, config_key, load_sweep, run_sweep, set_path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
# Student t, 2 degrees of freedom, 97.5%: the 95% CI half-width over seeds 0, 1, 2 is
# T2 * 0.1 / sqrt(3) (their values differ by 0.1)
T2 = 4.302652729911275


@pytest.fixture(scope="module", autouse=True)
def _probe_registered():
    import sweep_probe

    sweep_probe.ensure_registered()
    yield
    if "sweep_probe" in PIPELINES:
        PIPELINES.unregister("sweep_probe")


def write_sweep(folder: Path, **fields) -> Path:
    doc = {"pipeline": {"pipeline": "sweep_probe", "x": 0.0}, "plugins": ["sweep_probe"], **fields}
    path = folder / "sweep.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


# --- cells ----------------------------------------------------------------------------------------

def test_set_path_walks_mappings_and_list_indices_and_wraps_scalars_for_list_fields() -> None:
    config = {"scenarios": [{"preset": "mild", "params": {}}], "datasets": ["intel", "m3500"]}
    set_path(config, "scenarios.0.params.duration_s", 10.0)
    set_path(config, "datasets", "fr079")
    set_path(config, "estimators.ekf.sigma_range_m", 0.1)
    assert config == {"scenarios": [{"preset": "mild", "params": {"duration_s": 10.0}}], "datasets": ["fr079"],
                      "estimators": {"ekf": {"sigma_range_m": 0.1}}}
    with pytest.raises(ConfigError, match=r"axes.scenarios.3.preset: scenarios is a list of 1; '3' is not an index"):
        set_path(config, "scenarios.3.preset", "strong")
    with pytest.raises(ConfigError, match=r"axes.datasets.0.x: datasets.0 is fr079, not a mapping or list"):
        set_path(config, "datasets.0.x", 1)


def test_a_grid_crosses_every_axis_and_the_seeds(tmp_path: Path) -> None:
    sweep = load_sweep(write_sweep(tmp_path, seeds={"start": 5, "count": 2},
                                   axes={"x": [1.0, 2.0, 3.0], "dataset": ["a", "b"]}))
    assert len(sweep.cells) == 3 * 2 * 2
    assert sweep.cells[0].axes == {"x": 1.0, "dataset": "a", "seed": 5}
    # the resolved config: the common fields' defaults spelt out (issue 30)
    assert sweep.cells[0].config == {"pipeline": "sweep_probe", "x": 1.0, "name": "sweep", "dataset": "a",
                                     "seeds": [5], "record": True, "plugins": []}
    assert len({c.key for c in sweep.cells}) == 12
    assert all(c.key == config_key(c.config) and len(c.key) == 16 for c in sweep.cells)
    zipped = load_sweep(write_sweep(tmp_path, mode="zip", axes={"x": [1.0, 2.0], "dataset": ["a", "b"]}))
    assert [c.axes for c in zipped.cells] == [{"x": 1.0, "dataset": "a"}, {"x": 2.0, "dataset": "b"}]


def test_the_key_is_the_resolved_config_so_axis_order_and_spelling_do_not_matter(tmp_path: Path) -> None:
    a = load_sweep(write_sweep(tmp_path, axes={"x": [1.0], "dataset": ["a"]})).cells[0]
    b = load_sweep(write_sweep(tmp_path, axes={"dataset": ["a"], "x": [1.0]})).cells[0]
    assert a.key == b.key


@pytest.mark.parametrize("fields, message", [
    ({"axis": {"x": [1]}}, r"sweep.yaml:\d+: axis: unknown key \(did you mean 'axes'\?\)"),
    ({"axes": {"x..y": [1]}}, r"axes.x..y.\[key\]: String should match pattern"),
    ({"axes": {"x": []}}, r"axes.x: List should have at least 1 item"),
    ({"axes": {"seeds": [1, 2]}}, r"vary the seed with the top-level 'seeds:'"),
    ({"mode": "zip", "axes": {"x": [1, 2], "dataset": ["a"]}}, r"mode zip needs lists of one length, got x: 2, dataset: 1"),
    ({"axes": {"x": [1.0, 1.0]}}, r"cells x=1.0 and x=1.0 resolve to the same config"),
    ({"seeds": 0}, r"seeds: Input should be greater than or equal to 1"),
    ({"plugins": ["no_such_module_here"]}, r"plugins: plug-in module 'no_such_module_here' cannot be imported"),
])
def test_a_bad_sweep_is_refused_naming_the_field(tmp_path: Path, fields, message) -> None:
    with pytest.raises(ConfigError, match=message):
        load_sweep(write_sweep(tmp_path, **fields))


def test_every_cell_is_validated_by_its_pipeline_before_anything_runs(tmp_path: Path) -> None:
    (tmp_path / "fvs.yaml").write_text(yaml.safe_dump({
        "pipeline": "filter_vs_smoother", "scenarios": [{"preset": "mild", "params": {"duration_s": 5.0}}],
        "estimators": {"ekf": {}}}))
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"pipeline": "fvs.yaml", "axes": {"scenarios.0.params.duration_ss": [1.0]}}))
    with pytest.raises(ConfigError, match=r"s.yaml: cell scenarios.0.params.duration_ss=1.0: "
                                          r"scenarios.0.params.duration_ss: unknown key \(did you mean 'duration_s'\?\)"):
        load_sweep(path)
    path.write_text(yaml.safe_dump({"pipeline": "fvs.yaml", "axes": {"estimators.ekf.sigma_range_m": [0.1, -1.0]}}))
    with pytest.raises(ConfigError, match=r"cell estimators.ekf.sigma_range_m=-1.0: .*estimators.ekf.sigma_range_m: "
                                          r"Input should be greater than 0"):
        load_sweep(path)
    path.write_text(yaml.safe_dump({"pipeline": "fvs.yaml", "seeds": 2,
                                    "axes": {"estimators.ekf.sigma_range_m": [0.1, 0.2]}}))
    sweep = load_sweep(path)
    assert [c.config["estimators"]["ekf"] for c in sweep.cells] == [{"sigma_range_m": 0.1}] * 2 + [{"sigma_range_m": 0.2}] * 2
    assert [c.config["seeds"] for c in sweep.cells] == [[0], [1], [0], [1]]


# --- running, failures, aggregation ------------------------------------------------------------------

def test_a_sweep_runs_every_cell_records_failures_and_aggregates_per_axis_value(tmp_path: Path) -> None:
    sweep = write_sweep(tmp_path, seeds=3, axes={"x": [1.0, 2.0], "fail": [False, True]})
    result = run_sweep(sweep, tmp_path / "out", workers=2, progress=False)
    assert (result.ran, result.failed) == (12, 6)
    res = result.results
    assert res["pipeline"] == "sweep" and res["base_pipeline"] == "sweep_probe"
    assert res["axes"] == {"x": [1.0, 2.0], "fail": [False, True], "seed": [0, 1, 2]}
    assert [c["status"] for c in res["cells"]].count("failed") == 6
    failed = [c for c in res["cells"] if c["status"] == "failed"]
    assert all(c["axes"]["fail"] and "RuntimeError: probe asked to fail at x=" in c["error"] for c in failed)
    assert len(res["runs"]) == 6 and all(r["cell"] and "axes" in r for r in res["runs"])
    rows = {(s["axis"], json.dumps(s["value"])): s for s in res["summary"]}
    half = T2 * 0.1 / math.sqrt(3)
    for x in (1.0, 2.0):
        row = rows[("x", json.dumps(x))]
        assert row["metric"] == "value_m" and row["n"] == 3
        assert row["mean"] == pytest.approx(2 * x + 0.1)
        assert row["ci95"] == pytest.approx([2 * x + 0.1 - half, 2 * x + 0.1 + half])
    assert ("fail", "true") not in rows  # no run of a failed cell
    assert res["overall"][0]["mean"] == pytest.approx(3.1) and res["overall"][0]["n"] == 6
    out = result.out_dir
    assert sorted(p.name for p in (out / "plots").iterdir()) == ["value_m_vs_fail.png", "value_m_vs_x.png"]
    report = (out / "report.md").read_text()
    assert "12 cells (grid over x, fail, seed): 6 done, 6 failed, 0 not run" in report
    assert "| 1.0 | probe | probe | 2.1 ± 0.25 |" in report and "## Failed cells" in report
    cells = list((out / "cells").glob("*/*"))
    assert len(cells) == 12 and all(p.parent.name == p.name[:2] for p in cells)
    error = json.loads((cell_path(out / "cells", failed[0]["key"]) / "error.json").read_text())
    assert error["error_type"] == "RuntimeError" and "Traceback" in error["traceback"]
    assert json.loads((out / MARKER).read_text())["complete"] is True
    assert json.loads((out / "results.json").read_text())["summary"] == res["summary"]


def test_axis_values_are_compared_paired_on_the_seed(tmp_path: Path) -> None:
    # value_m = 2 x + seed / 10: on every seed x = 2 exceeds x = 1 by exactly 2, for each dataset;
    # six seeds all of one sign give the exact two-sided Wilcoxon p = 2 / 2^6
    sweep = write_sweep(tmp_path, seeds=6, axes={"x": [1.0, 2.0], "dataset": ["a", "b"]})
    result = run_sweep(sweep, tmp_path / "out", workers=2, progress=False)
    axes = result.results["paired"]["axes"]
    x_rows = [r for r in axes if r["axis"] == "x"]
    assert sorted(r["dataset"] for r in x_rows) == ["a", "b"]
    for r in x_rows:
        assert (r["treatment"], r["best"], r["pairs"]) == (2.0, 1.0, 6)
        assert r["mean_difference"] == pytest.approx(2.0) and r["ci95"] == pytest.approx([2.0, 2.0])
        assert r["wilcoxon_p"] == pytest.approx(2 / 64) and r["significant"]
    # values of the dataset axis run on different data: never paired with each other
    assert {r["axis"] for r in axes} == {"x"}
    assert result.results["paired"]["estimators"] == []  # one estimator: nothing to pair
    report = (result.out_dir / "report.md").read_text()
    assert "## Paired: axis values against the best value" in report and "### x" in report
    assert "| a | probe | value_m | 2 | 1 | 6 | 2 | [2, 2] | 0.03125 | **yes** |" in report


def test_a_list_valued_axis_runs_and_is_summarised_and_paired_by_its_value(tmp_path: Path) -> None:
    # issue 31: a list as an axis value (``counts: [[0, 5], [0, 10]]``, ``solvers: [[lm]]``) ran every
    # cell, then failed with "unhashable type: 'list'" and wrote no results.json.
    # value_m = 2 x + sum(offsets) + seed / 10: offsets [0, 3] exceed [0, 1] by 2 on every seed and x
    sweep = write_sweep(tmp_path, seeds=6, axes={"x": [1.0, 2.0], "offsets": [[0, 1], [0, 3]]})
    result = run_sweep(sweep, tmp_path / "out", workers=2, progress=False)
    assert (result.ran, result.failed) == (24, 0)
    saved = json.loads((result.out_dir / "results.json").read_text())
    assert saved["axes"]["offsets"] == [[0, 1], [0, 3]]
    rows = {json.dumps(s["value"]): s for s in saved["summary"] if s["axis"] == "offsets"}
    assert rows["[0, 1]"]["mean"] == pytest.approx(2 * 1.5 + 1 + 0.25) and rows["[0, 1]"]["n"] == 12
    assert rows["[0, 3]"]["mean"] == pytest.approx(2 * 1.5 + 3 + 0.25) and rows["[0, 3]"]["n"] == 12
    paired = saved["paired"]["axes"]
    offsets = [r for r in paired if r["axis"] == "offsets"]
    assert sorted(r["x"] for r in offsets) == [1.0, 2.0]
    for r in offsets:
        assert (r["treatment"], r["best"], r["pairs"]) == ([0, 3], [0, 1], 6)
        assert r["mean_difference"] == pytest.approx(2.0) and r["wilcoxon_p"] == pytest.approx(2 / 64)
    # the list axis is also part of the other axis' pairing context
    xs = [r for r in paired if r["axis"] == "x"]
    assert sorted(json.dumps(r["offsets"]) for r in xs) == ["[0, 1]", "[0, 3]"]
    assert all((r["treatment"], r["best"]) == (2.0, 1.0) for r in xs)
    report = (result.out_dir / "report.md").read_text()
    assert "| [0,1] | probe | probe | 4.25 ± " in report
    assert "| probe | probe | 1 | value_m | [0,3] | [0,1] | 6 | 2 | [2, 2] | 0.03125 | **yes** |" in report
    assert (result.out_dir / "plots" / "value_m_vs_offsets.png").is_file()


def test_resume_runs_only_unfinished_cells_and_retry_failed_only_failures(tmp_path: Path) -> None:
    log = tmp_path / "runs.log"
    sweep = write_sweep(tmp_path, pipeline={"pipeline": "sweep_probe", "log": str(log)},
                        seeds=2, axes={"fail": [False, True]})
    out = tmp_path / "out"
    assert run_sweep(sweep, out, workers=1, progress=False).ran == 4
    with pytest.raises(OutputError, match="holds a sweep already; continue it with --resume"):
        run_sweep(sweep, out, workers=1, progress=False)
    again = run_sweep(sweep, out, workers=1, resume=True, progress=False)
    assert (again.ran, again.failed) == (0, 0)
    assert [c["status"] for c in again.results["cells"]] == ["done", "done", "failed", "failed"]
    retried = run_sweep(sweep, out, workers=1, resume=True, retry_failed=True, progress=False)
    assert (retried.ran, retried.failed) == (2, 2)
    keys = [line.split()[0] for line in log.read_text().splitlines()]
    failing = {c["key"] for c in retried.results["cells"] if c["status"] == "failed"}
    assert sorted(keys.count(k) for k in set(keys)) == [1, 1, 2, 2] and {k for k in keys if keys.count(k) == 2} == failing
    # a grown sweep reuses the cells it shares with the old one
    grown = write_sweep(tmp_path, pipeline={"pipeline": "sweep_probe", "log": str(log)}, seeds=3,
                        axes={"fail": [False, True]})
    assert run_sweep(grown, out, workers=1, resume=True, progress=False).ran == 2


def test_the_sweep_folder_is_never_a_users_folder_or_a_pipeline_run(tmp_path: Path) -> None:
    sweep = write_sweep(tmp_path, axes={"x": [1.0]})
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    with pytest.raises(OutputError, match="not a slamkit results folder"):
        run_sweep(sweep, mine, progress=False, resume=True)
    from slamkit.experiments.pipeline import run_pipeline

    run = run_pipeline({"pipeline": "sweep_probe", "x": 1.0}, tmp_path / "run", progress=False).out_dir
    with pytest.raises(OutputError, match="holds a slamkit run of 'sweep_probe', not a sweep"):
        run_sweep(sweep, run, progress=False, resume=True)
    assert (mine / "notes.txt").read_text() == "keep" and sorted(p.name for p in mine.iterdir()) == ["notes.txt"]


def test_the_local_pool_pins_blas_threads_in_its_workers_and_yields_each_task_once() -> None:
    import sweep_probe

    before = os.environ.get("OPENBLAS_NUM_THREADS")
    with LocalExecutor(2) as ex:
        for x in (3, -1, 4, 5):
            ex.submit(sweep_probe.square, x)
        ex.submit(sweep_probe.worker_env, None)
        outcomes = dict(ex.as_completed())
    assert os.environ.get("OPENBLAS_NUM_THREADS") == before
    assert {k: outcomes[k] for k in (3, 4, 5)} == {3: 9, 4: 16, 5: 25}
    assert (outcomes[-1].error_type, outcomes[-1].message) == ("ValueError", "negative -1")
    assert set(outcomes[None].values()) == {"1"}


# --- kill -9 and resume -----------------------------------------------------------------------------

def test_a_sweep_killed_part_way_resumes_with_no_cell_lost_or_run_twice(tmp_path: Path) -> None:
    """SIGKILL to the sweep's coordinator while cells run: its workers exit by themselves; then
    --resume: every cell is complete, every cell that was complete at the kill ran exactly once,
    and only cells in flight at the kill (at most one per worker) ran twice."""
    log = tmp_path / "runs.log"
    n_cells, workers = 24, 2
    sweep = write_sweep(tmp_path, pipeline={"pipeline": "sweep_probe", "log": str(log), "sleep_s": 0.15},
                        seeds=n_cells // 2, axes={"x": [1.0, 2.0]})
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, "-c", "from slamkit.cli import main; main()", "sweep", str(sweep),
                             "--out", str(out), "--workers", str(workers), "--quiet"],
                            env=env, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if log.exists() and len(log.read_text().splitlines()) >= n_cells // 3:
            break
        time.sleep(0.05)
    assert proc.poll() is None, f"the sweep ended before the kill: {proc.stderr.read().decode()}"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    worker_pids = {int(line.split()[1]) for line in log.read_text().splitlines()}
    assert len(worker_pids) == workers
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and any(_alive(pid) for pid in worker_pids):
        time.sleep(0.05)
    assert not any(_alive(pid) for pid in worker_pids), "a worker outlived its killed coordinator"
    cells = load_sweep(sweep).cells
    complete_at_kill = {c.key for c in cells if cell_state(cell_path(out / "cells", c.key)) == "done"}
    assert 0 < len(complete_at_kill) < n_cells
    assert not (out / "results.json").exists()
    assert json.loads((out / MARKER).read_text())["complete"] is False

    result = run_sweep(sweep, out, workers=workers, resume=True, progress=False)
    assert result.ran == n_cells - len(complete_at_kill) and result.failed == 0
    keys = [line.split()[0] for line in log.read_text().splitlines()]
    counts = {c.key: keys.count(c.key) for c in cells}
    assert all(counts[k] == 1 for k in complete_at_kill)
    assert min(counts.values()) == 1 and max(counts.values()) <= 2
    assert sum(n == 2 for n in counts.values()) <= workers
    assert len(result.results["runs"]) == n_cells
    assert all(cell_state(cell_path(out / "cells", c.key)) == "done" for c in cells)
    # no leftovers of the killed cells remain visible: hidden partials were cleaned by their rerun
    assert sorted(p.name for p in (out / "cells").glob("*/*") if not p.name.startswith(".")) == sorted(counts)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


# --- command line ----------------------------------------------------------------------------------

def test_the_cli_runs_a_sweep_and_refuses_a_bad_executor(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from slamkit.cli import app

    sweep = write_sweep(tmp_path, axes={"x": [1.0, 2.0]})
    runner = CliRunner()
    done = runner.invoke(app, ["sweep", str(sweep), "--out", str(tmp_path / "o"), "--workers", "1"])
    assert done.exit_code == 0, done.output
    assert "2 cells run (0 failed)" in done.output and "| 2.0 | probe | probe | 4 |" in done.output
    bad = runner.invoke(app, ["sweep", str(sweep), "--out", str(tmp_path / "o2"), "--executor", "slurm"])
    assert bad.exit_code == 2 and "unknown executor 'slurm'; known: local, ray" in bad.output


def test_importing_the_sweep_layer_does_not_import_ray() -> None:
    code = "import sys, slamkit.experiments.sweep, slamkit.cli; print('ray' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_the_shipped_sweep_validates_into_its_cells() -> None:
    sweep = load_sweep(ROOT / "pipelines" / "sweeps" / "ekf_noise.yaml")
    assert len(sweep.cells) == 3 * 2 * 20 and sweep.axis_names == [
        "estimators.ekf.sigma_range_m", "scenarios.0.params.duration_s", "seed"]
    assert sweep.cells[-1].config["estimators"] == {"ekf": {"sigma_range_m": 0.2}}
    # the preset's params spelt out (issue 30: the cell runs on and is keyed by its resolved
    # config), the swept duration as set, every other field at the mild preset's value
    from slamkit.config import resolved
    from slamkit.sim.landmark_world import PRESETS, LandmarkScenario

    assert sweep.cells[-1].config["scenarios"][0]["params"] == resolved(
        LandmarkScenario, {"duration_s": 20.0}, base=PRESETS["mild"](), exclude=("name",))
    assert sweep.cells[-1].config["scenarios"][0]["params"]["duration_s"] == 20.0
