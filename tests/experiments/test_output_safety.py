"""Never lose a user's files (issue 10): only folders slamkit wrote are replaced, names that
become paths are one plain component, a replaced result is reachable at every instant (also when
the process is killed at any step), concurrent runs are refused clearly, files respect the umask."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from slamkit.data.formats.sequence import save_sequence
from slamkit.data.formats.tum import write_tum
from slamkit.data.sequence import Odometry, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError, OutputError
from slamkit.experiments import pipeline as pipeline_mod
from slamkit.experiments import results as results_mod
from slamkit.experiments.pipeline import PipelineOutput, run_pipeline
from slamkit.experiments.results import MARKER, ResultsFolder, RunRecord
from slamkit.paths import path_component

ROOT = Path(__file__).resolve().parents[2]


def _toy(config, folder, progress, observer):
    value = config.model_extra.get("value", 1.0)  # registered without a model: its keys are extras
    return PipelineOutput([RunRecord("toy", "est", {"ate_rmse_m": float(value)})], f"# toy {value}\n")


@pytest.fixture
def toy():
    pipeline_mod.register_pipeline(pipeline_mod.Pipeline("toy", _toy))
    yield
    pipeline_mod.PIPELINES.unregister("toy")


def _value(out: Path) -> float:
    return json.loads((out / "results.json").read_text())["runs"][0]["metrics"]["ate_rmse_m"]


def test_a_folder_of_someone_elses_files_is_refused_and_untouched(tmp_path, toy) -> None:
    out = tmp_path / "thesis"
    out.mkdir()
    (out / "chapter1.tex").write_text("years of work")
    with pytest.raises(OutputError, match=r"thesis exists and is not a slamkit results folder \(no "
                                          r"\.slamkit-results marker\); slamkit only replaces folders it wrote"):
        run_pipeline({"pipeline": "toy"}, out, progress=False)
    assert [p.name for p in out.iterdir()] == ["chapter1.tex"]
    assert (out / "chapter1.tex").read_text() == "years of work"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thesis"]  # no lock or partial left


def test_optimize_out_on_a_foreign_folder_is_refused(tmp_path) -> None:
    from slamkit.experiments.pose_graph import optimize_source

    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep")
    with pytest.raises(OutputError, match="is not a slamkit results folder"):
        optimize_source("ring", out=out)
    assert (out / "notes.txt").read_text() == "keep"


def test_a_regular_file_is_refused_and_untouched(tmp_path, toy) -> None:
    out = tmp_path / "data.csv"
    out.write_text("1,2,3\n")
    with pytest.raises(OutputError, match=r"data\.csv is a file, not a results folder; slamkit will not replace it"):
        run_pipeline({"pipeline": "toy"}, out, progress=False)
    assert out.read_text() == "1,2,3\n"


def test_a_symlink_is_refused(tmp_path, toy) -> None:
    target = tmp_path / "elsewhere"
    target.mkdir()
    (tmp_path / "link").symlink_to(target)
    with pytest.raises(OutputError, match="is a symbolic link"):
        run_pipeline({"pipeline": "toy"}, tmp_path / "link", progress=False)


def test_an_empty_folder_and_an_earlier_result_are_replaced(tmp_path, toy) -> None:
    out = tmp_path / "r"
    out.mkdir()
    run_pipeline({"pipeline": "toy", "value": 1.0}, out, progress=False)
    assert _value(out) == 1.0
    # issue 31: replacing an earlier result needs overwrite (slamkit run --overwrite)
    with pytest.raises(OutputError, match=r"r holds a result of 'toy' already; pass --overwrite to replace it"):
        run_pipeline({"pipeline": "toy", "value": 2.0}, out, progress=False)
    assert _value(out) == 1.0
    run_pipeline({"pipeline": "toy", "value": 2.0}, out, progress=False, overwrite=True)
    assert _value(out) == 2.0
    assert json.loads((out / MARKER).read_text()) == {
        "slamkit_version": __import__("slamkit").__version__, "pipeline": "toy", "complete": True}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


@pytest.mark.parametrize("name, problem", [
    ("../x", "it contains a path separator"),
    ("/some/folder", "it contains a path separator"),
    ("..", "it is empty or a relative folder reference"),
    (".hidden", "it starts with '.'"),
    ("a\x00b", "it contains a control character"),
])
def test_a_config_name_that_is_not_one_component_is_refused(tmp_path, toy, monkeypatch, name, problem) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError, match=f"name: Value error, name .* cannot be used as a file name: {problem}"):
        run_pipeline({"pipeline": "toy", "name": name}, None, progress=False)
    assert list(tmp_path.iterdir()) == []


def test_default_out_is_runs_slash_name(tmp_path, toy, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    result = run_pipeline({"pipeline": "toy", "name": "nightly"}, None, progress=False)
    assert result.out_dir == tmp_path / "runs" / "nightly"


def test_scenario_names_and_estimator_labels_must_be_plain(tmp_path) -> None:
    from slamkit.experiments.filter_vs_smoother import estimators_of, scenarios_of
    from slamkit.sim.scenario import scenario_from_dict

    with pytest.raises(ConfigError, match=r"scenarios\[0\]: name '\.\./\.\./x/scen' cannot be used as a file name"):
        scenarios_of([{"preset": "mild", "name": "../../x/scen"}])
    with pytest.raises(ConfigError, match=r"estimator label '\.\./\.\./x/est' cannot be used as a file name"):
        estimators_of({"../../x/est": {"type": "ekf"}})
    with pytest.raises(ConfigError, match=r"office.yaml: name '\.\./\.\./x/scen' cannot be used"):
        scenario_from_dict({"kind": "grid", "name": "../../x/scen"}, "office.yaml")


def test_path_component_accepts_plain_names() -> None:
    assert path_component("office_tour-2", "name") == "office_tour-2"
    with pytest.raises(ConfigError, match="must be a string"):
        path_component(5, "name")


def test_a_second_run_into_the_same_folder_is_refused_while_the_first_runs(tmp_path) -> None:
    first = ResultsFolder(tmp_path / "r", pipeline="toy")
    try:
        with pytest.raises(OutputError, match=r"another slamkit run is writing .*r \(it holds .*\.r\.lock\)"):
            ResultsFolder(tmp_path / "r", pipeline="toy")
    finally:
        first.discard()
    ResultsFolder(tmp_path / "r").discard()  # free again once the first has finished
    assert list(tmp_path.iterdir()) == []


def test_files_respect_the_umask(tmp_path) -> None:
    traj = Trajectory.from_se2(np.array([0.0, 1.0]), np.zeros((2, 3)))
    old = os.umask(0o022)
    try:
        path = write_tum(tmp_path / "a.tum", traj)
        assert path.stat().st_mode & 0o777 == 0o644
        os.umask(0o077)
        assert write_tum(tmp_path / "b.tum", traj).stat().st_mode & 0o777 == 0o600
    finally:
        os.umask(old)


def test_single_file_outputs_never_replace_someone_elses_file(tmp_path) -> None:
    from slamkit.viz.recording import Recording

    seq = Sequence.from_events("s", [Odometry(0.0, 1.0, 0.0, 0.1)])
    foreign = tmp_path / "thesis.slamseq"
    foreign.write_text("not a sequence")
    with pytest.raises(OutputError, match="thesis.slamseq exists and is not a sequence file slamkit wrote"):
        save_sequence(foreign, seq)
    assert foreign.read_text() == "not a sequence"
    ours = save_sequence(tmp_path / "ok.slamseq", seq)
    assert save_sequence(ours, seq) == ours  # its own file may be replaced
    rrd = tmp_path / "paper.rrd"
    rrd.write_text("draft")
    with pytest.raises(OutputError, match="paper.rrd exists and is not a recording slamkit wrote"):
        Recording("t", path=rrd)
    assert rrd.read_text() == "draft"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok.slamseq", "paper.rrd", "thesis.slamseq"]


def test_spawn_without_a_display_is_a_clear_error(monkeypatch, tmp_path) -> None:
    from slamkit.viz.recording import Recording

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    # and points to what works headless (issue 32: it pointed to `rerun FILE`, which fails there too)
    with pytest.raises(OutputError, match=r"--spawn needs a display.*`slamkit view RUN_FOLDER`"):
        Recording("t", path=tmp_path / "x.rrd", spawn=True)
    assert list(tmp_path.iterdir()) == []


# --- kill -9 at every step ---------------------------------------------------------------------

_KILLER = textwrap.dedent("""
    import os, signal, sys, json
    from pathlib import Path
    from slamkit.experiments import results as R

    out, stage = Path(sys.argv[1]), sys.argv[2]
    die = lambda: os.kill(os.getpid(), signal.SIGKILL)
    if stage == "between_renames":
        R._EXCHANGE = None
        real = R.os.replace
        calls = []
        def replace(a, b):
            calls.append(1)
            if len(calls) == 2:
                die()
            real(a, b)
        R.os.replace = replace
    elif stage == "after_swap":
        real_ex = R._EXCHANGE
        def ex(a, b):
            ok = real_ex(a, b)
            die()
        R._EXCHANGE = ex
    elif stage == "before_swap":
        R._fsync_tree = lambda root: die()
    folder = R.ResultsFolder(out, pipeline="toy", overwrite=True)
    (folder.path / "report.md").write_text("# new")
    if stage == "assembling":
        die()
    folder.commit("toy", [R.RunRecord("d", "e", {"ate_rmse_m": 2.0})], "# new")
""")


@pytest.mark.parametrize("stage", ["assembling", "before_swap", "between_renames", "after_swap"])
def test_a_kill_at_any_step_leaves_a_complete_result_and_the_next_run_cleans_up(tmp_path, stage) -> None:
    out = tmp_path / "r"
    with ResultsFolder(out, pipeline="toy") as folder:
        folder.commit("toy", [RunRecord("d", "e", {"ate_rmse_m": 1.0})], "# old")
    script = tmp_path.parent / f"killer_{stage}.py"
    script.write_text(_KILLER)
    done = subprocess.run([sys.executable, str(script), str(out), stage], cwd=ROOT, capture_output=True)
    assert done.returncode == -9, done.stderr.decode()
    # at every instant <out> is a complete result: the old one, or the new one after the swap
    expected = 2.0 if stage == "after_swap" else 1.0
    if stage == "between_renames":
        assert not out.exists()  # the fallback's window; the next run repairs it (below)
    else:
        assert _value(out) == expected and json.loads((out / MARKER).read_text())["complete"]
    leftovers = sorted(p.name for p in tmp_path.iterdir() if p.name != "r")
    assert leftovers and all(n.startswith(".r.") for n in leftovers)
    # the next run into the folder cleans the leftovers (and first restores a renamed-aside result)
    folder = ResultsFolder(out, pipeline="toy", overwrite=True)
    if stage == "between_renames":
        assert _value(out) == 1.0
    folder.commit("toy", [RunRecord("d", "e", {"ate_rmse_m": 3.0})], "# next")
    assert _value(out) == 3.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


def test_concurrent_runs_into_one_folder_never_crash(tmp_path) -> None:
    script = tmp_path.parent / "writer.py"
    script.write_text(textwrap.dedent("""
        import sys
        from slamkit.errors import OutputError
        from slamkit.experiments.results import ResultsFolder, RunRecord
        outcomes = []
        for k in range(15):
            try:
                with ResultsFolder(sys.argv[1], pipeline="toy", overwrite=True) as f:
                    f.commit("toy", [RunRecord("d", "e", {"ate_rmse_m": float(k)})], "# r")
                outcomes.append("ok")
            except OutputError as exc:
                assert "another slamkit run is writing" in str(exc), exc
                outcomes.append("refused")
        print(" ".join(outcomes))
    """))
    procs = [subprocess.Popen([sys.executable, str(script), str(tmp_path / "r")], cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE) for _ in range(2)]
    outputs = [p.communicate(timeout=120) for p in procs]
    for proc, (stdout, stderr) in zip(procs, outputs):
        assert proc.returncode == 0, stderr.decode()
        assert set(stdout.split()) <= {b"ok", b"refused"} and len(stdout.split()) == 15
    assert json.loads((tmp_path / "r" / MARKER).read_text())["complete"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


def test_atomic_file_keeps_the_old_content_until_the_new_file_is_whole(tmp_path) -> None:
    from slamkit.paths import atomic_file

    target = tmp_path / "results.json"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_file(target) as tmp:
            tmp.write_text("half")
            assert target.read_text() == "old"
            raise RuntimeError("killed mid-write")
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["results.json"]
    with atomic_file(target) as tmp:
        tmp.write_text("new")
    assert target.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["results.json"]
