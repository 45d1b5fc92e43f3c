"""Worked examples with known numbers for alignment, association, ATE, RPE, statistics, KITTI
drift and NEES/NIS bands, plus property tests for Umeyama."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.geometry import se3, so3
from slamkit.metrics import (
    ErrorStats,
    align,
    associate,
    ate,
    chi2_band,
    consistency,
    kitti_drift,
    nees,
    nis,
    rpe,
    transform_trajectory,
    umeyama,
)


def helix(n: int = 50) -> Trajectory:
    """A 3D helix with orientations following the path (not planar, not degenerate)."""
    k = np.arange(n)
    t = np.column_stack([np.cos(0.2 * k) * 5, np.sin(0.2 * k) * 5, 0.1 * k])
    R = so3.from_euler_zyx(0.2 * k + np.pi / 2, 0.05 * np.sin(k), 0.02 * k)
    return Trajectory(k * 0.5, t, so3.to_quat_wxyz(R))


def test_error_stats_worked_example():
    s = ErrorStats.from_errors([3.0, 4.0, 0.0, 5.0])
    assert s.rmse == pytest.approx(np.sqrt(50 / 4))
    assert (s.mean, s.median, s.min, s.max, s.sse, s.num) == (3.0, 3.5, 0.0, 5.0, 50.0, 4)
    assert s.std == pytest.approx(np.sqrt(((0 + 1 + 9 + 4) / 4)))  # population std
    with pytest.raises(DataError):
        ErrorStats.from_errors([])


def test_shifted_copy_ate_equals_offset_without_alignment_and_zero_with():
    ref = helix()
    offset = np.array([1.0, 2.0, 2.0])  # |offset| = 3 m
    est = Trajectory(ref.stamps_s, ref.world_t_body + offset, ref.world_q_body_wxyz)
    none = ate(ref, est, "none")
    for name in ("rmse", "mean", "median", "min", "max"):
        assert getattr(none.translation_m, name) == pytest.approx(3.0, abs=1e-12)
    assert none.translation_m.std == pytest.approx(0.0, abs=1e-12)
    assert none.rotation_rad.max == pytest.approx(0.0, abs=1e-7)
    for mode in ("se3", "sim3", "origin"):
        assert ate(ref, est, mode).translation_m.max == pytest.approx(0.0, abs=1e-9), mode
    res = align(est, ref, "se3")
    np.testing.assert_allclose(res.translation, -offset, atol=1e-9)
    np.testing.assert_allclose(res.rotation, np.eye(3), atol=1e-12)


def test_sim3_copy_aligns_to_zero_and_recovers_scale():
    ref = helix()
    R = so3.from_euler_zyx(0.7, -0.2, 0.3)
    est = transform_trajectory(ref, R, np.array([10.0, -3.0, 2.0]), scale=2.5)
    assert ate(ref, est, "sim3").translation_m.max == pytest.approx(0.0, abs=1e-9)
    assert ate(ref, est, "sim3").rotation_rad.max == pytest.approx(0.0, abs=1e-7)
    assert ate(ref, est, "sim3").alignment.scale == pytest.approx(1 / 2.5)
    assert ate(ref, est, "se3").translation_m.rmse > 1.0  # a rigid fit cannot undo the scale


def test_se2_alignment_is_planar():
    k = np.arange(30)
    ref = Trajectory.from_se2(k.astype(float), np.column_stack([k, np.sin(0.3 * k), 0.1 * k]))
    # a planar rigid motion: yaw 40 deg and an x-y shift
    est = transform_trajectory(ref, so3.from_euler_zyx(np.deg2rad(40), 0, 0), np.array([3.0, -1.0, 0.0]))
    res = ate(ref, est, "se2")
    assert res.translation_m.max == pytest.approx(0.0, abs=1e-9)
    assert res.rotation_deg.max == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_allclose(res.alignment.rotation[2], [0, 0, 1])
    # an out-of-plane tilt cannot be removed by se2 but is by se3
    tilted = transform_trajectory(ref, so3.from_euler_zyx(0, 0, 0.2), np.zeros(3))
    assert ate(ref, tilted, "se2").translation_m.max > 0.1
    assert ate(ref, tilted, "se3").translation_m.max == pytest.approx(0.0, abs=1e-9)


def test_rotation_error_of_constant_yaw_offset_is_ten_degrees():
    ref = helix()
    Rz = so3.from_euler_zyx(np.deg2rad(10.0), 0, 0)
    q = so3.to_quat_wxyz(so3.from_quat_wxyz(ref.world_q_body_wxyz) @ Rz)  # body-frame yaw offset
    est = Trajectory(ref.stamps_s, ref.world_t_body, q)
    res = ate(ref, est, "none")
    assert res.rotation_deg.mean == pytest.approx(10.0, abs=1e-9)
    assert res.rotation_deg.std == pytest.approx(0.0, abs=1e-9)
    assert res.rotation_rad.rmse == pytest.approx(np.deg2rad(10.0), abs=1e-12)
    assert res.translation_m.max == 0.0


def test_rpe_of_ten_percent_scale_drift_on_a_line():
    n = 21
    ref = Trajectory.from_se2(np.arange(n, dtype=float), np.column_stack([np.arange(n), np.zeros(n), np.zeros(n)]))
    est = Trajectory.from_se2(np.arange(n, dtype=float), np.column_stack([1.1 * np.arange(n), np.zeros(n), np.zeros(n)]))
    r1 = rpe(ref, est, 1, "frames")
    assert r1.num_pairs == 20
    assert r1.translation_m.mean == pytest.approx(0.1) and r1.translation_m.std == pytest.approx(0.0)
    r5 = rpe(ref, est, 5, "frames")
    assert r5.num_pairs == 4 and r5.translation_m.rmse == pytest.approx(0.5)
    r5all = rpe(ref, est, 5, "frames", all_pairs=True)
    assert r5all.num_pairs == 16
    # metres: pairs measured on the estimate's path (1.1 m per step): >= 2 m after 2 steps
    rm = rpe(ref, est, 2.0, "m")
    np.testing.assert_array_equal(rm.pairs[:3], [[0, 2], [2, 4], [4, 6]])
    assert rm.translation_m.max == pytest.approx(0.2)
    # points on a line leave the rotation about it undetermined: alignment refuses
    with pytest.raises(DataError, match="degenerate"):
        rpe(ref, est, 1, "frames", align_mode="se3")
    # on a helix, sim3 alignment removes a 10 % scale error, so RPE vanishes
    h = helix()
    h_scaled = transform_trajectory(h, np.eye(3), np.zeros(3), 1.1)
    assert rpe(h, h_scaled, 1, "frames").translation_m.max > 0.01
    assert rpe(h, h_scaled, 1, "frames", align_mode="sim3").translation_m.max == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(DataError, match="no pose pairs"):
        rpe(ref, est, 50, "frames")
    with pytest.raises(DataError, match="integer"):
        rpe(ref, est, 1.5, "frames")


def test_association_worked_example():
    ref = Trajectory.from_se2([0.0, 1.0, 2.0, 3.0], np.zeros((4, 3)))
    est = Trajectory.from_se2([0.005, 1.02, 2.0, 2.995, 7.0], np.zeros((5, 3)))
    pair = associate(ref, est, max_diff_s=0.01)
    np.testing.assert_array_equal(pair.ref_index, [0, 2, 3])
    np.testing.assert_array_equal(pair.est_index, [0, 2, 3])
    np.testing.assert_allclose(pair.est.stamps_s, [0.005, 2.0, 2.995])
    with pytest.raises(DataError, match="no matching timestamps"):
        associate(ref, Trajectory.from_se2([10.0], np.zeros((1, 3))))


def test_alignment_errors():
    ref = helix(5)
    with pytest.raises(DataError, match="associate"):
        align(ref.subset(np.arange(3)), ref, "se3")
    with pytest.raises(DataError, match="unknown alignment"):
        align(ref, ref, "affine")
    with pytest.raises(DataError, match="degenerate"):
        umeyama(np.zeros((4, 3)), np.zeros((4, 3)))


def test_origin_alignment_and_n_first():
    ref = helix()
    T = se3.exp(np.array([1.0, 2.0, 3.0, 0.1, 0.2, 0.3]))
    est = Trajectory.from_matrices(ref.stamps_s, T @ ref.matrices())
    res = align(est, ref, "origin")
    np.testing.assert_allclose(res.aligned.matrices(), ref.matrices(), atol=1e-9)
    # corrupt the tail: aligning on the first 10 poses only recovers the exact transform
    bad = est.world_t_body.copy()
    bad[10:] += 5.0
    est_bad = Trajectory(est.stamps_s, bad, est.world_q_body_wxyz)
    np.testing.assert_allclose(align(est_bad, ref, "se3", n_first=10).rotation, T[:3, :3].T, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.1, 10.0), st.booleans())
def test_umeyama_recovers_similarity(seed, scale, with_scale):
    rng = np.random.default_rng(seed)
    src = rng.normal(size=(20, 3))
    R = so3.exp(rng.normal(size=3))
    t = rng.normal(size=3) * 10
    s = scale if with_scale else 1.0
    dst = s * src @ R.T + t
    R_hat, t_hat, s_hat = umeyama(src, dst, with_scale)
    np.testing.assert_allclose(R_hat, R, atol=1e-9)
    np.testing.assert_allclose(t_hat, t, atol=1e-8)
    assert s_hat == pytest.approx(s, rel=1e-9)
    assert np.linalg.det(R_hat) == pytest.approx(1.0)


def test_umeyama_never_returns_a_reflection():
    rng = np.random.default_rng(3)
    src = rng.normal(size=(30, 3))
    dst = src * np.array([1.0, 1.0, -1.0])  # a mirror image
    R, _, _ = umeyama(src, dst)
    assert np.linalg.det(R) == pytest.approx(1.0)


def straight_line(n: int, step_m: float = 1.0) -> np.ndarray:
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, 0, 3] = step_m * np.arange(n)
    return T


def test_kitti_drift_scale_error_worked_example():
    # 301 poses 1 m apart; estimate 1 % too long. Segments (devkit rule: end at the first frame
    # *beyond* start + L) span L + 1 m, so the error per metre is 0.01 (L + 1) / L.
    # L = 100: starts 0..190 (20 segments); L = 200: starts 0..90 (10 segments).
    gt = straight_line(301)
    est = gt.copy()
    est[:, :3, 3] *= 1.01
    res = kitti_drift(Trajectory.from_matrices(np.arange(301.0), gt),
                      Trajectory.from_matrices(np.arange(301.0), est), lengths_m=(100.0, 200.0))
    assert res.num_segments == 30
    assert res.translation_percent == pytest.approx((20 * 101 / 100 + 10 * 201 / 200) / 30)
    assert res.rotation_deg_per_m == pytest.approx(0.0, abs=1e-9)
    assert res.per_length[100.0][2] == 20 and res.per_length[200.0][2] == 10


def test_kitti_drift_heading_drift_worked_example():
    # estimate turns at kappa rad per metre: over a segment of L + 1 m the heading error is
    # kappa (L + 1), i.e. rotational drift kappa (L + 1) / L rad/m.
    kappa, n = 1e-3, 301
    step = se3.exp(np.array([1.0, 0, 0, 0, 0, kappa]))
    est = np.tile(np.eye(4), (n, 1, 1))
    for k in range(1, n):
        est[k] = est[k - 1] @ step
    res = kitti_drift(Trajectory.from_matrices(np.arange(n * 1.0), straight_line(n)),
                      Trajectory.from_matrices(np.arange(n * 1.0), est), lengths_m=(100.0,))
    assert res.rotation_deg_per_m == pytest.approx(np.rad2deg(kappa * 101 / 100), rel=1e-6)
    assert res.rotation_deg_per_100m == pytest.approx(100 * res.rotation_deg_per_m)
    with pytest.raises(DataError, match="shorter"):
        kitti_drift(Trajectory.from_matrices(np.arange(50.0), straight_line(50)),
                    Trajectory.from_matrices(np.arange(50.0), straight_line(50)))


def test_nees_worked_example_and_batch():
    err = np.array([[1.0, 2.0], [0.0, 3.0]])
    cov = np.array([np.diag([1.0, 4.0]), [[2.0, 1.0], [1.0, 2.0]]])
    # second: [0, 3] P^-1 [0, 3]^T with P^-1 = [[2, -1], [-1, 2]] / 3 -> 9 * 2 / 3 = 6
    np.testing.assert_allclose(nees(err, cov), [2.0, 6.0])
    np.testing.assert_allclose(nis(np.array([2.0]), np.array([4.0])), [1.0])
    with pytest.raises(DataError, match="do not match"):
        nees(err, np.zeros((2, 3, 3)))


def test_chi2_band_closed_form_for_two_dof():
    # chi2 with 2 dof is exponential: ppf(q) = -2 ln(1 - q)
    band = chi2_band(2, 1, 0.95)
    assert band.lower == pytest.approx(-2 * np.log(0.975))
    assert band.upper == pytest.approx(-2 * np.log(0.025))
    # the band of a mean of n samples narrows around dof
    wide, narrow = chi2_band(3, 10), chi2_band(3, 1000)
    assert wide.lower < narrow.lower < 3.0 < narrow.upper < wide.upper
    # chi2.ppf(0.975, 3000) / 1000; the normal approximation 3 + 1.96 sqrt(6 / 1000) gives 3.152
    assert narrow.upper == pytest.approx(3.15370, abs=1e-5)


def test_consistency_of_a_consistent_and_an_overconfident_estimator():
    rng = np.random.default_rng(42)
    n, d = 2000, 3
    A = rng.normal(size=(d, d))
    P = A @ A.T + np.eye(d)
    err = rng.multivariate_normal(np.zeros(d), P, size=n)
    good = consistency(nees(err, np.broadcast_to(P, (n, d, d))), dof=d)
    assert good.consistent and abs(good.mean - 3.0) < 0.15
    assert good.fraction_inside == pytest.approx(0.95, abs=0.02)
    over = consistency(nees(err, np.broadcast_to(P / 2, (n, d, d))), dof=d)  # claims half the variance
    assert not over.consistent and over.mean == pytest.approx(2 * good.mean)


def test_nees_is_undefined_not_huge_for_a_covariance_that_is_not_positive_definite():
    from slamkit.metrics.consistency import nees_or_nan

    err = np.array([[1.0, 2.0], [1.0, 1.0], [1.0, 0.0], [0.0, 3.0]])
    cov = np.array([np.diag([1.0, 4.0]),                # fine: 1 + 1 = 2
                    [[1.0, 1.0], [1.0, 1.0]],            # singular (a collapsed particle cloud)
                    [[1.0, 2.0], [2.0, 1.0]],            # indefinite: solve() gives -1/3 * ... < 0
                    [[2.0, 1.0], [1.0, 2.0]]])           # fine: 6
    values = nees_or_nan(err, cov)
    np.testing.assert_allclose(values, [2.0, np.nan, np.nan, 6.0])
    assert np.mean(np.isnan(values)) == 0.5  # what the runner reports as nees_degenerate_fraction
    with pytest.raises(DataError, match=r"covariance 1 is not symmetric positive definite .* undefined for 2 of 4"):
        nees(err, cov)
    # the old solve() answer for the indefinite one was negative: e P^-1 e = -1/3
    assert np.linalg.solve(cov[2], err[2]) @ err[2] == pytest.approx(-1.0 / 3.0)


def test_non_finite_error_statistics_are_errors_not_results():
    from slamkit.errors import NoResultError
    from slamkit.metrics.stats import ErrorStats

    with pytest.raises(NoResultError, match=r"not finite \(error 1 is inf\)"):
        ErrorStats.from_errors(np.array([0.1, np.inf]))
    with pytest.raises(NoResultError, match=r"not finite \(error 0 is 1e\+200\)"):
        ErrorStats.from_errors(np.array([1e200, 0.0]))  # its square overflows
    assert ErrorStats.from_errors(np.array([3.0, 4.0])).rmse == pytest.approx(np.sqrt(12.5))
