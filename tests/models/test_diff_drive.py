"""Differential drive: worked examples with stated numbers, the square-path odometry error,
limits of the arc model and hypothesis properties."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import ConfigError
from slamkit.models import diff_drive as dd

finite = st.floats(-5.0, 5.0, allow_nan=False)


def test_worked_example_wheels_2_and_1():
    robot = dd.DiffDrive(wheel_radius_m=0.1, half_axle_m=0.2)
    v, omega = robot.forward(np.array([2.0, 1.0]))  # [right, left]
    assert v == pytest.approx(0.15, abs=1e-15)
    assert omega == pytest.approx(0.25, abs=1e-15)
    np.testing.assert_allclose(robot.inverse([v, omega]), [2.0, 1.0], atol=1e-14)

    origin = np.zeros(3)
    # straight-line (first-order) update: (v dt, 0, omega dt)
    np.testing.assert_allclose(dd.motion_straight(origin, [v, omega], 1.0), [0.15, 0.0, 0.25], atol=1e-15)
    # exact arc: x = (v/w) sin(w t), y = (v/w)(1 - cos(w t)) = 0.6 sin 0.25, 0.6 (1 - cos 0.25)
    exact = dd.motion(origin, [v, omega], 1.0)
    np.testing.assert_allclose(exact, [0.14844237555271375, 0.018652546973613158, 0.25], atol=1e-15)
    # the straight line overshoots x by ~1.6 mm and misses y by ~1.9 cm after one second
    assert 0.15 - exact[0] == pytest.approx(1.5576e-3, abs=1e-7)


def test_square_with_distance_and_heading_error():
    """A 2 m square driven as four (straight 2 m, turn +90 deg) segments, odometry wrong by
    +1 % distance and +0.5 deg heading per segment. Heading error: 4 * 0.5 = 2 deg.
    Position error: the legs are 2.02 m at headings k * 90.5 deg, whose sum is
    2.02 (1 - e^{i 362 deg}) / (1 - e^{i 90.5 deg}), magnitude 2.02 sin(1 deg) / sin(45.25 deg)
    = 0.04964036463349 m, at (0.035557489659278, -0.034638572864313)."""
    for exact in (True, False):  # straight legs and turns on the spot: both integrators agree
        pose = np.zeros(3)
        for _ in range(4):
            pose = dd.integrate_odometry(pose, 2.0 * 1.01, 0.0, exact=exact)
            pose = dd.integrate_odometry(pose, 0.0, np.deg2rad(90.0 + 0.5), exact=exact)
        assert np.rad2deg(pose[2]) == pytest.approx(2.0, abs=1e-9)
        expected_err = 2.02 * np.sin(np.deg2rad(1.0)) / np.sin(np.deg2rad(45.25))
        assert expected_err == pytest.approx(0.04964036463349, abs=1e-13)
        assert np.hypot(pose[0], pose[1]) == pytest.approx(expected_err, abs=1e-9)
        np.testing.assert_allclose(pose[:2], [0.035557489659278, -0.034638572864313], atol=1e-9)


def test_odometry_from_ticks():
    # 1000 ticks/rev, r = 0.1 m: one tick is 2 pi 0.1 / 1000 m
    d, dth = dd.odometry_from_ticks(1000, 500, 1000, 0.1, 0.2)
    assert d == pytest.approx(0.75 * 2 * np.pi * 0.1, rel=1e-14)  # mean of 1 and 0.5 revolutions
    assert dth == pytest.approx(0.5 * 2 * np.pi * 0.1 / 0.4, rel=1e-14)
    # ticks from wheel speeds 2 and 1 rad/s for 1 s reproduce the worked example
    n = 4096
    d, dth = dd.odometry_from_ticks(2 / (2 * np.pi) * n, 1 / (2 * np.pi) * n, n, 0.1, 0.2)
    assert (d, dth) == pytest.approx((0.15, 0.25), abs=1e-14)
    with pytest.raises(ConfigError):
        dd.odometry_from_ticks(1, 1, 0, 0.1, 0.2)


def test_arc_tends_to_straight_line_without_blow_up():
    x0 = np.array([1.0, -2.0, 0.3])
    for w in (0.0, 1e-12, -1e-9, 1e-6):
        got = dd.motion(x0, [1.0, w], 2.0)
        assert np.all(np.isfinite(got))
        np.testing.assert_allclose(got, dd.motion_straight(x0, [1.0, w], 2.0), atol=3 * abs(w) * 4 + 1e-15)
        F, L = dd.motion_jacobians(x0, [1.0, w], 2.0)
        assert np.all(np.isfinite(F)) and np.all(np.isfinite(L))


def test_full_circle_returns_to_start():
    x0 = np.array([0.5, 0.5, 1.0])
    np.testing.assert_allclose(dd.motion(x0, [1.0, 2 * np.pi / 10], 10.0), x0, atol=1e-12)


def test_batch_broadcasts_over_particles():
    rng = np.random.default_rng(0)
    poses = rng.normal(size=(50, 3))
    controls = rng.normal(size=(50, 2))
    batch = dd.motion(poses, controls, 0.1)
    one_by_one = np.array([dd.motion(p, c, 0.1) for p, c in zip(poses, controls)])
    np.testing.assert_allclose(batch, one_by_one, atol=1e-15)
    F, L = dd.motion_jacobians_batch(poses, controls, 0.1)
    assert F.shape == (50, 3, 3) and L.shape == (50, 3, 2)
    F3, L3 = dd.motion_jacobians(poses[3], controls[3], 0.1)
    np.testing.assert_allclose(F[3], F3)
    np.testing.assert_allclose(L[3], L3)
    # one control for all particles
    assert dd.motion(poses, controls[0], 0.1).shape == (50, 3)
    with pytest.raises(ConfigError):
        dd.motion_jacobians_batch(poses[0], controls[0], 0.1)


def test_process_noise_is_L_M_LT_and_psd():
    x, u, dt = np.array([0.0, 0.0, 0.7]), np.array([1.0, 0.4]), 0.5
    M = np.diag([0.1**2, 0.05**2])
    Q = dd.process_noise(x, u, dt, M)
    _, L = dd.motion_jacobians(x, u, dt)
    np.testing.assert_allclose(Q, L @ M @ L.T)
    np.testing.assert_allclose(Q, Q.T)
    assert np.linalg.eigvalsh(Q).min() > -1e-15
    assert np.linalg.matrix_rank(Q, tol=1e-12) == 2  # two noise inputs span a 2-D subspace


def test_bad_config_raises():
    with pytest.raises(ConfigError, match="wheel_radius_m"):
        dd.DiffDrive(wheel_radius_m=0.0)
    with pytest.raises(ConfigError, match="shape"):
        dd.motion(np.zeros(2), [1.0, 0.0], 1.0)


@settings(max_examples=200, deadline=None)
@given(finite, finite)
def test_forward_inverse_round_trip(right, left):
    robot = dd.DiffDrive(0.07, 0.23)
    np.testing.assert_allclose(robot.inverse(robot.forward([right, left])), [right, left], atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(finite, finite, finite, finite, st.floats(0.0, 2.0))
def test_arc_splits_into_two_half_steps(x, theta, v, w, dt):
    """Holding (v, omega) for dt equals holding it twice for dt/2 (the arc model is exact)."""
    x0 = np.array([x, -x, theta])
    one = dd.motion(x0, [v, w], dt)
    two = dd.motion(dd.motion(x0, [v, w], dt / 2), [v, w], dt / 2)
    np.testing.assert_allclose(one[:2], two[:2], atol=1e-9)
    assert abs(np.angle(np.exp(1j * (one[2] - two[2])))) < 1e-9


@settings(max_examples=100, deadline=None)
@given(st.floats(-3, 3), st.floats(-1e-3, 1e-3))
def test_dsinc_matches_finite_difference(z, small):
    for zz in (z, small):
        h = 1e-6
        num = (dd.sinc(zz + h) - dd.sinc(zz - h)) / (2 * h)
        assert dd.dsinc(zz) == pytest.approx(num, abs=1e-8)


@settings(max_examples=150, deadline=None)
@given(st.floats(-3.1, 3.1), st.floats(-2, 2), st.floats(-3, 3), st.floats(0.01, 2.0))
def test_motion_jacobians_match_finite_differences_everywhere(theta, v, w, dt):
    x0, u0, h = np.array([0.2, -0.4, theta]), np.array([v, w]), 1e-6

    def f(x, u):
        return dd.motion(x, u, dt)

    F, L = dd.motion_jacobians(x0, u0, dt)
    for k in range(3):
        e = np.eye(3)[k] * h
        d = f(x0 + e, u0) - f(x0 - e, u0)
        d[2] = np.angle(np.exp(1j * d[2]))
        np.testing.assert_allclose(F[:, k], d / (2 * h), atol=1e-6)
    for k in range(2):
        e = np.eye(2)[k] * h
        d = f(x0, u0 + e) - f(x0, u0 - e)
        d[2] = np.angle(np.exp(1j * d[2]))
        np.testing.assert_allclose(L[:, k], d / (2 * h), atol=1e-6)
