"""Strapdown mechanisation: the 15-state error Jacobians against finite differences, and a
stationary IMU that drifts only as its bias model says."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.geometry import so3
from slamkit.models import strapdown
from slamkit.models.imu import ImuNoise

G = np.array([0.0, 0.0, -9.80665])
DT = 0.01


def _state(rng):
    return (rng.standard_normal(3) * 5, rng.standard_normal(3) * 3, so3.exp(rng.standard_normal(3)),
            rng.standard_normal(3) * 0.1, rng.standard_normal(3) * 0.01)


def _step(p, v, R, ba, bg, accel_m, gyro_m, na=np.zeros(3), ng=np.zeros(3)):
    """One step of the true system with measured inputs, biases and input noise."""
    return strapdown.propagate(p, v, R, accel_m - ba - na, gyro_m - bg - ng, DT, G)


def _error(nominal, true):
    """The 15-dim error (true - nominal) with the world-frame attitude error."""
    (p, v, R, ba, bg), (pt, vt, Rt, bat, bgt) = nominal, true
    return np.concatenate([pt - p, vt - v, so3.log(Rt @ R.T), bat - ba, bgt - bg])


def _central_difference(error_of, n: int, eps: float = 1e-6) -> np.ndarray:
    """(15, n) columns (error_of(+eps e_i) - error_of(-eps e_i)) / (2 eps)."""
    out = np.zeros((15, n))
    for i in range(n):
        d = np.zeros(n)
        d[i] = eps
        out[:, i] = (error_of(d) - error_of(-d)) / (2 * eps)
    return out


def _perturb(x, dx):
    p, v, R, ba, bg = x
    return (p + dx[0:3], v + dx[3:6], so3.exp(dx[6:9]) @ R, ba + dx[9:12], bg + dx[12:15])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_error_transition_matches_finite_differences(seed):
    """Each column of F is (error after one step of a state perturbed by eps e_i) / eps, to
    within 1e-6 of its entries' scale (central differences, eps = 1e-6)."""
    rng = np.random.default_rng(seed)
    x = _state(rng)
    accel_m = np.array([0.5, -0.3, 9.9]) + rng.standard_normal(3)
    gyro_m = rng.standard_normal(3) * 0.8
    p, v, R = _step(*x, accel_m, gyro_m)
    nominal = (p, v, R, x[3], x[4])
    F = strapdown.error_transition(x[2], accel_m - x[3], gyro_m - x[4], DT)

    def error_of(dx):
        xt = _perturb(x, dx)
        return _error(nominal, (*_step(*xt, accel_m, gyro_m), xt[3], xt[4]))

    np.testing.assert_allclose(F, _central_difference(error_of, 15), atol=1e-7)


def test_noise_jacobian_matches_finite_differences():
    """G maps (n_a, n_g, w_ba, w_bg) of one step into the error state (central differences)."""
    rng = np.random.default_rng(5)
    x = _state(rng)
    accel_m, gyro_m = np.array([0.2, 0.1, 9.7]), np.array([0.3, -0.2, 0.5])
    p, v, R = _step(*x, accel_m, gyro_m)
    nominal = (p, v, R, x[3], x[4])
    Gm = strapdown.noise_jacobian(x[2], gyro_m - x[4], DT)

    def error_of(n):
        return _error(nominal, (*_step(*x, accel_m, gyro_m, na=n[0:3], ng=n[3:6]), x[3] + n[6:9], x[4] + n[9:12]))

    np.testing.assert_allclose(Gm, _central_difference(error_of, 12), atol=1e-9)


def test_process_noise_of_a_level_step():
    """Level attitude, no rotation: Q_d has velocity variance sigma_a^2 dt, attitude sigma_g^2 dt,
    position sigma_a^2 dt^3 / 4, bias steps sigma_b^2 dt (worked numbers)."""
    noise = ImuNoise(gyro_noise_density=0.01, gyro_bias_random_walk=0.001, accel_noise_density=0.1,
                     accel_bias_random_walk=0.02)
    Q = strapdown.process_noise(noise, np.eye(3), np.zeros(3), DT)
    np.testing.assert_allclose(np.diag(Q)[[0, 3, 6, 9, 12]],
                               [0.1**2 * DT**3 / 4, 0.1**2 * DT, 0.01**2 * DT, 0.02**2 * DT, 0.001**2 * DT])
    assert Q[0, 3] == pytest.approx(0.1**2 * DT**2 / 2)


def test_stationary_imu_does_not_drift_and_a_bias_drifts_as_half_b_t_squared():
    """A level IMU at rest reading -g stays at rest to rounding over 100 s at 100 Hz; an
    uncompensated accelerometer bias b along x gives x = b t^2 / 2 exactly (constant inputs), and
    a gyro bias about z rotates the heading by b t."""
    n = 10_000
    f = -G
    p, v, R = np.zeros(3), np.zeros(3), np.eye(3)
    for _ in range(n):
        p, v, R = strapdown.propagate(p, v, R, f, np.zeros(3), DT, G)
    assert np.abs(p).max() < 1e-9 and np.abs(v).max() < 1e-11 and so3.angle(R) < 1e-12
    b = 0.01
    p, v, R = np.zeros(3), np.zeros(3), np.eye(3)
    for _ in range(n):
        p, v, R = strapdown.propagate(p, v, R, f + [b, 0, 0], np.zeros(3), DT, G)
    T = n * DT
    assert p[0] == pytest.approx(0.5 * b * T**2, rel=1e-9)
    assert v[0] == pytest.approx(b * T, rel=1e-9)
    R = np.eye(3)
    for _ in range(1000):
        R = strapdown.propagate(p, v, R, f, np.array([0.0, 0.0, 1e-3]), DT, G)[2]
    assert so3.yaw(R) == pytest.approx(1e-3 * 10.0, rel=1e-9)
