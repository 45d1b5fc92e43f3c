"""Inertial scores: position error at withheld GPS fixes and bias consistency (worked numbers)."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data.trajectory import Trajectory
from slamkit.metrics.inertial import bias_metrics, outage_metrics, position_at


def _line():
    """x = 2 t m for t = 0 ... 10 s at 1 Hz, identity attitude."""
    t = np.arange(11.0)
    return Trajectory(t, np.column_stack([2 * t, np.zeros(11), np.zeros(11)]), np.tile([1.0, 0, 0, 0], (11, 1)))


def test_position_is_interpolated_between_poses():
    np.testing.assert_allclose(position_at(_line(), [0.5, 9.25]), [[1.0, 0, 0], [18.5, 0, 0]])


def test_outage_errors_worked_example():
    """Two windows; fixes off the estimate by 3, 4 (window 0) and 0, 1, 2 m (window 1): RMSE
    sqrt((9 + 16 + 0 + 1 + 4) / 5) = sqrt(6), end errors 4 and 2 -> mean 3, max 4."""
    withheld = {"stamps_s": np.array([1.5, 2.5, 6.0, 7.0, 8.0]),
                "world_p_body": np.array([[3.0, 3, 0], [5.0, 0, 4], [12.0, 0, 0], [14.0, 1, 0], [16.0, 0, -2]]),
                "window": np.array([0, 0, 1, 1, 1]), "windows_s": np.array([[1.0, 3.0], [5.5, 8.5]])}
    m = outage_metrics(_line(), withheld)
    assert m["outage_rmse_m"] == pytest.approx(np.sqrt(6.0))
    assert m["outage_end_error_mean_m"] == pytest.approx(3.0)
    assert m["outage_max_error_m"] == pytest.approx(4.0) and m["outage_windows"] == 2


def test_bias_metrics_worked_example():
    """Truth: accel bias (0.1, 0, 0), gyro 0; estimate off by 0.02 m/s^2 in x and 0.002 rad/s in
    z with sigmas 0.01 and 0.001: final errors 0.02 and 0.002, every component within 3 sigma
    (both off ones at 2 sigma); with half the sigmas the two are at 4 sigma: 4 of 6 within."""
    stamps = np.array([1.0, 2.0])
    truth = {"stamps_s": np.array([0.5, 1.5]), "accel_mps2": np.tile([0.1, 0, 0], (2, 1)),
             "gyro_radps": np.zeros((2, 3))}
    bias = np.tile([0.12, 0, 0, 0, 0, 0.002], (2, 1))
    sigma = np.tile([0.01, 0.01, 0.01, 0.001, 0.001, 0.001], (2, 1))
    m = bias_metrics(stamps, bias, sigma, truth)
    assert m["accel_bias_final_error_mps2"] == pytest.approx(0.02)
    assert m["gyro_bias_final_error_radps"] == pytest.approx(0.002)
    assert m["bias_within_3sigma_fraction"] == pytest.approx(1.0)
    m = bias_metrics(stamps, bias, sigma / 2, truth)
    assert m["bias_within_3sigma_fraction"] == pytest.approx(4 / 6)
