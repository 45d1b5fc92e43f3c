"""The one trajectory scorer (issue 30): worked examples in the metric vocabulary, and the same
numbers as ate / rpe / kitti_drift called directly."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.geometry import so3
from slamkit.metrics import ate, ate_paired_by_stamp, kitti_drift, rpe, score_trajectory


def helix(n: int = 50) -> Trajectory:
    k = np.arange(n)
    t = np.column_stack([np.cos(0.2 * k) * 5, np.sin(0.2 * k) * 5, 0.1 * k])
    R = so3.from_euler_zyx(0.2 * k + np.pi / 2, 0.05 * np.sin(k), 0.02 * k)
    return Trajectory(k * 0.5, t, so3.to_quat_wxyz(R))


def test_a_shifted_copy_scores_its_shift_unaligned_and_zero_aligned():
    ref = helix()
    est = Trajectory(ref.stamps_s, ref.world_t_body + [3.0, 4.0, 0.0], ref.world_q_body_wxyz)
    s = score_trajectory(ref, est, "none", extra_aligns=("se3", "sim3"), rpe_delta=1, rpe_delta_unit="frames")
    assert s["ate_rmse_m"] == pytest.approx(5.0)
    assert s["ate_rot_rmse_rad"] == pytest.approx(0.0, abs=1e-12)
    assert s["ate_se3_rmse_m"] == pytest.approx(0.0, abs=1e-9)
    assert s["ate_sim3_rmse_m"] == pytest.approx(0.0, abs=1e-9)
    assert s["rpe_rmse_m"] == pytest.approx(0.0, abs=1e-12)   # relative motion does not see the shift
    assert set(s) == {"ate_rmse_m", "ate_rot_rmse_rad", "ate_se3_rmse_m", "ate_sim3_rmse_m", "rpe_rmse_m",
                      "rpe_rot_rmse_rad"}


def test_ten_percent_too_long_monocular_estimate():
    ref = helix()
    est = Trajectory(ref.stamps_s, 1.1 * ref.world_t_body, ref.world_q_body_wxyz)
    s = score_trajectory(ref, est, "sim3", extra_aligns=("se3",), rotation_unit="deg", rpe_delta=1,
                         rpe_delta_unit="frames")
    assert s["ate_rmse_m"] == pytest.approx(0.0, abs=1e-9)
    assert s["sim3_scale"] == pytest.approx(1 / 1.1)
    assert s["ate_se3_rmse_m"] > 0.1
    assert s["ate_rot_rmse_deg"] == pytest.approx(0.0, abs=1e-9)
    # unaligned frame-to-frame error: 10 % of each step
    steps = np.linalg.norm(np.diff(ref.world_t_body, axis=0), axis=1)
    assert s["rpe_rmse_m"] == pytest.approx(np.sqrt(np.mean((0.1 * steps) ** 2)))
    assert "rpe_rot_rmse_deg" in s and "rpe_rot_rmse_rad" not in s


def test_the_same_numbers_as_the_metrics_it_composes():
    ref = helix(80)
    rng = np.random.default_rng(3)
    est = Trajectory(ref.stamps_s, ref.world_t_body + rng.normal(0, 0.05, (80, 3)), ref.world_q_body_wxyz)
    s = score_trajectory(ref, est, "se3", rpe_delta=2.0, rpe_delta_unit="m", rpe_pairs_from_reference=True,
                         drift_lengths_m=(5.0, 10.0), drift_step_frames=1, drift_suffix="_5_10m")
    a = ate(ref, est, "se3")
    r = rpe(ref, est, 2.0, "m", pairs_from_reference=True)
    d = kitti_drift(ref, est, lengths_m=(5.0, 10.0), step_frames=1)
    assert s["ate_rmse_m"] == a.translation_m.rmse and s["ate_rot_rmse_rad"] == a.rotation_rad.rmse
    assert s["rpe_rmse_m"] == r.translation_m.rmse and s["rpe_rot_rmse_rad"] == r.rotation_rad.rmse
    assert s["drift_percent_5_10m"] == d.translation_percent
    assert s["drift_deg_per_100m_5_10m"] == d.rotation_deg_per_100m


def test_rpe_left_out_on_a_short_path_and_bad_units_refused():
    ref = helix(10)   # ~9 m of path
    s = score_trajectory(ref, ref, "se3", rpe_min_path_m=20.0)
    assert "rpe_rmse_m" not in s and s["ate_rmse_m"] == pytest.approx(0.0, abs=1e-9)
    s = score_trajectory(ref, ref, "se3", rpe_delta=100.0, rpe_delta_unit="m")   # no pair that long
    assert "rpe_rmse_m" not in s
    with pytest.raises(DataError, match="rotation_unit"):
        score_trajectory(ref, ref, rotation_unit="grad")


def test_ate_only_when_rpe_delta_is_none():
    ref = helix()
    est = Trajectory(ref.stamps_s, ref.world_t_body + [0.3, 0.4, 0.0], ref.world_q_body_wxyz)
    s = score_trajectory(ref, est, "none", rpe_delta=None)
    assert set(s) == {"ate_rmse_m", "ate_rot_rmse_rad"}
    assert s["ate_rmse_m"] == pytest.approx(0.5)


def test_ate_paired_by_stamp_aligns_planar_in_se2_and_pairs_by_stamp():
    k = np.arange(40.0)
    ref = Trajectory.from_se2(k, np.column_stack([np.cos(0.2 * k) * 5, np.sin(0.2 * k) * 5, 0.2 * k + np.pi / 2]))
    # every other pose, rotated 0.3 rad and shifted, with 0.1 m of error along x on pose 10
    xy = ref.xytheta()[::2].copy()
    xy[5, 0] += 0.1
    c, s = np.cos(0.3), np.sin(0.3)
    moved = np.column_stack([c * xy[:, 0] - s * xy[:, 1] + 2.0, s * xy[:, 0] + c * xy[:, 1] - 1.0, xy[:, 2] + 0.3])
    rmse, mode = ate_paired_by_stamp(ref, Trajectory.from_se2(k[::2], moved))
    assert mode == "se2"
    assert rmse == pytest.approx(score_trajectory(Trajectory.from_se2(k[::2], ref.xytheta()[::2]),
                                                  Trajectory.from_se2(k[::2], moved), "se2")["ate_rmse_m"])
    assert 0.0 < rmse < 0.1 / np.sqrt(20)          # the one error, shared out by the alignment
    _, mode3 = ate_paired_by_stamp(helix(), helix())
    assert mode3 == "se3"
