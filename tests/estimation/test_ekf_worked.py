"""EKF building blocks on the course's worked example, and the generic EKF on a linear system
(where it must coincide with the Kalman filter)."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.estimation.ekf import ExtendedKalmanFilter, ekf_predict
from slamkit.estimation.kalman import KalmanFilter
from slamkit.models import diff_drive, range_bearing


def test_predict_worked_example():
    x0 = np.zeros(3)
    u = np.array([1.0, 0.0])
    F, L = diff_drive.motion_jacobians(x0, u, 0.1)
    x1, P1 = ekf_predict(x0, np.zeros((3, 3)), lambda s: diff_drive.motion(s, u, 0.1), F, np.zeros((3, 3)))
    np.testing.assert_allclose(x1, [0.1, 0.0, 0.0], atol=1e-15)
    # "F with 0.1 in row 2, column 3" (one-based)
    assert F[1, 2] == pytest.approx(0.1)
    np.testing.assert_allclose(F, [[1, 0, 0], [0, 1, 0.1], [0, 0, 1]], atol=1e-15)


def test_range_bearing_worked_example():
    z = range_bearing.observe(np.array([0.5, 0.0, 0.05]), np.array([4.0, 3.0]))
    assert round(float(z[0]), 2) == 4.61
    # atan2(3, 3.5) - 0.05 (the course text's 0.709 forgets to subtract the heading)
    assert float(z[1]) == pytest.approx(np.arctan2(3, 3.5) - 0.05)
    assert round(float(z[1]), 3) == 0.659


def test_generic_ekf_equals_kf_on_a_linear_model():
    A = np.array([[1.0, 0.1], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    Q, R = np.eye(2) * 0.01, np.eye(1) * 0.2
    ekf = ExtendedKalmanFilter(lambda x, u: A @ x, lambda x, u: A, lambda x: H @ x, lambda x: H, Q, R)
    kf = KalmanFilter(A, H, Q, R)
    ekf.x, ekf.P = np.array([1.0, -1.0]), np.eye(2)
    kf.reset([1.0, -1.0], np.eye(2))
    for z in (0.9, 0.7, 0.8, 0.4):
        ekf.predict(None)
        kf.predict()
        ekf.update(np.array([z]))
        kf.update([z])
    np.testing.assert_allclose(ekf.x, kf.mean, atol=1e-12)
    np.testing.assert_allclose(ekf.P, kf.covariance, atol=1e-12)
