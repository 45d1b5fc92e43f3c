"""``slamkit eval ate|rpe`` on files written in tmp_path, with the expected numbers stated."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from slamkit.cli import app
from slamkit.data.formats.kitti import write_kitti
from slamkit.data.formats.tum import write_tum
from slamkit.data.trajectory import Trajectory
from slamkit.geometry import se3, so3

runner = CliRunner()


def helix(n: int = 40, stamp0: float = 1000.0) -> Trajectory:
    k = np.arange(n)
    t = np.column_stack([np.cos(0.2 * k) * 5, np.sin(0.2 * k) * 5, 0.1 * k])
    return Trajectory(stamp0 + 0.1 * k, t, so3.to_quat_wxyz(so3.from_euler_zyx(0.2 * k, 0.0, 0.0)))


def shifted(traj: Trajectory, offset) -> Trajectory:
    return Trajectory(traj.stamps_s, traj.world_t_body + np.asarray(offset), traj.world_q_body_wxyz)


def run_json(*args: str) -> dict:
    result = runner.invoke(app, ["eval", *args, "--json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


@pytest.fixture()
def tum_pair(tmp_path: Path) -> tuple[Path, Path]:
    ref = helix()
    return (write_tum(tmp_path / "ref.txt", ref),
            write_tum(tmp_path / "est.txt", shifted(ref, [3.0, 4.0, 0.0])))  # |offset| = 5 m


def test_ate_json_of_shifted_copy(tum_pair):
    ref, est = map(str, tum_pair)
    out = run_json("ate", "--ref", ref, "--est", est, "--format", "tum")
    for key in ("rmse", "mean", "median", "min", "max"):
        assert out[key] == pytest.approx(5.0, abs=1e-12)
    assert out["std"] == pytest.approx(0.0, abs=1e-12)
    assert out["num_pairs"] == 40 and out["align"] == "none" and out["unit"] == "m"
    for mode in ("se3", "sim3", "origin", "se2"):
        assert run_json("ate", "--ref", ref, "--est", est, "--align", mode)["max"] == pytest.approx(0.0, abs=1e-9)


def test_ate_rotation_relation(tmp_path: Path):
    ref = helix()
    q = so3.to_quat_wxyz(so3.from_quat_wxyz(ref.world_q_body_wxyz) @ so3.from_euler_zyx(0, 0, np.deg2rad(3.0)))
    est = Trajectory(ref.stamps_s, ref.world_t_body, q)
    out = run_json("ate", "--ref", str(write_tum(tmp_path / "r.txt", ref)),
                   "--est", str(write_tum(tmp_path / "e.txt", est)), "--relation", "angle_deg")
    assert out["unit"] == "deg" and out["mean"] == pytest.approx(3.0, abs=1e-9)


def test_rpe_frames_and_metres_on_scaled_line(tmp_path: Path):
    n = 21
    line = np.column_stack([np.arange(n), np.zeros(n), np.zeros(n)]).astype(float)
    ref = Trajectory.from_se2(np.arange(n, dtype=float), line)
    est = Trajectory.from_se2(np.arange(n, dtype=float), line * [1.1, 1, 1])  # 10 % too long
    r = str(write_tum(tmp_path / "r.txt", ref))
    e = str(write_tum(tmp_path / "e.txt", est))
    out = run_json("rpe", "--ref", r, "--est", e, "--delta", "5")
    assert out["num_pairs"] == 4 and out["rmse"] == pytest.approx(0.5)  # 5 frames x 0.1 m
    out = run_json("rpe", "--ref", r, "--est", e, "--delta", "5", "--all-pairs")
    assert out["num_pairs"] == 16
    # 2 m of the estimate's path (1.1 m a step) -> every second pose: 10 pairs of 0.2 m error
    out = run_json("rpe", "--ref", r, "--est", e, "--delta", "2", "--delta-unit", "m")
    assert out["num_pairs"] == 10 and out["mean"] == pytest.approx(0.2)
    assert out["delta"] == 2.0 and out["delta_unit"] == "m"


def test_kitti_files_auto_detected(tmp_path: Path):
    ref = helix(stamp0=0.0)
    r = write_kitti(tmp_path / "00.txt", ref)
    e = write_kitti(tmp_path / "00_est.txt", shifted(ref, [0.0, 0.0, 2.0]))
    for fmt in ("auto", "kitti"):
        out = run_json("ate", "--ref", str(r), "--est", str(e), "--format", fmt)
        assert out["rmse"] == pytest.approx(2.0) and out["num_pairs"] == 40


def test_g2o_vertices_as_trajectory(tmp_path: Path):
    ref = tmp_path / "ref.g2o"
    est = tmp_path / "est.g2o"
    ref.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_SE2 2 2 0 0\n"
                   "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE2 1 2 1 0 0 1 0 0 1 0 1\n")
    # the estimate lacks vertex 1 and has vertex 2 off by 0.5 m in y: stamps are vertex ids
    est.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 2 2 0.5 0\nEDGE_SE2 0 2 2 0 0 1 0 0 1 0 1\n")
    out = run_json("ate", "--ref", str(ref), "--est", str(est), "--format", "g2o")
    assert out["num_pairs"] == 2
    assert out["max"] == pytest.approx(0.5) and out["min"] == 0.0
    assert out["rmse"] == pytest.approx(np.sqrt(0.25 / 2))


def test_cli_matches_evo_on_random_tum_files(tmp_path: Path):
    file_interface = pytest.importorskip("evo.tools.file_interface")
    from evo.core import metrics, sync

    rng = np.random.default_rng(7)
    n = 80
    T = np.empty((n, 4, 4))
    T[0] = np.eye(4)
    for k in range(1, n):
        T[k] = T[k - 1] @ se3.exp(np.r_[rng.normal(0.5, 0.1), rng.normal(0, 0.1, 2), rng.normal(0, 0.1, 3)])
    ref = Trajectory.from_matrices(10.0 + 0.1 * np.arange(n), T)
    noisy = se3.exp(rng.normal(0, [0.1, 0.1, 0.1, 0.02, 0.02, 0.02], (n, 6)))
    est_T = se3.exp(rng.normal(size=6)) @ (T @ noisy)
    est_T[:, :3, 3] *= 1.3
    est = Trajectory.from_matrices(ref.stamps_s + 0.002, est_T)
    r, e = write_tum(tmp_path / "ref.txt", ref), write_tum(tmp_path / "est.txt", est)
    for mode in ("none", "se3", "sim3"):
        ours = run_json("ate", "--ref", str(r), "--est", str(e), "--align", mode)
        tr, te = sync.associate_trajectories(file_interface.read_tum_trajectory_file(str(r)),
                                             file_interface.read_tum_trajectory_file(str(e)))
        if mode != "none":
            te.align(tr, correct_scale=mode == "sim3")
        ape = metrics.APE(metrics.PoseRelation.translation_part)
        ape.process_data((tr, te))
        for key, value in ape.get_all_statistics().items():
            assert ours[key] == pytest.approx(value, rel=1e-9), (mode, key)
        ours = run_json("rpe", "--ref", str(r), "--est", str(e), "--align", mode, "--delta", "3",
                        "--delta-unit", "m")
        rpe = metrics.RPE(metrics.PoseRelation.translation_part, 3.0, metrics.Unit.meters)
        rpe.process_data((tr, te))
        for key, value in rpe.get_all_statistics().items():
            assert ours[key] == pytest.approx(value, rel=1e-9), (mode, key)


def test_table_output_and_errors(tum_pair, tmp_path: Path):
    ref, est = map(str, tum_pair)
    result = runner.invoke(app, ["eval", "ate", "--ref", ref, "--est", est, "--align", "sim3"])
    assert result.exit_code == 0 and "rmse" in result.stdout and "scale" in result.stdout
    bad = tmp_path / "bad.txt"
    bad.write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n")
    result = runner.invoke(app, ["eval", "ate", "--ref", ref, "--est", str(bad), "--format", "tum"])
    assert result.exit_code == 2
    assert f"{bad}:2:" in result.stderr
    result = runner.invoke(app, ["eval", "ate", "--ref", ref, "--est", est, "--align", "affine"])
    assert result.exit_code != 0
    # --delta is RPE's pose-pair spacing: ATE refuses it instead of ignoring it (issue 32)
    result = runner.invoke(app, ["eval", "ate", "--ref", ref, "--est", est, "--delta", "3", "--json"])
    assert result.exit_code == 2 and "No such option: --delta" in result.stderr
    # the table names the pair count as the JSON does
    table = runner.invoke(app, ["eval", "ate", "--ref", ref, "--est", est])
    assert table.exit_code == 0 and "num_pairs" in table.stdout and "│ pairs" not in table.stdout
    assert json.loads(runner.invoke(app, ["eval", "ate", "--ref", ref, "--est", est, "--json"]).stdout)["rmse"] \
        == pytest.approx(5.0)


def test_eval_relations_on_intel_raw_odometry(shared_datasets, tmp_path) -> None:
    # the laser poses by odometry of every FLASER line, written as TUM, score the MANIFEST's check
    from slamkit.data.formats.carmen import read_carmen

    laser = read_carmen(shared_datasets / "lidar_2d" / "intel.clf.bz2").front
    order = np.argsort(laser.stamps_s, kind="stable")  # ipc stamps are not always in log order
    write_tum(tmp_path / "odo.tum", Trajectory.from_se2(laser.stamps_s[order], laser.world_xytheta_laser[order]))
    result = runner.invoke(app, ["eval", "relations", "--est", str(tmp_path / "odo.tum"),
                                 "--relations", str(shared_datasets / "lidar_2d" / "intel.relations"), "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.output)
    assert out["relation_count"] == 2984 and out["relation_unmatched"] == 0
    assert round(out["relation_trans_mean_m"], 2) == 7.37 and round(out["relation_trans_std_m"], 2) == 14.35


def test_data_convert_writes_a_bag_that_reads_back(tmp_path) -> None:
    from slamkit.data.formats.rosbag import read_bag

    result = runner.invoke(app, ["data", "convert", "mit-csail-log", str(tmp_path / "mit")])
    assert result.exit_code == 0, result.output
    assert result.output.strip() == f"wrote {tmp_path / 'mit'}: /scan 1988, /odom 1988"
    assert len(read_bag(tmp_path / "mit").events) == 1988 + 1987
