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
    # `make run`: a second run into a folder a run of the same pipeline wrote replaces it
    runs = tmp_path / "runs"
    assert _run("run", run_cfg, "--out", runs).exit_code == 0
    (runs / "results.json").write_text("{}")
    assert _run("run", run_cfg, "--out", runs).exit_code == 0
    assert json.loads((runs / "results.json").read_text())["pipeline"] == "pose_graph"
