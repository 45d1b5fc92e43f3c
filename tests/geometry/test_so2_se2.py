"""SO(2)/SE(2): worked example, group axioms and exp/log round trips (hypothesis)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from slamkit.geometry import angles, se2, so2, wrap_angle

finite = st.floats(-50.0, 50.0, allow_nan=False)
angle = st.floats(-np.pi, np.pi, allow_nan=False, exclude_max=True)
pose = st.tuples(finite, finite, angle).map(np.array)
# the interior of the principal branch plus tiny angles, where log is the inverse of exp
small = st.floats(-1e-8, 1e-8)
omega = st.one_of(st.floats(-np.pi + 1e-6, np.pi - 1e-6), small)
tangent = st.tuples(finite, finite, omega).map(np.array)


def assert_pose_close(a, b, atol=1e-9):
    a, b = np.asarray(a), np.asarray(b)
    np.testing.assert_allclose(a[..., :2], b[..., :2], atol=atol)
    np.testing.assert_allclose(wrap_angle(a[..., 2] - b[..., 2]), 0.0, atol=atol)


def test_worked_example_landmark_in_world():
    # body at (3, 2) heading 30 deg; landmark 1 m ahead: (3 + cos30, 2 + sin30) = (3.866, 2.5)
    world_T_body = np.array([3.0, 2.0, np.deg2rad(30.0)])
    world_p = se2.transform_points(world_T_body, np.array([1.0, 0.0]))
    np.testing.assert_allclose(world_p, [3.0 + np.sqrt(3) / 2, 2.5], atol=1e-12)
    assert world_p[0] == pytest.approx(3.866, abs=5e-4)
    # and back: the inverse pose maps it to (1, 0) in the body frame
    np.testing.assert_allclose(se2.transform_points(se2.inverse(world_T_body), world_p), [1, 0],
                               atol=1e-12)


@pytest.mark.parametrize("a, expected", [
    (0.0, 0.0), (np.pi, -np.pi), (-np.pi, -np.pi), (3 * np.pi, -np.pi), (2 * np.pi, 0.0),
    (np.pi / 2 + 4 * np.pi, np.pi / 2), (-1e-18, -1e-18), (7.0, 7.0 - 2 * np.pi),
])
def test_wrap_angle_examples(a, expected):
    assert wrap_angle(a) == pytest.approx(expected, abs=1e-12)


@given(st.floats(-1e4, 1e4))
def test_wrap_angle_range_and_equivalence(a):
    w = wrap_angle(a)
    assert -np.pi <= w < np.pi
    assert np.cos(w) == pytest.approx(np.cos(a), abs=1e-9)
    assert np.sin(w) == pytest.approx(np.sin(a), abs=1e-9)
    assert angles.angle_diff(a, a) == 0.0


def test_wrap_angle_keeps_shape():
    assert wrap_angle(np.zeros((2, 3))).shape == (2, 3)
    assert isinstance(wrap_angle(1.0), float)


def test_so2_matrix_round_trip_and_hat():
    theta = np.linspace(-3, 3, 7)
    np.testing.assert_allclose(so2.from_matrix(so2.to_matrix(theta)), theta, atol=1e-15)
    np.testing.assert_allclose(so2.vee(so2.hat(theta)), theta)
    R = so2.to_matrix(0.3)
    np.testing.assert_allclose(R @ R.T, np.eye(2), atol=1e-15)
    np.testing.assert_allclose(so2.act(np.pi / 2, [1.0, 0.0]), [0.0, 1.0], atol=1e-15)
    assert so2.exp(np.pi) == -np.pi and so2.log(0.25) == 0.25
    assert so2.between(0.5, 0.25) == pytest.approx(-0.25)


@settings(max_examples=60, deadline=None)
@given(pose, pose, pose)
def test_se2_group_axioms(a, b, c):
    assert_pose_close(se2.compose(se2.compose(a, b), c), se2.compose(a, se2.compose(b, c)), 1e-8)
    assert_pose_close(se2.compose(a, se2.identity()), a)
    assert_pose_close(se2.compose(a, se2.inverse(a)), se2.identity(), 1e-9)
    assert_pose_close(se2.between(a, b), se2.compose(se2.inverse(a), b), 1e-9)


@settings(max_examples=60, deadline=None)
@given(pose, pose)
def test_se2_matches_homogeneous_matrices(a, b):
    np.testing.assert_allclose(se2.to_matrix(se2.compose(a, b)), se2.to_matrix(a) @ se2.to_matrix(b),
                               atol=1e-9)
    assert_pose_close(se2.from_matrix(se2.to_matrix(a)), a, 1e-12)
    p = np.array([[1.0, -2.0], [0.5, 4.0]])
    hom = np.column_stack([p, np.ones(2)]) @ se2.to_matrix(a).T
    np.testing.assert_allclose(se2.transform_points(a, p), hom[:, :2], atol=1e-9)


@settings(max_examples=80, deadline=None)
@given(tangent)
def test_se2_exp_log_round_trip(xi):
    np.testing.assert_allclose(se2.log(se2.exp(xi)), xi, atol=1e-9, rtol=1e-9)


@settings(max_examples=60, deadline=None)
@given(pose)
def test_se2_log_exp_round_trip(T):
    assert_pose_close(se2.exp(se2.log(T)), T, 1e-9)


@settings(max_examples=60, deadline=None)
@given(pose, tangent)
def test_se2_retract_local_and_adjoint(T, xi):
    np.testing.assert_allclose(se2.local(T, se2.retract(T, xi)), xi, atol=1e-8)
    lhs = se2.compose(se2.compose(T, se2.exp(xi)), se2.inverse(T))
    rhs = se2.exp(se2.adjoint(T) @ xi)
    assert_pose_close(lhs, rhs, 1e-8)


def test_se2_exp_matches_matrix_exponential_numerically():
    # exp of the Lie algebra matrix by scaling-and-squaring Taylor, no closed forms involved
    xi = np.array([0.7, -0.3, 1.1])
    A = se2.hat(xi) / 1024.0
    E, term = np.eye(3), np.eye(3)
    for k in range(1, 12):
        term = term @ A / k
        E = E + term
    for _ in range(10):
        E = E @ E
    np.testing.assert_allclose(se2.to_matrix(se2.exp(xi)), E, atol=1e-12)
    np.testing.assert_allclose(se2.vee(se2.hat(xi)), xi)


def test_se2_batch_broadcasting():
    rng = np.random.default_rng(1)
    poses = np.column_stack([rng.normal(size=(5, 2)), rng.uniform(-3, 3, 5)])
    out = se2.compose(poses, poses[0])
    assert out.shape == (5, 3)
    for i in range(5):
        np.testing.assert_allclose(out[i], se2.compose(poses[i], poses[0]))
    pts = se2.transform_points(poses[0], rng.normal(size=(4, 2)))
    assert pts.shape == (4, 2)
    assert se2.adjoint(poses).shape == (5, 3, 3)


def test_one_pose_fast_paths_equal_the_broadcasting_ones():
    """transform_points of one pose on a point set and compose/between/inverse of single poses
    skip np.stack's broadcasting (the scan matchers' inner loops); the numbers are the batched
    path's bit for bit, also at +-pi and for rows wider than 2 columns."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        a, b = rng.normal(0, [5, 5, 3]), rng.normal(0, [1, 1, 0.5])
        if rng.random() < 0.2:
            a[2] = np.pi * rng.choice([-1.0, 1.0])
        p = rng.normal(0, 5, (int(rng.integers(1, 9)), 2))
        np.testing.assert_array_equal(se2.transform_points(a, p), se2.transform_points(a[None], p[None])[0])
        np.testing.assert_array_equal(se2.compose(a, b), se2.compose(a[None], b[None])[0])
        np.testing.assert_array_equal(se2.between(a, b), se2.between(a[None], b[None])[0])
        np.testing.assert_array_equal(se2.inverse(a), se2.inverse(a[None])[0])
    wide = rng.normal(size=(5, 3))
    assert se2.transform_points(np.zeros(3), wide).shape == (5, 2)
    np.testing.assert_array_equal(se2.transform_points(np.zeros(3), wide), wide[:, :2])
