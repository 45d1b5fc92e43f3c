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
    # every solution, and beside it the refined poses its certificate is about (issue 32)
    assert len(list((out / "trajectories").glob("*.tum"))) == 16
    assert len(list((out / "trajectories").glob("*_refined.tum"))) == 8
    assert (out / "trajectories" / "ring_lm_file_refined.g2o").is_file()
    assert "| ring | lm | file |" in (out / "report.md").read_text()
    entities = verify_rrd(out / "recording.rrd")
    assert {"/ring/world/estimate", "/ring/plots/error", "/tinygrid3d/world/estimate"} <= entities


def test_optimize_certifies_csail_at_sesyncs_optimum(shared_datasets) -> None:
    result = CliRunner().invoke(app, ["optimize", "csail", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    cert = data["certificate"]
    # SE-Sync, IJRR 2019, Table 1: f* = 3.170e1 (certified); GTSAM's own optimum has F = 53.49
    assert data["certified"] is True and cert["certified"] is True
    assert data["sesync_objective"] == pytest.approx(53.4863, rel=1e-5)
    assert cert["objective"] == pytest.approx(31.70, abs=0.005)
    assert cert["min_eigenvalue"] >= -1e-3 and cert["time_total_s"] > 0
    assert data["retry"] is None
    off = json.loads(CliRunner().invoke(app, ["optimize", "csail", "--json", "--certify", "off"]).stdout)
    assert off["certificate"] is None and off["certify_skipped"] == "certification off"


def twisted_cycle_g2o(path, n: int = 8) -> None:
    """n poses at the origin with headings wound once around the circle, every edge measuring the
    identity: a local minimum of both GTSAM's error and F (global optimum: all headings equal)."""
    lines = [f"VERTEX_SE2 {k} 0 0 {2 * 3.141592653589793 * k / n - (2 * 3.141592653589793 if k > n // 2 else 0)}"
             for k in range(n)]
    lines += [f"EDGE_SE2 {k} {(k + 1) % n} 0 0 0 1 0 0 1 0 5" for k in range(n)]
    path.write_text("\n".join(lines) + "\n")


def test_an_uncertified_local_minimum_is_retried_from_lago(tmp_path) -> None:
    path = tmp_path / "twisted.g2o"
    twisted_cycle_g2o(path)
    report = optimize_source(path, OptimizeConfig())
    # LM stays at the planted local minimum: each edge off by pi/4, error 8 * 5 * (pi/4)^2 / 2
    assert report.final_error == pytest.approx(8 * 5 * (3.141592653589793 / 4) ** 2 / 2, rel=1e-6)
    assert report.certified is False
    # lambda_min = -2 kappa (1 - cos(pi/4)) (tests/backend/test_certify.py)
    assert report.certificate.min_eigenvalue == pytest.approx(-2 * 5 * (1 - 0.7071067811865476), rel=1e-6)
    retry = report.retry
    assert retry is not None and retry.init == "lago" and retry.certified is True
    assert retry.final_error < 1e-9 and retry.certificate.objective < 1e-9
    summary = report.summary()
    assert summary["certified"] is False and summary["retry"]["certified"] is True


def test_optimize_says_which_solution_is_certified_and_which_poses_it_wrote(tmp_path) -> None:
    """The planted local minimum: the LM solution is refuted ('not optimal'), the retry from LAGO
    is certified; both solutions and the poses each certificate is about are written, named."""
    import numpy as np

    from slamkit.data.formats import load_pose_graph

    path = tmp_path / "twisted.g2o"
    twisted_cycle_g2o(path)
    result = CliRunner().invoke(app, ["optimize", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert any(line.startswith("certificate: not optimal (lambda_min -2.93 < -0.001: a better solution exists) "
                               "for the solution refined on SE-Sync's F") for line in lines), result.stdout
    assert any(line.startswith("retry from lago: certified (lambda_min") for line in lines), result.stdout
    out = tmp_path / "out"
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["certificate_verdict"] == "not optimal" and metrics["retry"]["certificate_verdict"] == "certified"
    assert metrics["written"] == {
        "solution": ["trajectories/twisted.g2o", "trajectories/twisted.tum"],
        "refined": ["trajectories/twisted_refined.g2o", "trajectories/twisted_refined.tum"],
        "retry_solution": ["trajectories/twisted_retry_lago.g2o", "trajectories/twisted_retry_lago.tum"],
        "retry_refined": ["trajectories/twisted_retry_lago_refined.g2o", "trajectories/twisted_retry_lago_refined.tum"]}
    for key, files in metrics["written"].items():
        assert f"wrote {out / files[0]}, {out / files[1]}: " in result.stdout
    # the files hold what they are named after: the twisted headings (k pi / 4, wrapped) for the
    # LM solution, all headings equal (F = 0) for the certified retry
    lm = load_pose_graph(out / "trajectories" / "twisted.g2o").poses
    heading_steps = np.angle(np.exp(1j * np.diff(lm[:, 2])))
    assert np.allclose(heading_steps, np.pi / 4, atol=1e-6)
    certified = load_pose_graph(out / "trajectories" / "twisted_retry_lago_refined.g2o").poses
    assert np.allclose(np.angle(np.exp(1j * (certified[:, 2] - certified[0, 2]))), 0.0, atol=1e-6)


def test_the_report_puts_sesyncs_published_optimum_beside_the_certified_one(shared_datasets, tmp_path) -> None:
    from slamkit.experiments.pose_graph import published_fstar

    # the registry's SE-Sync references (IJRR 2019, Tables 1-2); files and graphs without one: None
    assert (published_fstar("csail"), published_fstar("sphere2500")) == (31.70, 1687.0)
    assert published_fstar("ring") is None and published_fstar(str(tmp_path / "x.g2o")) is None
    config = {"pipeline": "pose_graph", "name": "t", "datasets": ["csail"], "solvers": ["lm"], "inits": ["file"]}
    report = (run_pipeline(config, tmp_path / "pg", progress=False).out_dir / "report.md").read_text()
    row = next(line for line in report.splitlines() if line.startswith("| csail | lm | file |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    # certified F 31.7037 beside f* 31.70: ratio 1.0001 (f* has 4 significant digits)
    assert cells[10] == "yes" and float(cells[12]) == 31.7
    assert float(cells[13]) == pytest.approx(31.7037 / 31.70, abs=2e-5)


def test_an_option_that_the_combinations_set_is_refused_before_anything_runs(tmp_path) -> None:
    """options.solver / init / robust are the pipeline's own lists (issue 30: this was a TypeError
    from OptimizeConfig after validation); the error names file and line."""
    from slamkit.errors import ConfigError
    from slamkit.experiments.pipeline import load_config

    cfg = tmp_path / "pg.yaml"
    cfg.write_text("pipeline: pose_graph\ndatasets: [intel]\nsolvers: [lm]\noptions:\n  solver: gn\n")
    with pytest.raises(ConfigError, match=r"pg.yaml:5: options.solver: set by the pipeline's 'solvers'"):
        load_config(cfg)
    with pytest.raises(ConfigError, match="options.robust: set by the pipeline's 'robust'"):
        run_pipeline({"pipeline": "pose_graph", "datasets": ["intel"], "options": {"robust": "huber"}},
                     tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()
