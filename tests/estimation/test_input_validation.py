"""Filters and smoothers check what they are given (issue 10): priors finite with a symmetric
positive semidefinite covariance, noise covariances positive definite, measurements finite."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data.estimate import Prior
from slamkit.data.sequence import Gps, Odometry, RangeBearing
from slamkit.errors import EstimationError
from slamkit.estimation.kalman import KalmanFilter
from slamkit.experiments.estimators import REGISTRY, factory
from slamkit.sim.inertial_world import PRESETS as INERTIAL_PRESETS, simulate_inertial_sequence
from slamkit.sim.landmark_world import mildly_nonlinear, simulate_landmark_sequence

SEQ = simulate_landmark_sequence(mildly_nonlinear(duration_s=2.0), np.random.default_rng(0))
#: the inertial estimators (es_ekf, isam2_imu, fixed_lag_imu) are built for an IMU + GPS sequence
INERTIAL_SEQ = simulate_inertial_sequence(INERTIAL_PRESETS["car3d"](duration_s=2.0), np.random.default_rng(0))
GOOD = Prior(np.zeros(3), np.diag([1e-4, 1e-4, 1e-4]))


@pytest.mark.parametrize("cov, text", [
    (np.array([[1.0, 0.5, 0], [0.0, 1.0, 0], [0, 0, 1.0]]), "prior covariance is not symmetric"),
    (np.diag([1.0, -1.0, 1.0]), r"prior covariance is not positive semidefinite \(eigenvalues \[-1\.0, 1\.0, 1\.0\]\)"),
    (np.diag([1.0, np.nan, 1.0]), "prior contains NaN or infinite values"),
])
def test_a_bad_prior_is_refused_when_it_is_made(cov, text) -> None:
    with pytest.raises(EstimationError, match=text):
        Prior(np.zeros(3), cov)
    assert Prior(np.zeros(3), np.zeros((3, 3))).covariance.shape == (3, 3)  # an exactly known start


@pytest.mark.parametrize("name", list(REGISTRY))
@pytest.mark.parametrize("event, text", [
    (Odometry(0.1, 0.1, np.nan, 0.0), r"Odometry at t=0\.1: \(v, omega\) = \(nan, 0\.0\) is not finite"),
    (Odometry(0.1, -0.1, 1.0, 0.0), r"Odometry at t=0\.1: dt_s=-0\.1 must be finite and >= 0"),
    (RangeBearing(0.1, np.array([0]), np.array([np.inf]), np.array([0.0])), "RangeBearing at t=0.1: a range or bearing is not finite"),
    (Gps(0.1, np.array([0.0, 0.0]), 0.0), r"Gps at t=0\.1: sigma_m=0\.0 must be finite and > 0"),
])
def test_every_estimator_refuses_a_non_finite_measurement(name, event, text) -> None:
    est = factory(name)(INERTIAL_SEQ if REGISTRY[name].sequence_kind == "inertial" else SEQ)
    if not hasattr(est, "step"):
        pytest.skip("batch estimators solve a whole sequence")
    est.reset(GOOD)
    with pytest.raises(EstimationError, match=f"{name}: {text}"):
        est.step(event)


def test_kalman_filter_noise_must_be_a_covariance() -> None:
    A = H = np.eye(2)
    with pytest.raises(EstimationError, match="KF measurement noise R is not positive definite"):
        KalmanFilter(A, H, np.eye(2), np.diag([1.0, 0.0]))
    with pytest.raises(EstimationError, match="KF process noise Q is not positive semidefinite"):
        KalmanFilter(A, H, np.diag([1.0, -1.0]), np.eye(2))
    KalmanFilter(A, H, np.zeros((2, 2)), np.eye(2))  # no process noise is allowed
