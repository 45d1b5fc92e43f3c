"""SO(3): 3D rotations as (..., 3, 3) matrices; tangent vectors phi (..., 3) (axis * angle).

Conventions
-----------
* ``exp(phi)`` is Rodrigues' formula R = I + A hat(phi) + B hat(phi)^2 with A = sin(t)/t,
  B = (1 - cos t)/t^2 (Barfoot, *State Estimation for Robotics*, eq. 7.14); both coefficients
  switch to their Taylor series for t < 1e-2 so near-identity rotations keep full precision.
* ``log(R)`` goes through the quaternion from Shepperd's method (Shepperd 1978, "Quaternion from
  rotation matrix", J. Guidance & Control 1(3)), which picks the best-conditioned of four
  formulas; the angle is then 2 atan2(|v|, w). That stays accurate at both ends: near identity
  (|phi| ~ 1e-8) and near pi, where the trace-based arccos formula loses half its digits and the
  axis cannot be read from the antisymmetric part. Returned angles are in [0, pi].
* Quaternions are ``wxyz`` (Hamilton, scalar first), unit norm, canonical ``w >= 0``.
* ZYX Euler: R = Rz(yaw) @ Ry(pitch) @ Rx(roll), pitch in [-pi/2, pi/2].
* ``local(R1, R2) = log(R1^T R2)`` and ``retract(R, phi) = R exp(phi)`` (right perturbation).
* ``adjoint(R) = R``: R exp(phi) R^T = exp(R phi).
* Jacobians (Barfoot eqs. 7.77, 7.87; Sola et al. 2018 eqs. 143-146):
  exp(phi + d) ~ exp(phi) exp(J_r(phi) d) ~ exp(J_l(phi) d) exp(phi), with
  J_l = I + B hat + C hat^2, J_r(phi) = J_l(-phi), and the closed-form inverses.

All functions are pure, broadcast over leading dimensions and never modify their inputs.
"""

from __future__ import annotations

import numpy as np

#: below this angle the trigonometric coefficients use their Taylor series
SMALL_ANGLE_RAD = 1e-2


def _arr(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    return np.broadcast_to(np.eye(3), tuple(shape) + (3, 3)).copy()


def hat(phi: np.ndarray) -> np.ndarray:
    """(..., 3) -> skew-symmetric (..., 3, 3) such that hat(a) @ b = cross(a, b)."""
    v = _arr(phi)
    out = np.zeros(v.shape[:-1] + (3, 3))
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    out[..., 0, 1] = -z
    out[..., 0, 2] = y
    out[..., 1, 0] = z
    out[..., 1, 2] = -x
    out[..., 2, 0] = -y
    out[..., 2, 1] = x
    return out


def vee(phi_hat: np.ndarray) -> np.ndarray:
    """Skew-symmetric (..., 3, 3) -> (..., 3); uses the antisymmetric part of the input."""
    m = _arr(phi_hat)
    return 0.5 * np.stack(
        [m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]],
        axis=-1,
    )


def _coefficients(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A = sin t / t, B = (1 - cos t)/t^2, C = (t - sin t)/t^3, Taylor-expanded when small."""
    t2 = theta * theta
    small = theta < SMALL_ANGLE_RAD
    safe = np.where(small, 1.0, theta)
    safe2 = safe * safe
    a_big = np.sin(safe) / safe
    # 2 sin^2(t/2) avoids the cancellation in 1 - cos t
    b_big = 2.0 * np.sin(0.5 * safe) ** 2 / safe2
    c_big = (safe - np.sin(safe)) / (safe2 * safe)
    a_small = 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0))
    b_small = 0.5 - t2 / 24.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0))
    c_small = 1.0 / 6.0 - t2 / 120.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))
    return (np.where(small, a_small, a_big), np.where(small, b_small, b_big),
            np.where(small, c_small, c_big))


def exp(phi: np.ndarray) -> np.ndarray:
    """Tangent (..., 3) -> rotation matrix (..., 3, 3) (Rodrigues)."""
    phi = _arr(phi)
    theta = np.linalg.norm(phi, axis=-1)
    a, b, _ = _coefficients(theta)
    K = hat(phi)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def log(R: np.ndarray) -> np.ndarray:
    """Rotation matrix (..., 3, 3) -> tangent (..., 3) with angle in [0, pi]."""
    q = to_quat_wxyz(R)
    w, v = q[..., 0], q[..., 1:]
    n = np.linalg.norm(v, axis=-1)
    # angle = 2 atan2(|v|, w); phi = angle * v / |v|.  For small |v| (w ~ 1) use the series
    # 2 atan2(n, w)/n = (2/w)(1 - n^2/(3 w^2) + n^4/(5 w^4)).
    small = n < 1e-6
    safe_n = np.where(small, 1.0, n)
    scale_big = 2.0 * np.arctan2(n, w) / safe_n
    r = np.where(small, n / np.where(small, w, 1.0), 0.0) ** 2
    scale_small = 2.0 / np.where(small, w, 1.0) * (1.0 - r / 3.0 + r * r / 5.0)
    scale = np.where(small, scale_small, scale_big)
    return scale[..., None] * v


def left_jacobian(phi: np.ndarray) -> np.ndarray:
    """J_l(phi) (..., 3, 3) = I + B hat(phi) + C hat(phi)^2 (also SE(3)'s V matrix)."""
    phi = _arr(phi)
    _, b, c = _coefficients(np.linalg.norm(phi, axis=-1))
    K = hat(phi)
    return np.eye(3) + b[..., None, None] * K + c[..., None, None] * (K @ K)


def right_jacobian(phi: np.ndarray) -> np.ndarray:
    """J_r(phi) = J_l(-phi): exp(phi + d) ~ exp(phi) exp(J_r d) for small d."""
    return left_jacobian(-_arr(phi))


def _inverse_coefficient(theta: np.ndarray) -> np.ndarray:
    """D = (1 - A / (2B)) / t^2 = 1/t^2 - (1 + cos t) / (2 t sin t), Taylor-expanded when small."""
    t2 = theta * theta
    small = theta < SMALL_ANGLE_RAD
    safe = np.where(small, 1.0, theta)
    # 1 - cos t = 2 sin^2(t/2) keeps the big-angle branch finite at t = pi
    d_big = (1.0 - safe * np.sin(safe) / (4.0 * np.sin(0.5 * safe) ** 2)) / (safe * safe)
    d_small = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2 * t2 * t2 / 1209600.0
    return np.where(small, d_small, d_big)


def left_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    """J_l(phi)^-1 = I - hat(phi)/2 + D hat(phi)^2 (valid for |phi| < 2 pi)."""
    phi = _arr(phi)
    d = _inverse_coefficient(np.linalg.norm(phi, axis=-1))
    K = hat(phi)
    return np.eye(3) - 0.5 * K + d[..., None, None] * (K @ K)


def right_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    return left_jacobian_inverse(-_arr(phi))


def compose(a_R_b: np.ndarray, b_R_c: np.ndarray) -> np.ndarray:
    return _arr(a_R_b) @ _arr(b_R_c)


def inverse(a_R_b: np.ndarray) -> np.ndarray:
    return np.swapaxes(_arr(a_R_b), -1, -2).copy()


def between(w_R_a: np.ndarray, w_R_b: np.ndarray) -> np.ndarray:
    """``a_R_b = inv(w_R_a) w_R_b``."""
    return np.swapaxes(_arr(w_R_a), -1, -2) @ _arr(w_R_b)


def act(a_R_b: np.ndarray, b_p: np.ndarray) -> np.ndarray:
    """Rotate points (..., 3) from frame b into frame a."""
    return np.einsum("...ij,...j->...i", _arr(a_R_b), _arr(b_p))


def retract(R: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """``R exp(phi)`` (perturbation on the right, in the body frame)."""
    return _arr(R) @ exp(phi)


def local(R1: np.ndarray, R2: np.ndarray) -> np.ndarray:
    """``log(R1^T R2)``, the inverse of ``retract``."""
    return log(between(R1, R2))


def adjoint(R: np.ndarray) -> np.ndarray:
    """Adjoint (..., 3, 3): R exp(phi) R^T = exp(adjoint(R) phi)."""
    return _arr(R).copy()


def angle(R: np.ndarray) -> np.ndarray:
    """Rotation angle (...,) in [0, pi]."""
    return np.linalg.norm(log(R), axis=-1)


def normalize(R: np.ndarray) -> np.ndarray:
    """Nearest rotation matrix (polar decomposition via SVD, det fixed to +1)."""
    U, _, Vt = np.linalg.svd(_arr(R))
    d = np.sign(np.linalg.det(U @ Vt))
    U = U.copy()
    U[..., :, 2] *= d[..., None]
    return U @ Vt


def from_quat_wxyz(quat_wxyz: np.ndarray) -> np.ndarray:
    """Quaternion (..., 4) wxyz (normalised here) -> rotation matrix (..., 3, 3)."""
    q = _arr(quat_wxyz)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def to_quat_wxyz(R: np.ndarray) -> np.ndarray:
    """Rotation matrix (..., 3, 3) -> unit quaternion (..., 4) wxyz with w >= 0 (Shepperd)."""
    R = _arr(R)
    r00, r01, r02 = R[..., 0, 0], R[..., 0, 1], R[..., 0, 2]
    r10, r11, r12 = R[..., 1, 0], R[..., 1, 1], R[..., 1, 2]
    r20, r21, r22 = R[..., 2, 0], R[..., 2, 1], R[..., 2, 2]
    trace = r00 + r11 + r22
    # Choose the largest of 4w^2-1, 4x^2-1, ... (all proportional to these diagonal sums): its
    # square root is far from zero, so the divisions below are well conditioned.
    choice = np.argmax(np.stack([trace, r00, r11, r22], axis=-1), axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        sw = np.sqrt(np.maximum(1.0 + trace, 0.0)) * 2.0  # 4w
        sx = np.sqrt(np.maximum(1.0 + r00 - r11 - r22, 0.0)) * 2.0  # 4x
        sy = np.sqrt(np.maximum(1.0 - r00 + r11 - r22, 0.0)) * 2.0
        sz = np.sqrt(np.maximum(1.0 - r00 - r11 + r22, 0.0)) * 2.0
        qw = np.stack([0.25 * sw, (r21 - r12) / sw, (r02 - r20) / sw, (r10 - r01) / sw], -1)
        qx = np.stack([(r21 - r12) / sx, 0.25 * sx, (r01 + r10) / sx, (r02 + r20) / sx], -1)
        qy = np.stack([(r02 - r20) / sy, (r01 + r10) / sy, 0.25 * sy, (r12 + r21) / sy], -1)
        qz = np.stack([(r10 - r01) / sz, (r02 + r20) / sz, (r12 + r21) / sz, 0.25 * sz], -1)
    c = choice[..., None]
    q = np.where(c == 0, qw, np.where(c == 1, qx, np.where(c == 2, qy, qz)))
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def canonical_quat_wxyz(quat_wxyz: np.ndarray) -> np.ndarray:
    """Normalise and flip sign so that w >= 0 (q and -q are the same rotation)."""
    q = _arr(quat_wxyz)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_multiply_wxyz(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p * q of wxyz quaternions (..., 4); matches from_quat(p) @ from_quat(q)."""
    p, q = _arr(p), _arr(q)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ], axis=-1)


def from_euler_zyx(yaw_rad, pitch_rad, roll_rad) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll); arguments broadcast, result (..., 3, 3)."""
    y, p, r = np.broadcast_arrays(_arr(yaw_rad), _arr(pitch_rad), _arr(roll_rad))
    cy, sy, cp, sp, cr, sr = np.cos(y), np.sin(y), np.cos(p), np.sin(p), np.cos(r), np.sin(r)
    out = np.empty(y.shape + (3, 3))
    out[..., 0, 0] = cy * cp
    out[..., 0, 1] = cy * sp * sr - sy * cr
    out[..., 0, 2] = cy * sp * cr + sy * sr
    out[..., 1, 0] = sy * cp
    out[..., 1, 1] = sy * sp * sr + cy * cr
    out[..., 1, 2] = sy * sp * cr - cy * sr
    out[..., 2, 0] = -sp
    out[..., 2, 1] = cp * sr
    out[..., 2, 2] = cp * cr
    return out


def to_euler_zyx(R: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotation (..., 3, 3) -> (yaw, pitch, roll), so ``from_euler_zyx(*to_euler_zyx(R)) == R``.

    pitch is in [-pi/2, pi/2]; at gimbal lock (|pitch| = pi/2) roll is set to 0 and yaw absorbs
    the remaining rotation about z.
    """
    R = _arr(R)
    cp = np.hypot(R[..., 0, 0], R[..., 1, 0])
    pitch = np.arctan2(-R[..., 2, 0], cp)
    locked = cp < 1e-9
    yaw = np.where(locked, np.arctan2(-R[..., 0, 1], R[..., 1, 1]), np.arctan2(R[..., 1, 0], R[..., 0, 0]))
    roll = np.where(locked, 0.0, np.arctan2(R[..., 2, 1], R[..., 2, 2]))
    return yaw, pitch, roll


def yaw(R: np.ndarray) -> np.ndarray:
    """Yaw (...,) of the ZYX Euler decomposition."""
    return to_euler_zyx(R)[0]
