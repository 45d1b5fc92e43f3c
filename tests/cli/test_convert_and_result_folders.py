"""Issue 31 at the CLI: ``data convert`` of stamps past a ROS time's int32 seconds, ``--out`` under
a regular file, and a sweep folder that ``slamkit run --out`` must not replace. Real files in
tmp_path, exit codes and messages stated."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from slamkit.cli import app

runner = CliRunner()


def _run(*args: str):
    result = runner.invoke(app, [str(a) for a in args])
    assert "Traceback" not in result.output
    return result


def _log(path: Path, *stamps: float) -> Path:
    path.write_text("".join(f"FLASER 3 1.0 2.0 3.0 {0.1 * k} 0 0 {0.1 * k} 0 0 {t!r} host {t!r}\n"
                            for k, t in enumerate(stamps)))
    return path


def test_convert_keeps_stamps_up_to_the_last_int32_second(tmp_path) -> None:
    from slamkit.data.formats.rosbag import read_bag

    log = _log(tmp_path / "late.clf", 2147483646.5, 2147483647.25)
    result = _run("data", "convert", log, tmp_path / "late")
    assert result.exit_code == 0, result.output
    assert [e.stamp_s for e in read_bag(tmp_path / "late").events] == [2147483646.5, 2147483647.25, 2147483647.25]


@pytest.mark.parametrize("out", ["bag2", "bag1.bag"])
def test_convert_refuses_stamps_from_2_to_the_31_seconds_cleanly(tmp_path, out) -> None:
    # before: exit 1, "internal error: 'i' format requires -2147483648 <= number <= 2147483647"
    log = _log(tmp_path / "y2038.clf", 2147483647.5, 2147483648.5)
    result = _run("data", "convert", log, tmp_path / out)
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines() == [
        "error: a stamp of 2147483648.5 s does not fit a ROS time, whose seconds are a signed 32-bit "
        "integer (-2147483648 .. 2147483647 s, up to 2038-01-19)"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["y2038.clf"]  # nothing written, no temporary left


# --- results folders -------------------------------------------------------------------------------

_PIPELINE = {"pipeline": "pose_graph", "name": "pg", "datasets": ["intel"], "solvers": ["lm"], "inits": ["file"],
             "robust": "none", "record": False}


def _configs(tmp_path: Path) -> tuple[Path, Path]:
    import yaml

    run_cfg, sweep_cfg = tmp_path / "pg.yaml", tmp_path / "sweep.yaml"
    run_cfg.write_text(yaml.safe_dump(_PIPELINE))
    sweep_cfg.write_text(yaml.safe_dump({"pipeline": _PIPELINE, "axes": {"options.max_iterations": [50]}}))
    return run_cfg, sweep_cfg


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_out_under_a_regular_file_exits_2_with_one_line(tmp_path) -> None:
    # before: exit 1, "internal error: NotADirectoryError" (run, sweep) / FileExistsError (convert)
    run_cfg, sweep_cfg = _configs(tmp_path)
    (tmp_path / "file.txt").write_text("keep")
    log = _log(tmp_path / "ok.clf", 1.5, 2.5)
    for args, hint in (((["run", run_cfg, "--out"]), "choose another --out"),
                       ((["sweep", sweep_cfg, "--workers", "1", "--out"]), "choose another --out"),
                       ((["data", "convert", log]), "choose another output path")):
        for sub in ("file.txt/sub", "file.txt/a/b.bag"):
            result = _run(*args, tmp_path / sub)
            assert result.exit_code == 2, (args, result.output)
            assert result.output.strip().splitlines()[-1] == (
                f"error: {tmp_path / sub} cannot be created: {tmp_path / 'file.txt'} is a file, not a folder; {hint}")
    assert (tmp_path / "file.txt").read_text() == "keep"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt", "ok.clf", "pg.yaml", "sweep.yaml"]


def test_a_run_never_replaces_a_sweep_folder_but_replaces_its_own_kind(tmp_path) -> None:
    # before: `slamkit run --out SWEEP` replaced the whole sweep with one run, exit 0
    run_cfg, sweep_cfg = _configs(tmp_path)
    sweep = tmp_path / "sweep"
    assert _run("sweep", sweep_cfg, "--workers", "1", "--out", sweep).exit_code == 0
    before = _snapshot(sweep)
    assert '"pipeline": "sweep"' in before[".slamkit-results"].decode() and len(before) >= 5
    result = _run("run", run_cfg, "--out", sweep)
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines() == [
        f"error: {sweep} is a sweep folder (written by slamkit sweep); a run would replace the whole sweep: "
        "choose another --out"]
    assert _snapshot(sweep) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pg.yaml", "sweep", "sweep.yaml"]  # no lock, no partial
    assert _run("run", run_cfg, "--out", sweep, "--overwrite").exit_code == 2  # not even with --overwrite
    assert _snapshot(sweep) == before
    # `make run` (--overwrite): a second run into a folder a run of the same pipeline wrote replaces it
    runs = tmp_path / "runs"
    assert _run("run", run_cfg, "--out", runs).exit_code == 0
    (runs / "results.json").write_text("{}")
    assert _run("run", run_cfg, "--out", runs, "--overwrite").exit_code == 0
    assert json.loads((runs / "results.json").read_text())["pipeline"] == "pose_graph"


# --- issue 31: replacing a result needs --overwrite; a result of another kind is never replaced ----


def test_run_replaces_an_earlier_result_only_with_overwrite(tmp_path) -> None:
    run_cfg, _ = _configs(tmp_path)
    runs = tmp_path / "runs"
    assert _run("run", run_cfg, "--out", runs, "--quiet").exit_code == 0
    before = _snapshot(runs)
    result = _run("run", run_cfg, "--out", runs, "--quiet")
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines() == [
        f"error: {runs} holds a result of 'pose_graph' already; pass --overwrite to replace it, or choose another --out"]
    assert _snapshot(runs) == before
    assert _run("run", run_cfg, "--out", runs, "--quiet", "--overwrite").exit_code == 0
    assert json.loads((runs / "results.json").read_text())["pipeline"] == "pose_graph"


def test_a_result_of_another_pipeline_is_never_replaced(tmp_path) -> None:
    """A pose_graph run folder, then a filter_vs_smoother run aimed at it, with and without
    --overwrite: the pipeline kind recorded in the folder's marker decides."""
    import yaml

    run_cfg, _ = _configs(tmp_path)
    runs = tmp_path / "runs"
    assert _run("run", run_cfg, "--out", runs, "--quiet").exit_code == 0
    before = _snapshot(runs)
    other = tmp_path / "fvs.yaml"
    other.write_text(yaml.safe_dump({"pipeline": "filter_vs_smoother", "estimators": ["ekf"], "seeds": [0],
                                     "scenarios": [{"preset": "mild", "params": {"duration_s": 2.0}}],
                                     "record": False}))
    for extra in ([], ["--overwrite"]):
        result = _run("run", other, "--out", runs, "--quiet", *extra)
        assert result.exit_code == 2, result.output
        assert result.output.strip().splitlines() == [
            f"error: {runs} holds a result of 'pose_graph'; a 'filter_vs_smoother' result never replaces one of "
            "another kind: choose another --out"]
    assert _snapshot(runs) == before


def test_sweep_resumes_without_overwrite_and_starts_afresh_only_with_it(tmp_path) -> None:
    _, sweep_cfg = _configs(tmp_path)
    out = tmp_path / "sweep"
    assert _run("sweep", sweep_cfg, "--workers", "1", "--out", out, "--quiet").exit_code == 0
    before = _snapshot(out)
    result = _run("sweep", sweep_cfg, "--workers", "1", "--out", out, "--quiet")
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines() == [
        f"error: {out} holds a sweep already; continue it with --resume, replace it with --overwrite, or choose "
        "another --out"]
    assert _snapshot(out) == before
    # resuming the same sweep is not a replacement: no cell runs again, no --overwrite needed
    result = _run("sweep", sweep_cfg, "--workers", "1", "--out", out, "--resume")
    assert result.exit_code == 0 and "0 cells run (0 failed)" in result.output, result.output
    cells = sorted(str(p.relative_to(out)) for p in (out / "cells").rglob("results.json"))
    assert len(cells) == 1 and (out / cells[0]).read_bytes() == before[cells[0]]
    (out / "cells" / "stray.txt").write_text("from the earlier sweep")
    result = _run("sweep", sweep_cfg, "--workers", "1", "--out", out, "--overwrite")
    assert result.exit_code == 0 and "1 cells run (0 failed)" in result.output, result.output
    assert not (out / "cells" / "stray.txt").exists()  # the earlier sweep was cleared
    # a run folder is never taken over by a sweep, --overwrite or not
    run_cfg, _ = _configs(tmp_path)
    assert _run("run", run_cfg, "--out", tmp_path / "runs", "--quiet").exit_code == 0
    result = _run("sweep", sweep_cfg, "--workers", "1", "--out", tmp_path / "runs", "--overwrite")
    assert result.exit_code == 2 and "holds a slamkit run of 'pose_graph', not a sweep" in result.output


@pytest.mark.parametrize("out", ["bag2", "bag1.bag"])
def test_convert_replaces_a_bag_only_with_overwrite(tmp_path, out) -> None:
    from slamkit.data.formats.rosbag import read_bag

    log = _log(tmp_path / "a.clf", 1.5, 2.5)
    assert _run("data", "convert", log, tmp_path / out).exit_code == 0
    result = _run("data", "convert", _log(tmp_path / "b.clf", 1.5, 2.5, 3.5), tmp_path / out)
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines() == [
        f"error: {tmp_path / out} exists; a bag is only written to a new path (pass --overwrite to replace an "
        "earlier bag)"]
    assert len(read_bag(tmp_path / out).events) == 3  # 2 scans and 1 odometry: untouched
    assert _run("data", "convert", tmp_path / "b.clf", tmp_path / out, "--overwrite").exit_code == 0
    assert len(read_bag(tmp_path / out).events) == 5
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.clf", "b.clf", out]  # nothing left aside
    # --overwrite replaces only a bag of the same kind: not a folder of someone's files, not a ROS 2
    # bag folder that happens to be called *.bag
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "n.txt").write_text("keep")
    result = _run("data", "convert", log, tmp_path / "notes", "--overwrite")
    assert result.exit_code == 2 and "notes exists and is not a ROS 2 bag; --overwrite replaces only a bag" in result.output
    assert (tmp_path / "notes" / "n.txt").read_text() == "keep"
    if out == "bag2":
        (tmp_path / out).rename(tmp_path / "z.bag")
        before = _snapshot(tmp_path / "z.bag")
        result = _run("data", "convert", log, tmp_path / "z.bag", "--overwrite")
        assert result.exit_code == 2 and "z.bag exists and is not a ROS 1 bag" in result.output
        assert _snapshot(tmp_path / "z.bag") == before


def test_optimize_replaces_its_earlier_result_only_with_overwrite(tmp_path) -> None:
    out = tmp_path / "ring"
    assert _run("optimize", "ring", "--out", out, "--json").exit_code == 0
    before = _snapshot(out)
    result = _run("optimize", "ring", "--out", out, "--json")
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines() == [
        f"error: {out} holds a result of 'optimize' already; pass --overwrite to replace it, or choose another --out"]
    assert _snapshot(out) == before
    assert _run("optimize", "ring", "--out", out, "--json", "--overwrite").exit_code == 0
    assert json.loads((out / ".slamkit-results").read_text())["pipeline"] == "optimize"
