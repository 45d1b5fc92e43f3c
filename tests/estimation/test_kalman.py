"""Linear Kalman filter: the course's 1D worked example and the DARE steady state."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import EstimationError
from slamkit.estimation.kalman import KalmanFilter, kf_predict, kf_update, steady_state_gain


def test_1d_worked_example():
    # mu0 = 0, Sigma0 = 1, u = 0.5, Q = 0.01, R = 0.1, z = 0.6
    mu, Sigma = kf_predict(0.0, 1.0, A=1.0, Q=0.01, B=1.0, u=0.5)
    assert mu[0] == pytest.approx(0.5)
    assert Sigma[0, 0] == pytest.approx(1.01)
    up = kf_update(mu, Sigma, 0.6, H=1.0, R=0.1)
    assert round(float(up.gain[0, 0]), 2) == 0.91
    assert round(float(up.mean[0]), 3) == 0.591
    assert round(float(up.covariance[0, 0]), 3) == 0.091
    # exact values: K = 1.01 / 1.11
    assert up.gain[0, 0] == pytest.approx(1.01 / 1.11)
    assert up.nis == pytest.approx(0.1**2 / 1.11)


def test_steady_state_gain_is_the_limit_of_the_recursion():
    # constant-velocity model, position measured
    dt = 0.1
    A = np.array([[1, dt], [0, 1]])
    H = np.array([[1.0, 0.0]])
    Q = 0.01 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    R = np.array([[0.25]])
    K_inf, P_inf = steady_state_gain(A, H, Q, R)
    kf = KalmanFilter(A, H, Q, R)
    kf.reset([0, 0], np.eye(2) * 10)
    for _ in range(2000):
        kf.predict()
        P_pred = kf.covariance.copy()
        gain = kf.update([0.0]).gain
    np.testing.assert_allclose(P_pred, P_inf, rtol=1e-8)
    np.testing.assert_allclose(gain, K_inf, rtol=1e-8)
    # DARE residual: P = A P A^T - A P H^T S^-1 H P A^T + Q
    S = H @ P_inf @ H.T + R
    rhs = A @ P_inf @ A.T - A @ P_inf @ H.T @ np.linalg.solve(S, H @ P_inf @ A.T) + Q
    np.testing.assert_allclose(P_inf, rhs, atol=1e-12)


def test_steady_state_filter_reaches_the_same_covariance():
    A, H, Q, R = np.eye(1) * 0.9, np.eye(1), np.eye(1) * 0.5, np.eye(1) * 2.0
    K_inf, P_inf = steady_state_gain(A, H, Q, R)
    kf = KalmanFilter(A, H, Q, R, steady_state=True)
    kf.reset([3.0], [[50.0]])
    for _ in range(200):
        kf.predict()
        kf.update([0.0])
    # posterior covariance under the steady-state gain: (1 - K) P_inf
    assert kf.covariance[0, 0] == pytest.approx((1 - K_inf[0, 0]) * P_inf[0, 0], rel=1e-9)


def test_undetectable_system_raises():
    # unstable mode that is not observed: no stabilising solution
    A = np.diag([2.0, 0.5])
    H = np.array([[0.0, 1.0]])
    with pytest.raises(EstimationError):
        steady_state_gain(A, H, np.eye(2) * 0.0, np.eye(1))


@settings(max_examples=60, deadline=None)
@given(st.floats(0.01, 10), st.floats(0.001, 5), st.floats(0.001, 5), st.floats(-5, 5))
def test_joseph_update_is_optimal_and_positive(sigma0, q, r, z):
    mu, P = kf_predict(0.0, sigma0, 1.0, q)
    up = kf_update(mu, P, z, 1.0, r)
    # scalar case closed form: posterior variance = P r / (P + r)
    assert up.covariance[0, 0] == pytest.approx(P[0, 0] * r / (P[0, 0] + r), rel=1e-9)
    assert 0 < up.covariance[0, 0] <= P[0, 0]
