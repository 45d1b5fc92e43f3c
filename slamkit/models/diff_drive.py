"""Differential-drive robot: wheel kinematics, the velocity motion model and wheel odometry.

Conventions: a planar pose is ``world_xytheta_body = (x_m, y_m, theta_rad)`` (batch-first
``(..., 3)``); a control is ``u = (v_mps, omega_radps)`` in the body frame (x forward, y left);
wheel speeds are ``(..., 2) = [right, left]`` in rad/s.

Kinematics (Siegwart, Nourbakhsh & Scaramuzza, *Introduction to Autonomous Mobile Robots*,
2nd ed., sec. 3.2.1):

    v = r (w_R + w_L) / 2,        omega = r (w_R - w_L) / (2 l)

with wheel radius r and half axle length l (wheel-to-centre distance).

Motion model (Thrun, Burgard & Fox, *Probabilistic Robotics*, sec. 5.3, noise-free): holding
(v, omega) for dt the robot drives an arc. Instead of the textbook form
``x + v/w (sin(theta + w dt) - sin theta)``, which divides by omega, we use the identity

    sin(theta + a) - sin(theta) = 2 cos(theta + a/2) sin(a/2)

so the translation is ``v dt * sinc(a/2) * (cos, sin)(theta + a/2)`` with a = omega dt. This is
the same arc, exact for every omega, and reduces smoothly to the straight line at omega = 0
without a special case. The first-order ("straight-line") update
``x += v dt cos(theta)`` is kept beside it because many filters and textbooks use it.

Jacobians F = df/dx and L = df/du are those of the exact arc; the process noise in state
space is Q = L M L^T for control noise covariance M (the V M V^T term of EKF localisation,
Probabilistic Robotics Table 7.2, with V = L).

Odometry from encoders (Siegwart et al., sec. 5.2.4): each wheel turns 2 pi r ticks / N
metres; the centre travels the mean of the wheel distances and turns by their difference over
the axle length 2 l. Integration uses the exact arc or the straight-line approximation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.geometry.angles import wrap_angle

__all__ = [
    "DiffDrive",
    "motion",
    "motion_straight",
    "motion_jacobians",
    "motion_jacobians_batch",
    "motion_straight_jacobians",
    "process_noise",
    "odometry_from_ticks",
    "integrate_odometry",
    "sinc",
    "dsinc",
]


@dataclass(frozen=True)
class DiffDrive:
    """Wheel geometry of a differential-drive robot (SI units)."""

    wheel_radius_m: float = 0.1
    half_axle_m: float = 0.2

    def __post_init__(self) -> None:
        for name in ("wheel_radius_m", "half_axle_m"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ConfigError(f"DiffDrive.{name} must be positive and finite, got {value}")

    def forward(self, wheel_speeds_radps: np.ndarray) -> np.ndarray:
        """(..., 2) wheel speeds [right, left] rad/s -> (..., 2) body [v_mps, omega_radps]."""
        w = np.asarray(wheel_speeds_radps, dtype=float)
        r, l = self.wheel_radius_m, self.half_axle_m
        v = 0.5 * r * (w[..., 0] + w[..., 1])
        omega = r * (w[..., 0] - w[..., 1]) / (2.0 * l)
        return np.stack([v, omega], axis=-1)

    def inverse(self, v_omega: np.ndarray) -> np.ndarray:
        """(..., 2) body [v_mps, omega_radps] -> (..., 2) wheel speeds [right, left] rad/s."""
        u = np.asarray(v_omega, dtype=float)
        r, l = self.wheel_radius_m, self.half_axle_m
        right = (u[..., 0] + l * u[..., 1]) / r
        left = (u[..., 0] - l * u[..., 1]) / r
        return np.stack([right, left], axis=-1)

    def forward_jacobian(self) -> np.ndarray:
        """(2, 2) d[v, omega] / d[w_R, w_L] (constant: the kinematics are linear)."""
        r, l = self.wheel_radius_m, self.half_axle_m
        return np.array([[0.5 * r, 0.5 * r], [r / (2 * l), -r / (2 * l)]])


# ---------------------------------------------------------------------------------------------
# Numerically safe sinc and its derivative (the arc formula's only "division by omega").

_SERIES_BELOW = 1e-2


def sinc(z):
    """sin(z) / z with sinc(0) = 1 (unnormalised; numpy's sinc is sin(pi z)/(pi z))."""
    return np.sinc(np.asarray(z, dtype=float) / np.pi)


def dsinc(z):
    """d/dz of sin(z)/z = (z cos z - sin z) / z^2; Taylor series near 0 avoids cancellation."""
    z = np.asarray(z, dtype=float)
    small = np.abs(z) < _SERIES_BELOW
    zs = np.where(small, 1.0, z)  # keep the unused branch finite
    direct = (zs * np.cos(zs) - np.sin(zs)) / (zs * zs)
    series = -z / 3.0 + z**3 / 30.0 - z**5 / 840.0
    return np.where(small, series, direct)


# ---------------------------------------------------------------------------------------------
# Velocity motion model


def _split(world_xytheta_body, u):
    x = np.asarray(world_xytheta_body, dtype=float)
    u = np.asarray(u, dtype=float)
    if x.shape[-1:] != (3,):
        raise ConfigError(f"pose must have shape (..., 3), got {x.shape}")
    if u.shape[-1:] != (2,):
        raise ConfigError(f"control u must have shape (..., 2) = (v_mps, omega_radps), got {u.shape}")
    return x, u


def motion(world_xytheta_body, u, dt_s):
    """Exact-arc velocity motion model: (..., 3) pose, (..., 2) (v, omega), dt -> (..., 3).

    Broadcasts over leading axes, so one call moves N particles with N noisy controls.
    The returned heading is wrapped to [-pi, pi).
    """
    x, u = _split(world_xytheta_body, u)
    dt = np.asarray(dt_s, dtype=float)
    theta = x[..., 2]
    dist = u[..., 0] * dt
    a = u[..., 1] * dt
    s = sinc(0.5 * a)
    phi = theta + 0.5 * a
    out = np.stack(
        [x[..., 0] + dist * s * np.cos(phi), x[..., 1] + dist * s * np.sin(phi), wrap_angle(theta + a)],
        axis=-1,
    )
    return out


def motion_straight(world_xytheta_body, u, dt_s):
    """First-order (straight-line) update: x += v dt cos(theta), y += v dt sin(theta),
    theta += omega dt. Broadcasts like :func:`motion`; heading wrapped."""
    x, u = _split(world_xytheta_body, u)
    dt = np.asarray(dt_s, dtype=float)
    theta = x[..., 2]
    dist = u[..., 0] * dt
    return np.stack(
        [x[..., 0] + dist * np.cos(theta), x[..., 1] + dist * np.sin(theta), wrap_angle(theta + u[..., 1] * dt)],
        axis=-1,
    )


def motion_jacobians(world_xytheta_body, u, dt_s):
    """Jacobians of :func:`motion`: F = df/dx (..., 3, 3) and L = df/du (..., 3, 2).

    With D = v dt, a = omega dt, s = sinc(a/2), phi = theta + a/2:
        f = x + [D s cos phi, D s sin phi, a]
    For single inputs (3,), (2,) the result is (3, 3), (3, 2); leading axes broadcast.
    """
    x, u = _split(world_xytheta_body, u)
    dt = np.asarray(dt_s, dtype=float)
    theta = x[..., 2]
    v, w = u[..., 0], u[..., 1]
    shape = np.broadcast_shapes(theta.shape, v.shape, dt.shape)
    theta, v, w, dt = (np.broadcast_to(t, shape) for t in (theta, v, w, dt))
    dist = v * dt
    a = w * dt
    s = sinc(0.5 * a)
    ds = dsinc(0.5 * a)
    phi = theta + 0.5 * a
    c, sn = np.cos(phi), np.sin(phi)

    F = np.zeros(shape + (3, 3))
    F[..., 0, 0] = 1.0
    F[..., 1, 1] = 1.0
    F[..., 2, 2] = 1.0
    F[..., 0, 2] = -dist * s * sn
    F[..., 1, 2] = dist * s * c

    L = np.zeros(shape + (3, 2))
    L[..., 0, 0] = dt * s * c
    L[..., 1, 0] = dt * s * sn
    # d/domega: s depends on a/2 and phi on a/2, with da/domega = dt
    L[..., 0, 1] = dist * 0.5 * dt * (ds * c - s * sn)
    L[..., 1, 1] = dist * 0.5 * dt * (ds * sn + s * c)
    L[..., 2, 1] = dt
    return F, L


def motion_jacobians_batch(world_xytheta_body, u, dt_s):
    """Batch form of :func:`motion_jacobians` for (N, 3) poses and (N, 2) or (2,) controls:
    returns (N, 3, 3), (N, 3, 2). (``motion_jacobians`` already broadcasts; this name only
    checks the batch shape so a caller that forgot the leading axis gets a clear error.)"""
    x = np.asarray(world_xytheta_body, dtype=float)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ConfigError(f"motion_jacobians_batch expects poses of shape (N, 3), got {x.shape}")
    return motion_jacobians(x, u, dt_s)


def motion_straight_jacobians(world_xytheta_body, u, dt_s):
    """Jacobians of :func:`motion_straight`: F (..., 3, 3), L (..., 3, 2)."""
    x, u = _split(world_xytheta_body, u)
    dt = np.asarray(dt_s, dtype=float)
    theta = x[..., 2]
    v = u[..., 0]
    shape = np.broadcast_shapes(theta.shape, v.shape, dt.shape)
    theta, v, dt = (np.broadcast_to(t, shape) for t in (theta, v, dt))
    c, sn = np.cos(theta), np.sin(theta)
    F = np.zeros(shape + (3, 3))
    F[..., 0, 0] = F[..., 1, 1] = F[..., 2, 2] = 1.0
    F[..., 0, 2] = -v * dt * sn
    F[..., 1, 2] = v * dt * c
    L = np.zeros(shape + (3, 2))
    L[..., 0, 0] = dt * c
    L[..., 1, 0] = dt * sn
    L[..., 2, 1] = dt
    return F, L


def process_noise(world_xytheta_body, u, dt_s, M):
    """State-space process noise Q = L M L^T (..., 3, 3) for control covariance M (2, 2)
    (or (..., 2, 2)) of (v, omega), linearised at (x, u) through the exact arc."""
    M = np.asarray(M, dtype=float)
    if M.shape[-2:] != (2, 2):
        raise ConfigError(f"control covariance M must be (2, 2), got {M.shape}")
    _, L = motion_jacobians(world_xytheta_body, u, dt_s)
    return L @ M @ np.swapaxes(L, -1, -2)


# ---------------------------------------------------------------------------------------------
# Wheel odometry


def odometry_from_ticks(ticks_right, ticks_left, ticks_per_rev, wheel_radius_m, half_axle_m):
    """Encoder tick increments -> (distance_m, dtheta_rad) of the robot centre.

    Each wheel rolls 2 pi r ticks / N; the centre moves their mean and turns by their
    difference over the axle length 2 l. Broadcasts over array inputs.
    """
    if not ticks_per_rev > 0:
        raise ConfigError(f"ticks_per_rev must be positive, got {ticks_per_rev}")
    per_tick = 2.0 * np.pi * wheel_radius_m / ticks_per_rev
    d_right = np.asarray(ticks_right, dtype=float) * per_tick
    d_left = np.asarray(ticks_left, dtype=float) * per_tick
    return 0.5 * (d_right + d_left), (d_right - d_left) / (2.0 * half_axle_m)


def integrate_odometry(world_xytheta_body, distance_m, dtheta_rad, exact: bool = True):
    """Apply one odometry increment (distance along the path, heading change) to a pose.

    ``exact=True`` follows the circular arc (the velocity model with v dt = d, omega dt =
    dtheta); ``exact=False`` is the straight-line approximation x += d cos(theta),
    theta += dtheta. Broadcasts over leading axes.
    """
    u = np.stack(np.broadcast_arrays(np.asarray(distance_m, float), np.asarray(dtheta_rad, float)), axis=-1)
    step = motion if exact else motion_straight
    return step(world_xytheta_body, u, 1.0)
