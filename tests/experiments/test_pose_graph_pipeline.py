"""End to end: `slamkit optimize` and the pose_graph pipeline on real benchmark graphs."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from slamkit.backend.solvers import OptimizeConfig
from slamkit.cli import app
from slamkit.experiments.pipeline import run_pipeline
from slamkit.experiments.pose_graph import optimize_source
from slamkit.viz.pipelines import observer_for

JSON_KEYS = {"dataset", "num_poses", "num_factors", "solver", "init", "initial_error",
             "final_error", "chi2", "sesync_objective", "iterations", "time_load_s", "time_init_s",
             "time_solve_s", "time_total_s", "ate_rmse_m"}


def test_optimize_json_on_ring_matches_reference(shared_datasets, tmp_path) -> None:
    out = tmp_path / "ring"
    result = CliRunner().invoke(app, ["optimize", "ring", "--json", "--out", str(out),
                                      "--rrd", str(tmp_path / "ring.rrd")])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert JSON_KEYS <= set(data)
    # MANIFEST "gtsam local check": error 5.58155 (chi2 11.1631) at the optimum; 434 poses,
    # 459 edges + the gauge prior
    assert data["final_error"] == pytest.approx(5.58155, rel=1e-5)
    assert data["chi2"] == pytest.approx(2 * data["final_error"])
    assert (data["num_poses"], data["num_factors"]) == (434, 460)
    # ground truth exists for ring: the optimum sits 1.43 m RMS from it after SE(2) alignment
    assert data["ate_rmse_m"] == pytest.approx(1.4316, abs=1e-3)
    assert sorted(p.name for p in out.iterdir()) == [".slamkit-results", "config.yaml", "metrics.json", "trajectories"]
    assert json.loads((out / "metrics.json").read_text())["final_error"] == data["final_error"]


def test_optimize_recording_has_the_documented_entities(shared_datasets, tmp_path, verify_rrd) -> None:
    rrd = tmp_path / "ring.rrd"
    report = optimize_source("ring", OptimizeConfig(), keep_iterates=True)
    from slamkit.viz.pose_graph import record_optimization

    record_optimization(report, rrd)
    entities = verify_rrd(rrd)
    assert {"/world/initial", "/world/estimate", "/world/loop_closures", "/world/ground_truth",
            "/world/iterate", "/plots/error"} <= entities
    # one iterate per iteration plus the initial state
    assert len(report.iterates) == report.iterations + 1


def test_optimize_unknown_source_is_a_clean_error(tmp_path) -> None:
    result = CliRunner().invoke(app, ["optimize", "no-such-dataset", "--json"])
    assert result.exit_code == 2
    assert "no-such-dataset" in result.output


def test_pose_graph_pipeline_writes_table_plots_and_recording(shared_datasets, tmp_path,
                                                              verify_rrd) -> None:
    config = {"pipeline": "pose_graph", "name": "t", "datasets": ["ring", "tinygrid3d"],
              "solvers": ["lm", "gn"], "inits": ["file", "lago", "chordal"]}
    result = run_pipeline(config, tmp_path / "pg", progress=False,
                          observer_factory=lambda kind, path: observer_for(kind, path))
    runs = result.results["runs"]
    # ring: file + lago; tinygrid3d: file + chordal -> 2 datasets x 2 solvers x 2 inits
    assert len(runs) == 8
    ring = [r for r in runs if r["dataset"] == "ring"]
    assert all(r["metrics"]["final_error"] == pytest.approx(5.58155, rel=1e-5) for r in ring)
    tiny = [r for r in runs if r["dataset"] == "tinygrid3d" and r["params"]["init"] == "chordal"]
    # MANIFEST local check for tinyGrid3D with chordal init + LM: 9.31391
    assert tiny[0]["metrics"]["final_error"] == pytest.approx(9.31391, rel=1e-5)
    out = result.out_dir
    assert (out / "plots" / "final_error_and_time.png").stat().st_size > 10_000
    assert (out / "plots" / "trajectory_ring.png").exists()
    assert len(list((out / "trajectories").glob("*.tum"))) == 8
    assert "| ring | lm | file |" in (out / "report.md").read_text()
    entities = verify_rrd(out / "recording.rrd")
    assert {"/ring/world/estimate", "/ring/plots/error", "/tinygrid3d/world/estimate"} <= entities
