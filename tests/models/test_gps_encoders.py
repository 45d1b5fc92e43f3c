"""GPS fixes (lever arm, presets, Gauss-Markov error) and encoder quantisation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import ConfigError
from slamkit.models import diff_drive as dd
from slamkit.models import gps
from slamkit.models.encoders import Encoder, angle_from_ticks, ticks_from_angle


def test_gps_lever_arm_worked_example():
    # antenna 0.5 m ahead of the body origin; robot at (10, 20) facing +y: antenna at (10, 20.5)
    np.testing.assert_allclose(gps.observe([10.0, 20.0, np.pi / 2], (0.5, 0.0)), [10.0, 20.5], atol=1e-15)
    np.testing.assert_allclose(gps.observe_jacobian([10.0, 20.0, np.pi / 2], (0.5, 0.0)),
                               [[1, 0, -0.5], [0, 1, 0.0]], atol=1e-15)


def test_gps_presets_and_statistics():
    assert gps.GPS_PRESETS["consumer"].sigma_m > gps.GPS_PRESETS["dgps"].sigma_m > gps.GPS_PRESETS["rtk"].sigma_m
    rtk = gps.Gps.preset("rtk")
    assert (rtk.sigma_m, rtk.rate_hz) == (0.02, 10.0)
    np.testing.assert_allclose(rtk.covariance, np.eye(2) * 4e-4)
    assert gps.Gps.preset("consumer", rate_hz=5.0).rate_hz == 5.0
    with pytest.raises(ConfigError, match="unknown GPS preset"):
        gps.Gps.preset("galileo_hp")
    poses = np.zeros((20000, 3))
    fixes = gps.Gps(sigma_m=2.0).simulate_fixes(np.random.default_rng(0), poses, np.arange(20000.0))
    assert fixes.std(axis=0) == pytest.approx([2.0, 2.0], rel=0.03)  # SE of a std with n = 2e4: 0.5 %


def test_gps_gauss_markov_correlation():
    """Stationary sigma is kept, and the lag-k autocorrelation is exp(-k dt / tau)."""
    unit = gps.Gps(sigma_m=1.0, correlation_time_s=10.0)
    t = np.arange(200000) * 1.0
    err = unit.simulate_fixes(np.random.default_rng(1), np.zeros((len(t), 3)), t)[:, 0]
    assert err.std() == pytest.approx(1.0, rel=0.05)
    for lag in (1, 5, 10):
        rho = np.corrcoef(err[:-lag], err[lag:])[0, 1]
        assert rho == pytest.approx(np.exp(-lag / 10.0), abs=0.02)


def test_encoder_quantisation_numbers():
    enc = Encoder(ticks_per_rev=1000)
    assert enc.resolution_rad == pytest.approx(2 * np.pi / 1000)
    assert ticks_from_angle(2 * np.pi, 1000) == 1000  # exactly one revolution
    assert ticks_from_angle(-1e-6, 1000) == -1
    # 2 rad/s and 1 rad/s for 1 s on a 4096-tick encoder: floor(1303.797) = 1303, floor(651.899) = 651
    right, left = ticks_from_angle([2.0, 1.0], 4096)
    assert (right, left) == (1303, 651)
    d, dth = dd.odometry_from_ticks(right, left, 4096, 0.1, 0.2)
    # d = 977 ticks * 2 pi 0.1 / 4096 m, dtheta = 652 ticks * 2 pi 0.1 / 4096 / 0.4 rad, against
    # the true 0.15 m and 0.25 rad: quantisation costs at most one tick (1.5e-4 m) per wheel
    assert d == pytest.approx(0.14986992297642715, abs=1e-15)
    assert dth == pytest.approx(0.2500388684253595, abs=1e-15)
    assert abs(d - 0.15) < 2 * np.pi * 0.1 / 4096


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-50.0, 50.0), min_size=2, max_size=30), st.integers(8, 5000))
def test_encoder_counts_do_not_drift(angles, n):
    angles = np.sort(np.asarray(angles))
    inc = Encoder(ticks_per_rev=n).interval_ticks(None, angles)
    # cumulative counter: increments sum to the last minus the first reading, so the total
    # error is one tick at most however many reads there are
    total = angle_from_ticks(inc.sum(), n)
    assert abs(total - (angles[-1] - angles[0])) <= 2 * np.pi / n * (1 + 1e-9) + 1e-12


def test_encoder_quantisation_variance():
    enc = Encoder(ticks_per_rev=64)
    phi = np.random.default_rng(2).uniform(0, 100, 200000)
    err = phi - angle_from_ticks(ticks_from_angle(phi, 64), 64)
    assert np.all((err >= -1e-9) & (err < enc.resolution_rad))
    assert err.var() == pytest.approx(enc.quantisation_variance_rad2, rel=0.02)


def test_gps_irregular_stamps_match_the_uniform_filter():
    """The lfilter path (uniform rate) and the explicit recursion (irregular stamps) agree."""
    unit = gps.Gps(sigma_m=1.0, correlation_time_s=5.0)
    t = np.arange(50) * 0.5
    t_jitter = t.copy()
    t_jitter[-1] += 1e-3  # breaks uniformity only at the last step
    a = unit.simulate_fixes(np.random.default_rng(3), np.zeros((50, 3)), t)
    b = unit.simulate_fixes(np.random.default_rng(3), np.zeros((50, 3)), t_jitter)
    np.testing.assert_allclose(a[:-1], b[:-1], atol=1e-12)
