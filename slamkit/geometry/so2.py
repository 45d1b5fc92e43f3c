"""SO(2): planar rotations, represented by their angle in radians (any shape ``(...)``).

The tangent space is the angle rate ``omega`` (scalar per element). Because the element *is* the
angle, ``exp`` and ``log`` are angle wrapping into [-pi, pi); ``to_matrix``/``from_matrix``
convert to and from (..., 2, 2) rotation matrices. All functions are pure and broadcast.
"""

from __future__ import annotations

import numpy as np

from slamkit.geometry.angles import wrap_angle


def _arr(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    return np.zeros(shape)


def exp(omega_rad):
    """Tangent (angle) -> group element (wrapped angle)."""
    return wrap_angle(omega_rad)


def log(theta_rad):
    """Group element -> tangent in [-pi, pi)."""
    return wrap_angle(theta_rad)


def hat(omega_rad) -> np.ndarray:
    """omega (...,) -> skew matrix (..., 2, 2) [[0, -w], [w, 0]]."""
    w = _arr(omega_rad)
    out = np.zeros(w.shape + (2, 2))
    out[..., 0, 1] = -w
    out[..., 1, 0] = w
    return out


def vee(omega_hat: np.ndarray) -> np.ndarray:
    """Skew matrix (..., 2, 2) -> omega (...,)."""
    m = _arr(omega_hat)
    return 0.5 * (m[..., 1, 0] - m[..., 0, 1])


def to_matrix(theta_rad) -> np.ndarray:
    """Angle (...,) -> rotation matrix (..., 2, 2)."""
    t = _arr(theta_rad)
    c, s = np.cos(t), np.sin(t)
    out = np.empty(t.shape + (2, 2))
    out[..., 0, 0] = c
    out[..., 0, 1] = -s
    out[..., 1, 0] = s
    out[..., 1, 1] = c
    return out


def from_matrix(R: np.ndarray):
    """Rotation matrix (..., 2, 2) -> angle (...,) in [-pi, pi)."""
    R = _arr(R)
    return wrap_angle(np.arctan2(R[..., 1, 0], R[..., 0, 0]))


def compose(a_theta_b, b_theta_c):
    return wrap_angle(_arr(a_theta_b) + _arr(b_theta_c))


def inverse(a_theta_b):
    return wrap_angle(-_arr(a_theta_b))


def between(w_theta_a, w_theta_b):
    """``inv(a) o b``."""
    return wrap_angle(_arr(w_theta_b) - _arr(w_theta_a))


def act(a_theta_b, b_p: np.ndarray) -> np.ndarray:
    """Rotate points (..., 2) expressed in b into frame a."""
    return np.einsum("...ij,...j->...i", to_matrix(a_theta_b), _arr(b_p))


def retract(theta_rad, omega_rad):
    return compose(theta_rad, omega_rad)


def local(theta1_rad, theta2_rad):
    return between(theta1_rad, theta2_rad)
