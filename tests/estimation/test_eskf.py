"""The 15-state error-state EKF: its hand-fused covariance step against the strapdown Jacobians,
a stationary IMU, and Monte-Carlo consistency on the simulated 3D drive."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from slamkit.data.inertial import InertialSetup, NavState
from slamkit.data.sequence import Gps, Imu, Sequence
from slamkit.estimation.eskf import ErrorStateEKF, ErrorStateEKFConfig
from slamkit.estimation.registry import make_estimator
from slamkit.experiments.runner import world_pose_error
from slamkit.geometry import so3
from slamkit.metrics.alignment import associate
from slamkit.metrics.inertial import inertial_metrics
from slamkit.models import strapdown
from slamkit.models.imu import ImuNoise
from slamkit.sim.inertial_world import PRESETS, simulate_inertial_sequence

G = np.array([0.0, 0.0, -9.80665])
NOISE = ImuNoise(gyro_noise_density=1e-3, gyro_bias_random_walk=1e-4, accel_noise_density=0.02,
                 accel_bias_random_walk=1e-3)


def _setup(R=np.eye(3), v=np.zeros(3)):
    sigma = np.r_[np.full(3, 0.1), np.full(3, 0.05), np.full(3, 0.01), np.full(3, 0.02), np.full(3, 1e-3)]
    return InertialSetup(NavState(0.0, np.zeros(3), v, R), sigma, NOISE, G, 0.5)


def test_covariance_step_equals_strapdown_jacobians():
    """One IMU step: the filter's fused P update equals F P F^T + Q_d built from
    strapdown.error_transition and strapdown.process_noise (to 1e-6 of P's scale: the filter
    uses J_r ~ I - hat/2 and R J_r (R J_r)^T ~ I in Q)."""
    rng = np.random.default_rng(3)
    R0 = so3.exp(rng.standard_normal(3))
    f = ErrorStateEKF(_setup(R0, v=np.array([3.0, -1.0, 0.2])))
    f.reset()
    A = rng.standard_normal((15, 15))
    f.P = A @ A.T * 1e-3 + np.diag(f.setup.initial_sigma**2)
    P0, ba, bg = f.P.copy(), f.ba.copy(), f.bg.copy()
    accel, gyro = np.array([0.4, -0.2, 9.6]), np.array([0.3, -0.5, 0.9])
    f.step(Imu(0.01, gyro, accel))
    F = strapdown.error_transition(R0, accel - ba, gyro - bg, 0.01)
    Q = strapdown.process_noise(NOISE, R0, gyro - bg, 0.01)
    expected = F @ P0 @ F.T + Q
    np.testing.assert_allclose(f.P, expected, atol=1e-6 * np.abs(expected).max())
    p, v, R = strapdown.propagate(np.zeros(3), np.array([3.0, -1.0, 0.2]), R0, accel - ba, gyro - bg, 0.01, G)
    np.testing.assert_allclose(f.p, p, atol=1e-14)
    np.testing.assert_allclose(f.R, R, atol=1e-14)


def test_stationary_imu_stays_put_and_its_velocity_variance_grows_as_the_model_says():
    """Level and at rest, readings exactly -g and 0: after 20 s at 100 Hz without GPS the
    position and velocity are unchanged (to rounding), and the velocity variance grew by
    sigma_a^2 t plus the accel-bias random walk sigma_ba^2 t^3 / 3 plus the initial bias
    sigma_b^2 t^2 (the bias model's only effect)."""
    f = ErrorStateEKF(_setup())
    f.reset()
    n, dt = 2000, 0.01
    for k in range(1, n + 1):
        f.step(Imu(k * dt, np.zeros(3), -G))
    assert np.abs(f.p).max() < 1e-12 and np.abs(f.v).max() < 1e-12
    t = n * dt
    # velocity x variance: initial + sigma_a^2 t + sigma_ba0^2 t^2 + sigma_ba^2 t^3 / 3 (level,
    # the horizontal axis also collects gravity through the tilt: g^2 of the attitude variance,
    # whose own growth is sigma_g^2 t + sigma_bg^2 t^3/3 + ...; compare only the z axis, which
    # has no tilt coupling)
    expected = 0.05**2 + NOISE.accel_noise_density**2 * t + 0.02**2 * t**2 + NOISE.accel_bias_random_walk**2 * t**3 / 3
    assert f.P[5, 5] == pytest.approx(expected, rel=1e-3)
    est = f.estimate()
    assert len(est.trajectory) == n + 1 and est.pose_covariances.shape == (n + 1, 6, 6)


def test_gps_update_on_the_position_only():
    """A fix with sigma s on a position prior sigma p: the posterior position variance is
    p^2 s^2 / (p^2 + s^2) per axis and the NIS is recorded."""
    f = ErrorStateEKF(_setup())
    f.reset()
    f.step(Gps(0.0, np.array([0.1, 0.0, 0.0]), 0.1))
    assert f.P[0, 0] == pytest.approx(0.1**2 * 0.1**2 / (0.1**2 + 0.1**2))
    assert f.p[0] == pytest.approx(0.05)
    assert f.estimate().nis[0] == pytest.approx(0.1**2 / 0.02)


def test_registry_builds_it_from_the_sequence():
    seq = simulate_inertial_sequence(PRESETS["car3d"](duration_s=2.0), np.random.default_rng(0))
    f = make_estimator("es_ekf", seq, {"gps_sigma_m": 0.3})
    assert isinstance(f, ErrorStateEKF) and f.config == ErrorStateEKFConfig(gps_sigma_m=0.3)


def test_monte_carlo_nees_inside_its_band_and_biases_within_three_sigma():
    """6 seeds of a 20 s car3d drive (consumer MEMS IMU at 100 Hz, 0.5 m GPS at 1 Hz): the
    time-mean of the average pose NEES (6 dof) lies inside the two-sided 95% band of
    chi2(6M)/M, and >= 95% of the bias components stay inside their 3-sigma bounds."""
    runs, nees, within = 6, [], []
    for seed in range(runs):
        seq = simulate_inertial_sequence(PRESETS["car3d"](duration_s=20.0), np.random.default_rng(seed))
        f = ErrorStateEKF.from_sequence(seq)
        f.reset()
        for e in seq:
            f.step(e)
        est = f.estimate()
        pairs = associate(seq.ground_truth, est.trajectory, max_diff_s=1e-6)
        err = world_pose_error(pairs.ref, pairs.est)
        P = est.pose_covariances[pairs.est_index]
        nees.append(np.einsum("ni,nij,nj->n", err, np.linalg.inv(P), err))
        within.append(inertial_metrics(est, seq.metadata)["bias_within_3sigma_fraction"])
    anees = np.mean(nees, axis=0)
    lo, hi = chi2.ppf([0.025, 0.975], 6 * runs) / runs
    assert lo <= anees.mean() <= hi, (anees.mean(), lo, hi)
    assert min(within) >= 0.95, within


def test_compiled_step_agrees_with_numpy(monkeypatch):
    """The C kernel (``_eskfkernel.c``) and the numpy step give the same state and covariance
    after 2 s of a simulated drive with GPS (to 1e-12 relative: same arithmetic, other order)."""
    from slamkit._native import load_extension
    from slamkit.estimation.eskf import KERNEL_MODULE

    if load_extension(KERNEL_MODULE) is None:
        pytest.skip("the ES-EKF kernel is not built")
    seq = simulate_inertial_sequence(PRESETS["car3d"](duration_s=2.0), np.random.default_rng(1))
    out = []
    for disabled in ("0", "1"):
        monkeypatch.setenv("SLAMKIT_NO_NATIVE", disabled)
        f = ErrorStateEKF.from_sequence(seq)
        f.reset()
        assert (f._kernel is None) == (disabled == "1")
        for e in seq:
            f.step(e)
        out.append((f._x.copy(), f.P.copy()))
    np.testing.assert_allclose(out[0][0], out[1][0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out[0][1], out[1][1], rtol=1e-9, atol=1e-15)


def test_a_non_finite_reading_is_an_estimation_error():
    from slamkit.errors import EstimationError

    f = ErrorStateEKF(_setup())
    f.reset()
    with pytest.raises(EstimationError, match="not finite"):
        f.step(Imu(0.01, np.array([0.0, np.nan, 0.0]), -G))
