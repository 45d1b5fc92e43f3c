"""SE(2): planar poses as arrays (..., 3) = (x, y, theta), theta in [-pi, pi).

``a_T_b`` maps points expressed in frame b into frame a: a_p = R(theta) b_p + (x, y).
The tangent vector is xi = (v_x, v_y, omega), translation first, which is also GTSAM's Pose2
order. ``exp`` integrates a constant body twist for unit time (Barfoot, *State Estimation for
Robotics*, sec. 7.1.9 specialised to the plane; Sola et al. 2018, "A micro Lie theory", eq. 156):
t = V(omega) v with V = [[A, -B], [B, A]], A = sin(w)/w, B = (1 - cos w)/w.

``retract(T, xi) = T o exp(xi)`` and ``local(T1, T2) = log(inv(T1) o T2)`` (body-frame
perturbations). ``adjoint(T)`` satisfies T o exp(xi) o inv(T) = exp(adjoint(T) @ xi).
All functions are pure and broadcast over leading dimensions.
"""

from __future__ import annotations

import numpy as np

from slamkit.geometry.angles import wrap_angle

SMALL_ANGLE_RAD = 1e-2


def _arr(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


def _pack(x, y, theta) -> np.ndarray:
    if np.ndim(x) == 0 and np.ndim(y) == 0 and np.ndim(theta) == 0:
        # one pose (the scan matchers' inner loops): the same numbers without np.stack's
        # broadcasting machinery
        return np.array([float(x), float(y), float(wrap_angle(theta))])
    x, y, theta = np.broadcast_arrays(_arr(x), _arr(y), _arr(theta))
    return np.stack([x, y, np.asarray(wrap_angle(theta), dtype=float)], axis=-1)


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    return np.zeros(tuple(shape) + (3,))


def compose(a_T_b: np.ndarray, b_T_c: np.ndarray) -> np.ndarray:
    """a_T_c = a_T_b o b_T_c."""
    a, b = _arr(a_T_b), _arr(b_T_c)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return _pack(a[..., 0] + c * b[..., 0] - s * b[..., 1],
                 a[..., 1] + s * b[..., 0] + c * b[..., 1],
                 a[..., 2] + b[..., 2])


def inverse(a_T_b: np.ndarray) -> np.ndarray:
    """b_T_a."""
    a = _arr(a_T_b)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return _pack(-c * a[..., 0] - s * a[..., 1], s * a[..., 0] - c * a[..., 1], -a[..., 2])


def between(world_T_a: np.ndarray, world_T_b: np.ndarray) -> np.ndarray:
    """a_T_b = inv(world_T_a) o world_T_b."""
    a, b = _arr(world_T_a), _arr(world_T_b)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    return _pack(c * dx + s * dy, -s * dx + c * dy, b[..., 2] - a[..., 2])


def transform_points(a_T_b: np.ndarray, b_p: np.ndarray) -> np.ndarray:
    """Points (..., 2) in frame b -> frame a. Poses and points broadcast (e.g. (3,) with (N, 2))."""
    T, p = _arr(a_T_b), _arr(b_p)
    c, s = np.cos(T[..., 2]), np.sin(T[..., 2])
    x = T[..., 0] + c * p[..., 0] - s * p[..., 1]
    y = T[..., 1] + s * p[..., 0] + c * p[..., 1]
    if T.ndim == 1 and p.ndim == 2:
        # one pose, a point set (the scan matchers' inner loops): the same numbers, without
        # np.stack's broadcasting machinery
        out = np.empty((p.shape[0], 2))
        out[:, 0], out[:, 1] = x, y
        return out
    return np.stack(np.broadcast_arrays(x, y), axis=-1)


def _a_b(omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A = sin(w)/w, B = (1 - cos w)/w with Taylor series near zero."""
    w2 = omega * omega
    small = np.abs(omega) < SMALL_ANGLE_RAD
    safe = np.where(small, 1.0, omega)
    a = np.where(small, 1.0 - w2 / 6.0 * (1.0 - w2 / 20.0 * (1.0 - w2 / 42.0)), np.sin(safe) / safe)
    b = np.where(small, omega * (0.5 - w2 / 24.0 * (1.0 - w2 / 30.0 * (1.0 - w2 / 56.0))),
                 2.0 * np.sin(0.5 * safe) ** 2 / safe)
    return a, b


def exp(xi: np.ndarray) -> np.ndarray:
    """Tangent (..., 3) = (v_x, v_y, omega) -> pose (..., 3)."""
    xi = _arr(xi)
    a, b = _a_b(xi[..., 2])
    return _pack(a * xi[..., 0] - b * xi[..., 1], b * xi[..., 0] + a * xi[..., 1], xi[..., 2])


def log(T: np.ndarray) -> np.ndarray:
    """Pose (..., 3) -> tangent (..., 3) with omega in [-pi, pi)."""
    T = _arr(T)
    w = np.asarray(wrap_angle(T[..., 2]), dtype=float)
    a, b = _a_b(w)
    det = a * a + b * b  # V^-1 = [[A, B], [-B, A]] / (A^2 + B^2), never singular for |w| <= pi
    vx = (a * T[..., 0] + b * T[..., 1]) / det
    vy = (-b * T[..., 0] + a * T[..., 1]) / det
    return np.stack([vx, vy, w], axis=-1)


def retract(T: np.ndarray, xi: np.ndarray) -> np.ndarray:
    return compose(T, exp(xi))


def local(T1: np.ndarray, T2: np.ndarray) -> np.ndarray:
    return log(between(T1, T2))


def adjoint(T: np.ndarray) -> np.ndarray:
    """(..., 3, 3): [[R, (y, -x)^T], [0, 0, 1]] for the (v_x, v_y, omega) tangent order."""
    T = _arr(T)
    c, s = np.cos(T[..., 2]), np.sin(T[..., 2])
    out = np.zeros(T.shape[:-1] + (3, 3))
    out[..., 0, 0] = c
    out[..., 0, 1] = -s
    out[..., 1, 0] = s
    out[..., 1, 1] = c
    out[..., 0, 2] = T[..., 1]
    out[..., 1, 2] = -T[..., 0]
    out[..., 2, 2] = 1.0
    return out


def hat(xi: np.ndarray) -> np.ndarray:
    """(..., 3) -> Lie algebra matrix (..., 3, 3)."""
    xi = _arr(xi)
    out = np.zeros(xi.shape[:-1] + (3, 3))
    out[..., 0, 1] = -xi[..., 2]
    out[..., 1, 0] = xi[..., 2]
    out[..., 0, 2] = xi[..., 0]
    out[..., 1, 2] = xi[..., 1]
    return out


def vee(xi_hat: np.ndarray) -> np.ndarray:
    m = _arr(xi_hat)
    return np.stack([m[..., 0, 2], m[..., 1, 2], 0.5 * (m[..., 1, 0] - m[..., 0, 1])], axis=-1)


def to_matrix(T: np.ndarray) -> np.ndarray:
    """(..., 3) -> homogeneous (..., 3, 3)."""
    T = _arr(T)
    c, s = np.cos(T[..., 2]), np.sin(T[..., 2])
    out = np.zeros(T.shape[:-1] + (3, 3))
    out[..., 0, 0] = c
    out[..., 0, 1] = -s
    out[..., 1, 0] = s
    out[..., 1, 1] = c
    out[..., 0, 2] = T[..., 0]
    out[..., 1, 2] = T[..., 1]
    out[..., 2, 2] = 1.0
    return out


def from_matrix(M: np.ndarray) -> np.ndarray:
    """Homogeneous (..., 3, 3) -> (..., 3)."""
    M = _arr(M)
    return _pack(M[..., 0, 2], M[..., 1, 2], np.arctan2(M[..., 1, 0], M[..., 0, 0]))


def covariance_body_to_world(world_xytheta_body: np.ndarray, cov_body: np.ndarray) -> np.ndarray:
    """A (3, 3) pose covariance in the body-frame tangent (GTSAM's Pose2 marginals, where
    T Exp(xi) perturbs the pose) expressed in world (x, y, theta) terms, to first order:
    T Exp(xi) ~ (t + R(theta) xi_t, theta + xi_theta), so P_world = A P_body A^T with
    A = blockdiag(R(theta), 1)."""
    theta = float(np.asarray(world_xytheta_body, dtype=float).reshape(3)[2])
    c, s = np.cos(theta), np.sin(theta)
    A = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return A @ np.asarray(cov_body, dtype=float) @ A.T


def covariance_world_to_body(world_xytheta_body: np.ndarray, cov_world: np.ndarray) -> np.ndarray:
    """The inverse of :func:`covariance_body_to_world`: P_body = A^T P_world A."""
    theta = float(np.asarray(world_xytheta_body, dtype=float).reshape(3)[2])
    c, s = np.cos(theta), np.sin(theta)
    A = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return A.T @ np.asarray(cov_world, dtype=float) @ A
