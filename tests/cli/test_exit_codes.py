"""One error handler for every command (issue 10): no traceback for any input, documented exit
codes (0 done, 2 bad input, 3 no result, 1 internal error), ``--debug`` for the traceback,
non-finite options refused, a file on disk wins over a registry name of the same spelling."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from slamkit.cli import app
from slamkit.data import registry
from slamkit.errors import BackendError

runner = CliRunner()


def _run(*args: str):
    result = runner.invoke(app, list(args))
    assert "Traceback" not in result.output
    return result


def test_help_documents_the_exit_codes() -> None:
    out = " ".join(_run("--help").output.replace("│", " ").split())  # rich wraps and boxes the text
    assert "Exit codes: 0 done, 2 bad input" in out and "3 no result" in out and "1 internal error" in out


@pytest.mark.parametrize("args, message", [
    (["eval", "rpe", "--ref", "a", "--est", "b", "--delta", "nan"], "Invalid value for '--delta': must be a finite number, got nan"),
    (["eval", "rpe", "--ref", "a", "--est", "b", "--delta", "inf"], "Invalid value for '--delta': must be a finite number, got inf"),
    (["eval", "rpe", "--ref", "a", "--est", "b", "--delta", "0"], "Invalid value for '--delta': must be > 0, got 0"),
    (["eval", "ate", "--ref", "a", "--est", "b", "--max-diff", "-1"], "Invalid value for '--max-diff': must be >= 0, got -1"),
    (["optimize", "ring", "--robust-k", "nan"], "Invalid value for '--robust-k': must be a finite number, got nan"),
    (["plan", "den312d", "--start", "nan,1", "--goal", "2,2"], "--start must be finite, got 'nan,1'"),
    (["plan", "den312d", "--start", "1,1", "--goal", "2,2", "--inflate", "-0.5"], "Invalid value for '--inflate': must be >= 0, got -0.5"),
    (["plan", "den312d", "--start", "1,1", "--goal", "2,2", "--time-limit", "inf"], "Invalid value for '--time-limit': must be a finite number, got inf"),
])
def test_bad_numeric_options_exit_2_naming_the_option(args, message) -> None:
    result = _run(*args)
    assert result.exit_code == 2, result.output
    assert message in " ".join(result.output.split()).replace("│", "").replace("  ", " ") or message in result.output


def test_bad_input_is_one_line_and_exit_2(tmp_path) -> None:
    result = _run("optimize", str(tmp_path / "missing.g2o"))
    assert result.exit_code == 2
    assert result.output.strip().splitlines() == [
        f"error: {str(tmp_path / 'missing.g2o')!r} is neither an existing file nor a registry name (no dataset "
        f"named {str(tmp_path / 'missing.g2o')!r} in the registry; `slamkit data list --all` shows every name)"]


def test_no_path_prints_the_answer_and_exits_3() -> None:
    result = _run("plan", "den312d", "--start", "10,10", "--goal", "0.5,0.5", "--json")
    assert result.exit_code == 3
    assert json.loads(result.output)["status"] == "invalid_goal"
    same = _run("plan", "den312d", "--start", "10,10", "--goal", "10,10", "--json")
    assert same.exit_code == 0 and json.loads(same.output)["cost"] == 0.0


def test_a_failed_solve_exits_3(monkeypatch) -> None:
    import slamkit.experiments.pose_graph as pg

    def fail(*a, **k):
        raise BackendError("Indeterminate linear system at X(3)")

    monkeypatch.setattr(pg, "optimize_source", fail)
    result = _run("optimize", "ring")
    assert result.exit_code == 3 and result.output.strip() == "error: Indeterminate linear system at X(3)"


def test_an_unexpected_exception_is_one_line_exit_1_and_debug_shows_it(monkeypatch) -> None:
    import slamkit.experiments.pose_graph as pg

    def bug(*a, **k):
        raise RuntimeError("boom\nsecond line")

    monkeypatch.setattr(pg, "optimize_source", bug)
    result = _run("optimize", "ring")
    assert result.exit_code == 1
    assert result.output.strip() == ("internal error: RuntimeError: boom (run again with --debug for the "
                                     "traceback, and please report it)")
    debug = runner.invoke(app, ["--debug", "optimize", "ring"])
    assert isinstance(debug.exception, RuntimeError) and str(debug.exception) == "boom\nsecond line"


def test_a_file_on_disk_wins_over_the_registry_name(tmp_path, monkeypatch) -> None:
    # a copy of intel-g2o's file named like the registry's 'ring': the file must be used
    shutil.copy(registry.path_of("intel-g2o"), tmp_path / "ring")
    monkeypatch.chdir(tmp_path)
    result = _run("optimize", "ring", "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["num_poses"] == 943  # intel-g2o's, not ring's 434
    assert data["warnings"][0].startswith("'ring' is both a file here and a registry dataset: using the file ")
    assert registry.resolution_note("intel") is None


def test_doctor_says_which_kernels_are_compiled() -> None:
    result = _run("doctor", "--json")
    assert result.exit_code == 0
    data = json.loads(result.output)
    assert data["kernels"] == {"slamkit.data.formats._textscan": "compiled", "slamkit.maps._raycast": "compiled",
                               "slamkit.planning._gridsearch": "compiled", "slamkit.estimation._pfkernel": "compiled",
                               "slamkit.estimation._eskfkernel": "compiled",
                               "slamkit.frontend._bnbkernel": "compiled", "slamkit.frontend._icpkernel": "compiled"}
    assert [r["kind"] for r in data["data_roots"]][-1] == "cache"


def test_an_ate_of_infinity_is_no_result_exit_3(tmp_path) -> None:
    # a 1e308 coordinate used to print ATE Infinity and exit 0
    (tmp_path / "ref.tum").write_text("0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n")
    (tmp_path / "est.tum").write_text("0 0 0 0 0 0 0 1\n1 1e308 0 0 0 0 0 1\n")
    result = _run("eval", "ate", "--ref", str(tmp_path / "ref.tum"), "--est", str(tmp_path / "est.tum"), "--json")
    assert result.exit_code == 3
    assert "error: the error statistics are not finite (error 1 is inf)" in result.output


def test_a_negative_sesync_objective_is_no_result(tmp_path) -> None:
    from slamkit.backend.objective import sesync_objective
    from slamkit.data.formats import load_pose_graph
    from slamkit.errors import NoResultError

    g2o = tmp_path / "neg.g2o"
    g2o.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n"
                   "EDGE_SE2 0 1 2 0 0 -1 0 0 -1 0 -1\n")  # negative-definite information, kept
    graph = load_pose_graph(g2o, policy="keep")
    with pytest.raises(NoResultError, match=r"neg: the SE-Sync objective is -.*, which a sum of squares cannot be"):
        sesync_objective(graph, graph.poses)


def test_information_gtsam_cannot_use_is_bad_input_naming_the_edge(tmp_path) -> None:
    bad = tmp_path / "neg.g2o"
    bad.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 -1 0 0 -1 0 -1\n")
    result = _run("optimize", str(bad), "--json")
    assert result.exit_code == 2
    assert result.output.startswith(f"error: {bad}: edge 0 (0 -> 1) has an information matrix GTSAM cannot use "
                                    "(Isotropic::Variance: variance must be non-negative)")
    zero = tmp_path / "zero.g2o"  # no information at all: no force, SE-Sync weight 0, a warning
    zero.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 0 0 0 0 0 0\n")
    ok = _run("optimize", str(zero), "--json")
    assert ok.exit_code == 0
    data = json.loads(ok.output)
    assert data["final_error"] == 0.0 and data["sesync_objective"] == 0.0
    assert data["warnings"] == ["1 of 1 edges have an information matrix that is not positive definite; "
                                "GTSAM factorises them as given (as readG2o does)"]


def test_an_old_planner_spelling_runs_with_one_warning_line() -> None:
    # issue 18: one naming rule; 'rrt-star' (the spelling before it) still plans, and says so
    r = runner.invoke(app, ["plan", "arena", "--start", "1.5,13.5", "--goal", "40.5,40.5",
                                                 "--planner", "RRT-Star", "--max-iterations", "300", "--json"])
    assert r.exit_code in (0, 3), r.stderr
    assert r.stderr.splitlines()[0] == "warning: planner name 'RRT-Star' is deprecated; write 'rrt_star'"
    assert json.loads(r.stdout)["planner"] == "rrt_star"
    unknown = runner.invoke(app, ["plan", "arena", "--start", "1,1", "--goal", "2,2",
                                                       "--planner", "rrt_start"])
    assert unknown.exit_code == 2
    assert "error: unknown planner 'rrt_start' (did you mean 'rrt_star'?)" in unknown.stderr


def test_run_perturbations_option(tmp_path) -> None:
    """``slamkit run CFG --perturbations N`` sets ``perturbations.count`` (kept kinds), and a
    pipeline that does not rerun its data says so with exit 2, writing nothing."""
    cfg = tmp_path / "fvs.yaml"
    cfg.write_text("pipeline: filter_vs_smoother\nseeds: 1\nworkers: 1\nrecord: false\n"
                   "scenarios: [{preset: mild, params: {duration_s: 5.0}}]\nestimators: {ekf: {}}\n"
                   "perturbations: {count: 1, kinds: [range_jitter]}\n")
    result = _run("run", str(cfg), "--out", str(tmp_path / "out"), "--quiet", "--perturbations", "2")
    assert result.exit_code == 0, result.output
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert sorted(r.get("params", {}).get("perturbation", 0) for r in data["runs"]) == [0, 1, 2]
    written = (tmp_path / "out" / "config.yaml").read_text()
    assert "count: 2" in written and "range_jitter" in written and "start_offset" not in written
    pose_graph = Path(__file__).resolve().parents[2] / "pipelines" / "pose_graph.yaml"
    bad = _run("run", str(pose_graph), "--out", str(tmp_path / "pg"), "--quiet", "--perturbations", "2")
    assert bad.exit_code == 2 and "does not rerun its data" in bad.output and "lidar_slam" in bad.output
    assert not (tmp_path / "pg").exists()
