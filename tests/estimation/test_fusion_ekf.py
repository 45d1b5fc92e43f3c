"""The 5-state multi-rate fusion EKF (issue 13 part 1): Jacobians against finite differences,
worked updates with the numbers written out, the late-event rule, and the wheel-odometry
baseline."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data.estimate import Prior
from slamkit.data.sequence import Imu, WheelEncoders
from slamkit.errors import ConfigError
from slamkit.estimation.fusion_ekf import (FusionEKF, FusionEkfConfig, PoseFix, WheelCalibration, motion,
                                           motion_jacobians)
from slamkit.estimation.wheel_odometry import WheelOdometry

CAL = WheelCalibration(ticks_per_rev=4096, wheel_radius_m=0.1, half_axle_m=0.2)


def _numeric(f, x0: np.ndarray, eps: float = 1e-7) -> np.ndarray:
    cols = []
    for k in range(len(x0)):
        d = np.zeros(len(x0))
        d[k] = eps
        cols.append((f(x0 + d) - f(x0 - d)) / (2 * eps))
    return np.column_stack(cols)


@pytest.mark.parametrize("seed", range(5))
def test_the_5_state_jacobians_match_finite_differences(seed) -> None:
    rng = np.random.default_rng(seed)
    x = np.array([*rng.uniform(-5, 5, 2), rng.uniform(-3, 3), rng.uniform(-1, 1), rng.uniform(-1, 1)])
    u = rng.uniform(-1, 1, 2)
    dt = 0.005
    F, G = motion_jacobians(x, u, dt)
    assert np.allclose(F, _numeric(lambda s: motion(s, u, dt), x), atol=1e-8)
    assert np.allclose(G, _numeric(lambda v: motion(x, v, dt), u), atol=1e-8)
    assert F.shape == (5, 5) and G.shape == (5, 2)


def _filter(config: FusionEkfConfig = FusionEkfConfig(), cov=np.diag([0.03, 0.01, 0.001])) -> FusionEKF:
    ekf = FusionEKF(CAL, config)
    ekf.reset(Prior(np.array([1.0, 2.0, 0.1]), cov))
    return ekf


def test_worked_pose_fix_update() -> None:
    # no process noise and no time step: the pose block is the prior's, diag(0.03, 0.01, 0.001);
    # R_lidar = diag(0.01, 0.01, 0.001), so the gains are 0.75, 0.5, 0.5
    ekf = _filter()
    ekf.step(PoseFix(0.0, np.array([1.4, 1.8, 0.14])))
    x = ekf.state
    assert x[:3] == pytest.approx([1.0 + 0.75 * 0.4, 2.0 - 0.5 * 0.2, 0.1 + 0.5 * 0.04])
    assert np.diag(ekf.covariance)[:3] == pytest.approx([0.0075, 0.005, 0.0005])
    # the NIS of the innovation (0.4, -0.2, 0.04) with S = diag(0.04, 0.02, 0.002)
    assert ekf.estimate().nis[-1] == pytest.approx(0.16 / 0.04 + 0.04 / 0.02 + 0.0016 / 0.002)
    # the heading innovation is wrapped: a fix at theta = 2 pi + 0.14 is the same fix
    again = _filter()
    again.step(PoseFix(0.0, np.array([1.4, 1.8, 2 * np.pi + 0.14])))
    assert again.state == pytest.approx(x)


def test_worked_encoder_update() -> None:
    # 2 ms after the first reading both wheels turned 20 ticks: v = 20 * 2 pi 0.1 / 4096 / 0.002 m/s,
    # omega = 0; the prior on (v, omega) is diag(0.1^2, 0.1^2) and R_enc = diag(0.001, 0.001)
    cfg = FusionEkfConfig(accel_sigma_mps2=0.0, gyro_sigma_radps=0.0, v_random_walk=0.0,
                          omega_random_walk=0.0, pose_random_walk=(0.0, 0.0, 0.0))
    ekf = _filter(cfg)
    ekf.step(WheelEncoders(0.0, 0, 0))
    ekf.step(WheelEncoders(0.002, 20, 20))
    v_meas = 20 * 2 * np.pi * 0.1 / 4096 / 0.002
    gain = 0.01 / (0.01 + 0.001)
    assert ekf.state[3] == pytest.approx(gain * v_meas)
    assert ekf.state[4] == pytest.approx(0.0)
    assert ekf.covariance[3, 3] == pytest.approx(0.01 * 0.001 / 0.011)
    # the 2 ms prediction before the update made x and v correlated (F[x, v] = cos(theta) dt),
    # so the update also moves the pose by v dt along the heading: the rate is the interval's mean
    v = gain * v_meas
    assert ekf.state[:2] == pytest.approx([1.0 + v * np.cos(0.1) * 0.002, 2.0 + v * np.sin(0.1) * 0.002])
    # IMU samples at 5 and 10 ms move it on by v dt and turn it by omega dt
    ekf.step(Imu(0.005, np.array([0.0, 0.0, 0.2]), np.array([0.5, 0.0, 9.81])))
    ekf.step(Imu(0.010, np.array([0.0, 0.0, 0.2]), np.array([0.5, 0.0, 9.81])))
    assert ekf.state[:2] == pytest.approx([1.0 + v * np.cos(0.1) * 0.010, 2.0 + v * np.sin(0.1) * 0.010])
    assert ekf.state[2] == pytest.approx(0.1 + 0.2 * 0.005)  # the first sample has only been held
    assert ekf.state[3] == pytest.approx(v + 0.5 * 0.005)


def _events(n: int = 400) -> list:
    """A drive: IMU at 200 Hz, encoders at 500 Hz, a pose fix every 0.1 s."""
    rng = np.random.default_rng(0)
    out = []
    for k in range(1, n + 1):
        t = k * 0.002
        out.append(WheelEncoders(t, int(20 + rng.integers(-1, 2)), int(22 + rng.integers(-1, 2))))
        if k % 5 == 0:
            out.append(Imu(t, np.array([0, 0, 0.1 + 0.01 * rng.standard_normal()]),
                           np.array([0.05 * rng.standard_normal(), 0, 9.81])))
        if k % 50 == 0:
            out.append(PoseFix(t, np.array([1.0 + 0.8 * t, 2.0, 0.1 + 0.1 * t])))
    return out


def _run(events) -> FusionEKF:
    ekf = _filter()
    for e in events:
        ekf.step(e)
    return ekf


def test_a_late_event_inside_the_window_is_replayed_exactly() -> None:
    events = _events()
    in_order = _run(events)
    # the pose fix at t = 0.4 s arrives after the events of the next 0.3 s
    k = next(i for i, e in enumerate(events) if isinstance(e, PoseFix) and abs(e.stamp_s - 0.4) < 1e-9)
    late = events[:k] + events[k + 1:k + 1 + 200] + [events[k]] + events[k + 1 + 200:]
    assert late[k + 200].stamp_s < late[k + 199].stamp_s - 0.25
    replayed = _run(late)
    assert replayed.state == pytest.approx(in_order.state, abs=1e-12)
    assert replayed.covariance == pytest.approx(in_order.covariance, abs=1e-15)
    extras = replayed.estimate().extras
    assert (extras["late_replayed"], extras["late_dropped"]) == (1, 0)


def test_a_late_event_beyond_the_window_is_dropped_and_counted() -> None:
    events = _events()
    k = next(i for i, e in enumerate(events) if isinstance(e, PoseFix) and abs(e.stamp_s - 0.1) < 1e-9)
    without = _run(events[:k] + events[k + 1:])
    late = _run(events[:k] + events[k + 1:] + [events[k]])  # 0.7 s late, window 0.5 s
    assert late.state == pytest.approx(without.state, abs=0)
    extras = late.estimate().extras
    assert (extras["late_replayed"], extras["late_dropped"]) == (0, 1)
    # the trajectory stays in time order (the late event refreshes the newest row)
    assert np.all(np.diff(late.estimate().trajectory.stamps_s) > 0)


def test_encoders_without_a_calibration_are_a_config_error() -> None:
    ekf = FusionEKF(None)
    ekf.reset(Prior(np.zeros(3), np.eye(3) * 1e-6))
    ekf.step(WheelEncoders(0.0, 0, 0))
    with pytest.raises(ConfigError, match="wheel calibration"):
        ekf.step(WheelEncoders(0.002, 1, 1))
    with pytest.raises(ConfigError, match="lidar_noise"):
        FusionEkfConfig(lidar_noise="icp")


def test_wheel_odometry_integrates_ticks_along_the_arc() -> None:
    # a quarter circle of radius 1 m: the right wheel rolls (1 + l) pi / 2, the left (1 - l) pi / 2
    per_tick = 2 * np.pi * CAL.wheel_radius_m / CAL.ticks_per_rev
    right, left = round(1.2 * np.pi / 2 / per_tick / 100), round(0.8 * np.pi / 2 / per_tick / 100)
    odo = WheelOdometry(CAL)
    odo.reset(Prior(np.zeros(3), np.zeros((3, 3))))
    for k in range(100):
        odo.step(WheelEncoders(0.01 * (k + 1), left, right))
    est = odo.estimate()
    pose = est.trajectory.xytheta()[-1]
    assert pose == pytest.approx([1.0, 1.0, np.pi / 2], abs=2e-3)
    # the covariance grows with the distance rolled and stays symmetric positive definite
    P = est.pose_covariances[-1]
    assert np.all(np.linalg.eigvalsh(P) > 0) and P[0, 0] > est.pose_covariances[10][0, 0]
