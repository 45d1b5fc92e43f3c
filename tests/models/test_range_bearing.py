"""Range-bearing model: worked example, inverse round trip, and the simulated sensor's field of
view, range limit, dropout rate and noise statistics."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import ConfigError
from slamkit.models import range_bearing as rb


def test_worked_example():
    # robot at (1, 1) facing +y; landmark at (4, 5): range 5, world angle atan2(4, 3)
    z = rb.observe([1.0, 1.0, np.pi / 2], [4.0, 5.0])
    assert z[0] == pytest.approx(5.0, abs=1e-15)
    assert z[1] == pytest.approx(np.arctan2(4.0, 3.0) - np.pi / 2, abs=1e-15)  # -0.6435 rad, to the right
    H_pose, H_lm = rb.observe_jacobians([1.0, 1.0, np.pi / 2], [4.0, 5.0])
    np.testing.assert_allclose(H_pose, [[-0.6, -0.8, 0.0], [0.16, -0.12, -1.0]], atol=1e-15)
    np.testing.assert_allclose(H_lm, [[0.6, 0.8], [-0.16, 0.12]], atol=1e-15)


def test_bearing_is_wrapped():
    z = rb.observe([0.0, 0.0, 3.0], [-1.0, -0.1])  # atan2 ~ -3.04, minus 3 -> -6.04 -> +0.24
    assert -np.pi <= z[1] < np.pi
    assert z[1] == pytest.approx(np.arctan2(-0.1, -1.0) - 3.0 + 2 * np.pi, abs=1e-14)


@settings(max_examples=200, deadline=None)
@given(st.floats(-10, 10), st.floats(-10, 10), st.floats(-4, 4), st.floats(0.1, 30), st.floats(-3.1, 3.1))
def test_inverse_observe_round_trip(x, y, theta, r, b):
    pose = np.array([x, y, theta])
    m = rb.inverse_observe(pose, [r, b])
    z = rb.observe(pose, m)
    assert z[0] == pytest.approx(r, abs=1e-9)
    assert abs(np.angle(np.exp(1j * (z[1] - b)))) < 1e-9


def test_batch_shapes():
    poses = np.zeros((7, 3))
    lms = np.arange(14, dtype=float).reshape(7, 2) + 1
    assert rb.observe(poses, lms).shape == (7, 2)
    assert rb.observe(poses[:, None, :], lms[None, :, :]).shape == (7, 7, 2)  # particles x landmarks
    Hp, Hl = rb.observe_jacobians(poses[:, None, :], lms[None, :, :])
    assert Hp.shape == (7, 7, 2, 3) and Hl.shape == (7, 7, 2, 2)


def test_sensor_fov_range_and_dropout():
    sensor = rb.RangeBearingSensor(sigma_range_m=0.0, sigma_bearing_rad=0.0,
                                   fov_rad=np.deg2rad(90), max_range_m=10.0)
    lms = np.array([[5.0, 0.0], [5.0, 4.0], [5.0, 6.0], [-5.0, 0.0], [11.0, 0.0]])
    # bearings 0, 38.7 deg (in fov), 50.2 deg (out), 180 deg (behind), range 11 (too far)
    ids, r, b = sensor.measure(np.random.default_rng(1), [0.0, 0.0, 0.0], lms, [10, 11, 12, 13, 14])
    np.testing.assert_array_equal(ids, [10, 11])
    np.testing.assert_allclose(r, [5.0, np.hypot(5, 4)])
    np.testing.assert_allclose(b, [0.0, np.arctan2(4, 5)])

    lossy = rb.RangeBearingSensor(dropout_prob=0.3, max_range_m=100.0)
    grid = np.stack(np.meshgrid(np.arange(1, 41.0), np.arange(1, 26.0)), -1).reshape(-1, 2)  # 1000
    ids, _, _ = lossy.measure(np.random.default_rng(2), [0.0, 0.0, 0.0], grid, np.arange(1000))
    # 700 expected kept, binomial sd = sqrt(1000 * 0.3 * 0.7) = 14.5; allow 4 sd
    assert abs(len(ids) - 700) < 4 * 14.5


def test_sensor_noise_statistics_and_seed():
    sensor = rb.RangeBearingSensor(sigma_range_m=0.2, sigma_bearing_rad=0.05, max_range_m=100)
    lms = np.tile([[3.0, 4.0]], (20000, 1))
    ids, r, b = sensor.measure(np.random.default_rng(3), [0.0, 0.0, 0.0], lms, np.arange(20000))
    # standard error of a standard deviation estimate with n = 20000 is sigma / sqrt(2n) = 0.5 %
    assert r.mean() == pytest.approx(5.0, abs=4 * 0.2 / np.sqrt(20000))
    assert r.std() == pytest.approx(0.2, rel=0.02)
    assert b.std() == pytest.approx(0.05, rel=0.02)
    again = sensor.measure(np.random.default_rng(3), [0.0, 0.0, 0.0], lms, np.arange(20000))
    np.testing.assert_array_equal(again[1], r)
    np.testing.assert_allclose(sensor.covariance, np.diag([0.04, 0.0025]))


def test_sensor_bad_input():
    with pytest.raises(ConfigError, match="dropout_prob"):
        rb.RangeBearingSensor(dropout_prob=1.5)
    with pytest.raises(ConfigError, match="landmark_ids"):
        rb.RangeBearingSensor().measure(np.random.default_rng(0), np.zeros(3), np.ones((3, 2)), [1, 2])
