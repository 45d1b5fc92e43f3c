"""Strapdown mechanisation: the discrete process noise, and a stationary IMU that drifts only as
its bias model says. (Its error Jacobians F and G are a case of the finite-difference contract,
tests/models/test_model_jacobians.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.geometry import so3
from slamkit.models import strapdown
from slamkit.models.imu import ImuNoise

G = np.array([0.0, 0.0, -9.80665])
DT = 0.01


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
