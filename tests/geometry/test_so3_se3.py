"""SO(3)/SE(3): group axioms, exp/log round trips near identity and near pi, quaternions, Euler
angles, adjoint identity and numeric checks against a series matrix exponential."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

from slamkit.geometry import se3, so3

unit = st.tuples(*[st.floats(-1, 1)] * 3).map(np.array).filter(lambda v: np.linalg.norm(v) > 1e-3) \
    .map(lambda v: v / np.linalg.norm(v))
# angles over the whole principal range, plus the tricky ends
angle_mag = st.one_of(st.floats(0.0, np.pi - 1e-6), st.floats(0.0, 1e-8),
                      st.floats(np.pi - 1e-6, np.pi - 1e-7))
rotvec = st.builds(lambda u, a: u * a, unit, angle_mag)
finite3 = st.tuples(*[st.floats(-20, 20)] * 3).map(np.array)
rotation = rotvec.map(so3.exp)
pose = st.builds(lambda phi, t: se3.from_rotation_translation(so3.exp(phi), t), rotvec, finite3)
tangent6 = st.builds(lambda rho, phi: np.concatenate([rho, phi]), finite3, rotvec)


def series_expm(A: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring a Taylor series (independent of closed forms)."""
    A = A / 1024.0
    E, term = np.eye(len(A)), np.eye(len(A))
    for k in range(1, 14):
        term = term @ A / k
        E = E + term
    for _ in range(10):
        E = E @ E
    return E


def same_rotation_vector(a, b, atol):
    """phi and -phi are the same rotation when |phi| = pi."""
    if np.allclose(a, b, atol=atol):
        return True
    return bool(np.linalg.norm(a) > np.pi - 1e-5 and np.allclose(a, -b, atol=atol))


@settings(max_examples=100, deadline=None)
@given(rotvec)
def test_so3_exp_log_round_trip(phi):
    R = so3.exp(phi)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
    assert same_rotation_vector(so3.log(R), phi, 1e-9)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-8, 1e-5, 1e-2 - 1e-12, 1e-2, 0.3, 2.0,
                                   np.pi - 1e-3, np.pi - 1e-6, np.pi - 1e-9, np.pi])
def test_so3_log_precision_across_angles(angle):
    axis = np.array([0.36, -0.48, 0.8])
    phi = angle * axis
    out = so3.log(so3.exp(phi))
    # near identity: relative precision; near pi: absolute 1e-9 (sign of the axis may flip at pi)
    if angle < 1.0:
        np.testing.assert_allclose(out, phi, rtol=1e-12, atol=1e-300)
    else:
        assert same_rotation_vector(out, phi, 1e-9)
    assert so3.angle(so3.exp(phi)) == pytest.approx(angle, abs=1e-12)


def test_so3_log_of_exact_half_turns():
    for axis in np.eye(3):
        R = np.diag(2 * axis ** 2 - 1)  # rotation by pi about a coordinate axis
        phi = so3.log(R)
        assert np.linalg.norm(phi) == pytest.approx(np.pi)
        np.testing.assert_allclose(np.abs(phi), np.pi * axis, atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(rotvec)
def test_so3_exp_matches_series(phi):
    np.testing.assert_allclose(so3.exp(phi), series_expm(so3.hat(phi)), atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(rotation, rotation, rotation)
def test_so3_group_axioms(a, b, c):
    np.testing.assert_allclose(so3.compose(so3.compose(a, b), c), so3.compose(a, so3.compose(b, c)),
                               atol=1e-12)
    np.testing.assert_allclose(so3.compose(a, so3.inverse(a)), np.eye(3), atol=1e-12)
    np.testing.assert_allclose(so3.compose(so3.identity(), a), a)
    np.testing.assert_allclose(so3.between(a, b), a.T @ b, atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(rotation, rotvec)
def test_so3_retract_local_adjoint(R, phi):
    assume(np.linalg.norm(phi) < np.pi - 1e-5)
    np.testing.assert_allclose(so3.local(R, so3.retract(R, phi)), phi, atol=1e-9)
    np.testing.assert_allclose(R @ so3.exp(phi) @ R.T, so3.exp(so3.adjoint(R) @ phi), atol=1e-12)
    v = np.array([1.0, 2.0, 3.0])
    np.testing.assert_allclose(so3.act(R, v), R @ v)
    np.testing.assert_allclose(so3.hat(phi) @ v, np.cross(phi, v), atol=1e-15)
    np.testing.assert_allclose(so3.vee(so3.hat(phi)), phi)


@settings(max_examples=100, deadline=None)
@given(rotation)
def test_quaternion_round_trip_and_canonical(R):
    q = so3.to_quat_wxyz(R)
    assert q[0] >= 0.0
    assert np.linalg.norm(q) == pytest.approx(1.0)
    np.testing.assert_allclose(so3.from_quat_wxyz(q), R, atol=1e-14)
    np.testing.assert_allclose(so3.to_quat_wxyz(so3.from_quat_wxyz(-q)), q, atol=1e-14)


def test_quaternion_worked_examples():
    # 90 degrees about z: q = (cos 45, 0, 0, sin 45)
    Rz = so3.exp([0.0, 0.0, np.pi / 2])
    np.testing.assert_allclose(so3.to_quat_wxyz(Rz), [np.sqrt(0.5), 0, 0, np.sqrt(0.5)], atol=1e-15)
    # 180 about x: w = 0, Shepperd's x-branch
    np.testing.assert_allclose(so3.to_quat_wxyz(np.diag([1.0, -1.0, -1.0])), [0, 1, 0, 0], atol=1e-15)
    # Hamilton product matches matrix product
    p, q = np.array([0.5, 0.5, 0.5, 0.5]), so3.to_quat_wxyz(Rz)
    np.testing.assert_allclose(so3.from_quat_wxyz(so3.quat_multiply_wxyz(p, q)),
                               so3.from_quat_wxyz(p) @ Rz, atol=1e-15)
    batch = so3.to_quat_wxyz(np.stack([Rz, np.eye(3)]))
    assert batch.shape == (2, 4)


@settings(max_examples=100, deadline=None)
@given(st.floats(-np.pi, np.pi, exclude_max=True), st.floats(-np.pi / 2 + 1e-6, np.pi / 2 - 1e-6),
       st.floats(-np.pi, np.pi, exclude_max=True))
def test_euler_zyx_round_trip(yaw, pitch, roll):
    R = so3.from_euler_zyx(yaw, pitch, roll)
    y, p, r = so3.to_euler_zyx(R)
    np.testing.assert_allclose(so3.from_euler_zyx(y, p, r), R, atol=1e-12)
    np.testing.assert_allclose(p, pitch, atol=1e-6)


def test_euler_zyx_convention_and_gimbal_lock():
    yaw, pitch, roll = 0.3, -0.2, 0.1
    Rz = so3.exp([0, 0, yaw])
    Ry = so3.exp([0, pitch, 0])
    Rx = so3.exp([roll, 0, 0])
    np.testing.assert_allclose(so3.from_euler_zyx(yaw, pitch, roll), Rz @ Ry @ Rx, atol=1e-15)
    np.testing.assert_allclose(so3.to_euler_zyx(Rz @ Ry @ Rx), [yaw, pitch, roll], atol=1e-15)
    for p in (np.pi / 2, -np.pi / 2):
        R = so3.from_euler_zyx(0.4, p, 0.0)
        np.testing.assert_allclose(so3.from_euler_zyx(*so3.to_euler_zyx(R)), R, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(pose, pose, pose)
def test_se3_group_axioms(a, b, c):
    np.testing.assert_allclose(se3.compose(se3.compose(a, b), c), se3.compose(a, se3.compose(b, c)),
                               atol=1e-9)
    np.testing.assert_allclose(se3.compose(a, se3.inverse(a)), np.eye(4), atol=1e-12)
    np.testing.assert_allclose(se3.inverse(a), np.linalg.inv(a), atol=1e-9)
    np.testing.assert_allclose(se3.between(a, b), np.linalg.inv(a) @ b, atol=1e-9)
    p = np.array([[0.5, -1.0, 2.0]])
    np.testing.assert_allclose(se3.transform_points(a, p)[0], (a @ np.append(p[0], 1.0))[:3],
                               atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(tangent6)
def test_se3_exp_log_round_trip(xi):
    out = se3.log(se3.exp(xi))
    if np.linalg.norm(xi[3:]) < np.pi - 1e-5:
        np.testing.assert_allclose(out, xi, atol=1e-8)
    else:  # near pi the log is the inverse up to the axis sign: compare the poses
        np.testing.assert_allclose(se3.exp(out), se3.exp(xi), atol=1e-8)


@pytest.mark.parametrize("angle", [0.0, 1e-10, 1e-6, 1e-2, 1.0, np.pi - 1e-6])
def test_se3_exp_matches_series_and_log_precise(angle):
    xi = np.array([1.0, -2.0, 0.5, *(angle * np.array([0.6, 0.0, -0.8]))])
    np.testing.assert_allclose(se3.exp(xi), series_expm(se3.hat(xi)), atol=1e-11)
    np.testing.assert_allclose(se3.log(se3.exp(xi)), xi, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(pose, tangent6)
def test_se3_adjoint_retract_local(T, xi):
    lhs = T @ se3.exp(xi) @ se3.inverse(T)
    np.testing.assert_allclose(lhs, se3.exp(se3.adjoint(T) @ xi), atol=1e-7)
    if np.linalg.norm(xi[3:]) < np.pi - 1e-5:
        np.testing.assert_allclose(se3.local(T, se3.retract(T, xi)), xi, atol=1e-7)
    np.testing.assert_allclose(se3.vee(se3.hat(xi)), xi)


@settings(max_examples=60, deadline=None)
@given(pose)
def test_se3_quaternion_translation_round_trip(T):
    q, t = se3.to_quat_wxyz_t(T)
    np.testing.assert_allclose(se3.from_quat_wxyz_t(q, t), T, atol=1e-13)


def test_se3_translation_first_convention():
    # pure translation along x, then pure rotation about z
    np.testing.assert_allclose(se3.exp([2.0, 0, 0, 0, 0, 0])[:3, 3], [2.0, 0, 0])
    np.testing.assert_allclose(se3.exp([0, 0, 0, 0, 0, np.pi / 2])[:3, :3], so3.exp([0, 0, np.pi / 2]))
    # worked SE(3) example matching the planar one: (3, 2, 0) yawed 30 deg, point (1, 0, 0)
    T = se3.from_se2(np.array([3.0, 2.0, np.deg2rad(30)]))
    np.testing.assert_allclose(se3.transform_points(T, [1.0, 0, 0]), [3.0 + np.sqrt(3) / 2, 2.5, 0],
                               atol=1e-12)


def test_se3_batch_shapes():
    rng = np.random.default_rng(0)
    xi = rng.normal(size=(7, 6))
    T = se3.exp(xi)
    assert T.shape == (7, 4, 4)
    np.testing.assert_allclose(se3.log(T), xi, atol=1e-9)
    assert se3.adjoint(T).shape == (7, 6, 6)
    assert se3.transform_points(T, np.zeros(3)).shape == (7, 3)
    assert so3.to_quat_wxyz(T[:, :3, :3]).shape == (7, 4)
    np.testing.assert_allclose(so3.normalize(T[:, :3, :3] * 1.0001), T[:, :3, :3], atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(rotvec)
def test_so3_jacobians_match_finite_differences(phi):
    assume(np.linalg.norm(phi) < np.pi - 1e-3)
    eps = 1e-6
    Jr = so3.right_jacobian(phi)
    Jl = so3.left_jacobian(phi)
    R = so3.exp(phi)
    for i in range(3):
        d = np.zeros(3)
        d[i] = eps
        # central differences of exp(phi + d) expressed on the right and on the left of exp(phi)
        right = (so3.log(R.T @ so3.exp(phi + d)) - so3.log(R.T @ so3.exp(phi - d))) / (2 * eps)
        left = (so3.log(so3.exp(phi + d) @ R.T) - so3.log(so3.exp(phi - d) @ R.T)) / (2 * eps)
        np.testing.assert_allclose(right, Jr[:, i], atol=1e-7)
        np.testing.assert_allclose(left, Jl[:, i], atol=1e-7)
    np.testing.assert_allclose(Jr @ so3.right_jacobian_inverse(phi), np.eye(3), atol=1e-9)
    np.testing.assert_allclose(Jl @ so3.left_jacobian_inverse(phi), np.eye(3), atol=1e-9)
