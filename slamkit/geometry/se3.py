"""SE(3): rigid poses as homogeneous (..., 4, 4) matrices.

``a_T_b`` maps points in frame b into frame a: a_p = R b_p + t.

**Tangent order is translation first**: xi = (rho, phi), rho (linear) then phi (angular), as in
Barfoot's *State Estimation for Robotics* (sec. 7.1.4) and Sophus. GTSAM's Pose3 is rotation
first (omega, v): permute with ``xi[..., [3, 4, 5, 0, 1, 2]]`` when crossing that boundary.

exp(xi) = [[exp_so3(phi), V(phi) rho], [0, 1]] with V = I + B hat(phi) + C hat(phi)^2,
B = (1 - cos t)/t^2, C = (t - sin t)/t^3 (Barfoot eq. 7.86); log inverts it with
V^-1 = I - hat(phi)/2 + D hat(phi)^2, D = (1 - A/(2B))/t^2 (A = sin t/t), Taylor near zero.
``retract(T, xi) = T exp(xi)``, ``local(T1, T2) = log(T1^-1 T2)``, and
T exp(xi) T^-1 = exp(adjoint(T) xi) with adjoint(T) = [[R, hat(t) R], [0, R]].

All functions are pure and broadcast over leading dimensions.
"""

from __future__ import annotations

import numpy as np

from slamkit.geometry import so3

SMALL_ANGLE_RAD = so3.SMALL_ANGLE_RAD


def _arr(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    return np.broadcast_to(np.eye(4), tuple(shape) + (4, 4)).copy()


def from_rotation_translation(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    R, t = _arr(R), _arr(t)
    shape = np.broadcast_shapes(R.shape[:-2], t.shape[:-1])
    out = identity(shape)
    out[..., :3, :3] = R
    out[..., :3, 3] = t
    return out


def rotation(T: np.ndarray) -> np.ndarray:
    return _arr(T)[..., :3, :3].copy()


def translation(T: np.ndarray) -> np.ndarray:
    return _arr(T)[..., :3, 3].copy()


def compose(a_T_b: np.ndarray, b_T_c: np.ndarray) -> np.ndarray:
    return _arr(a_T_b) @ _arr(b_T_c)


def inverse(a_T_b: np.ndarray) -> np.ndarray:
    """Closed form [[R^T, -R^T t], [0, 1]] (exact, unlike a general matrix inverse)."""
    T = _arr(a_T_b)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    return from_rotation_translation(Rt, -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3]))


def between(world_T_a: np.ndarray, world_T_b: np.ndarray) -> np.ndarray:
    """a_T_b = inv(world_T_a) world_T_b."""
    return inverse(world_T_a) @ _arr(world_T_b)


def transform_points(a_T_b: np.ndarray, b_p: np.ndarray) -> np.ndarray:
    """Points (..., 3) in frame b -> frame a; poses and points broadcast."""
    T, p = _arr(a_T_b), _arr(b_p)
    return np.einsum("...ij,...j->...i", T[..., :3, :3], p) + T[..., :3, 3]


def _v_matrix(phi: np.ndarray) -> np.ndarray:
    """V = J_l(phi), the left Jacobian of SO(3)."""
    return so3.left_jacobian(phi)


def _v_inverse(phi: np.ndarray) -> np.ndarray:
    return so3.left_jacobian_inverse(phi)


def exp(xi: np.ndarray) -> np.ndarray:
    """Tangent (..., 6) = (rho, phi) -> pose (..., 4, 4)."""
    xi = _arr(xi)
    rho, phi = xi[..., :3], xi[..., 3:]
    t = np.einsum("...ij,...j->...i", _v_matrix(phi), rho)
    return from_rotation_translation(so3.exp(phi), t)


def log(T: np.ndarray) -> np.ndarray:
    """Pose (..., 4, 4) -> tangent (..., 6) = (rho, phi), |phi| in [0, pi]."""
    T = _arr(T)
    phi = so3.log(T[..., :3, :3])
    rho = np.einsum("...ij,...j->...i", _v_inverse(phi), T[..., :3, 3])
    return np.concatenate([rho, phi], axis=-1)


def retract(T: np.ndarray, xi: np.ndarray) -> np.ndarray:
    return _arr(T) @ exp(xi)


def local(T1: np.ndarray, T2: np.ndarray) -> np.ndarray:
    return log(between(T1, T2))


def adjoint(T: np.ndarray) -> np.ndarray:
    """(..., 6, 6) = [[R, hat(t) R], [0, R]] for the (rho, phi) order."""
    T = _arr(T)
    R, t = T[..., :3, :3], T[..., :3, 3]
    out = np.zeros(T.shape[:-2] + (6, 6))
    out[..., :3, :3] = R
    out[..., 3:, 3:] = R
    out[..., :3, 3:] = so3.hat(t) @ R
    return out


def hat(xi: np.ndarray) -> np.ndarray:
    """(..., 6) -> Lie algebra matrix (..., 4, 4)."""
    xi = _arr(xi)
    out = np.zeros(xi.shape[:-1] + (4, 4))
    out[..., :3, :3] = so3.hat(xi[..., 3:])
    out[..., :3, 3] = xi[..., :3]
    return out


def vee(xi_hat: np.ndarray) -> np.ndarray:
    m = _arr(xi_hat)
    return np.concatenate([m[..., :3, 3], so3.vee(m[..., :3, :3])], axis=-1)


def from_quat_wxyz_t(quat_wxyz: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Quaternion (..., 4) wxyz and translation (..., 3) -> pose (..., 4, 4)."""
    return from_rotation_translation(so3.from_quat_wxyz(quat_wxyz), t)


def to_quat_wxyz_t(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pose (..., 4, 4) -> (quat_wxyz (..., 4) with w >= 0, t (..., 3))."""
    T = _arr(T)
    return so3.to_quat_wxyz(T[..., :3, :3]), T[..., :3, 3].copy()


def from_se2(xytheta: np.ndarray) -> np.ndarray:
    """Planar poses (..., 3) -> (..., 4, 4) with z = 0 and yaw-only rotation."""
    p = _arr(xytheta)
    z = np.zeros_like(p[..., 0])
    R = so3.from_euler_zyx(p[..., 2], z, z)
    return from_rotation_translation(R, np.stack([p[..., 0], p[..., 1], z], axis=-1))
