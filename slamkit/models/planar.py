"""Exact integration of a constant body twist (v_x, v_y, omega) on SE(2), with Jacobians.

Every planar robot model reduces to a body twist: diff drive and bicycle have v_y = 0,
holonomic platforms (omni, mecanum) and a slipping tracked vehicle do not. Holding the twist
for dt moves the pose by the group exponential (Lynch & Park, *Modern Robotics*, sec. 13.4 "Odometry";
Barfoot, *State Estimation for Robotics*, ch. 7):

    world_T_body(t + dt) = world_T_body(t) o exp(dt * (v_x, v_y, omega))

with the SE(2) exponential translation V(a) (v_x dt, v_y dt), a = omega dt,
V(a) = [[S, -C], [C, S]], S = sin(a)/a, C = (1 - cos a)/a = (a/2) sinc(a/2)^2.
The value comes from ``slamkit.geometry.se2``; the Jacobians F = df/dx and
L = df/d(twist) are written out here.
"""

from __future__ import annotations

import numpy as np

from slamkit.errors import ConfigError
from slamkit.geometry import se2
from slamkit.models.diff_drive import dsinc, sinc

__all__ = ["motion_twist", "motion_twist_jacobians", "LinearWheelKinematics"]


def _check(world_xytheta_body, twist_body):
    x = np.asarray(world_xytheta_body, dtype=float)
    t = np.asarray(twist_body, dtype=float)
    if x.shape[-1:] != (3,):
        raise ConfigError(f"pose must have shape (..., 3), got {x.shape}")
    if t.shape[-1:] != (3,):
        raise ConfigError(f"body twist must have shape (..., 3) = (v_x, v_y, omega), got {t.shape}")
    return x, t


def motion_twist(world_xytheta_body, twist_body, dt_s):
    """(..., 3) pose, (..., 3) body twist (v_x_mps, v_y_mps, omega_radps), dt -> (..., 3) pose."""
    x, t = _check(world_xytheta_body, twist_body)
    dt = np.asarray(dt_s, dtype=float)
    return se2.compose(x, se2.exp(t * dt[..., None]))


def motion_twist_jacobians(world_xytheta_body, twist_body, dt_s):
    """F = df/dx (..., 3, 3) and L = df/d(twist) (..., 3, 3) of :func:`motion_twist`."""
    x, t = _check(world_xytheta_body, twist_body)
    dt = np.asarray(dt_s, dtype=float)
    shape = np.broadcast_shapes(x.shape[:-1], t.shape[:-1], dt.shape)
    x = np.broadcast_to(x, shape + (3,))
    t = np.broadcast_to(t, shape + (3,))
    dt = np.broadcast_to(dt, shape)
    a = t[..., 2] * dt
    dx, dy = t[..., 0] * dt, t[..., 1] * dt
    half = 0.5 * a
    S = sinc(a)
    dS = dsinc(a)
    C = half * sinc(half) ** 2
    dC = 0.5 * sinc(half) ** 2 + half * sinc(half) * dsinc(half)  # d/da of (a/2) sinc(a/2)^2
    # body-frame translation and its derivative with respect to a
    bx, by = S * dx - C * dy, C * dx + S * dy
    dbx, dby = dS * dx - dC * dy, dC * dx + dS * dy
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])

    def rot(px, py):
        return c * px - s * py, s * px + c * py

    wx, wy = rot(bx, by)
    F = np.zeros(shape + (3, 3))
    F[..., 0, 0] = F[..., 1, 1] = F[..., 2, 2] = 1.0
    F[..., 0, 2] = -wy
    F[..., 1, 2] = wx

    L = np.zeros(shape + (3, 3))
    L[..., 0, 0], L[..., 1, 0] = rot(S * dt, C * dt)  # d/dv_x
    L[..., 0, 1], L[..., 1, 1] = rot(-C * dt, S * dt)  # d/dv_y
    ox, oy = rot(dbx, dby)
    L[..., 0, 2], L[..., 1, 2] = ox * dt, oy * dt  # d/domega through a = omega dt
    L[..., 2, 2] = dt
    return F, L


class LinearWheelKinematics:
    """Mixin for platforms whose wheel speeds are linear in the body twist:
    wheel_speeds_radps = H @ (v_x, v_y, omega) with H = ``self.wheel_matrix()`` (n_wheels, 3).

    ``inverse`` applies H; ``forward`` applies its pseudo-inverse, the least-squares twist for
    possibly inconsistent wheel speeds (Lynch & Park, *Modern Robotics*, sec. 13.2.1 and 13.4).
    forward(inverse(twist)) == twist whenever H has full column rank; inverse(forward(w)) == w
    only for wheel speeds in the range of H (always, when H is square and invertible).
    """

    def wheel_matrix(self) -> np.ndarray:  # pragma: no cover - implemented by subclasses
        raise NotImplementedError

    def forward_matrix(self) -> np.ndarray:
        """(3, n_wheels): twist = F @ wheel speeds (the Moore-Penrose pseudo-inverse of H)."""
        return np.linalg.pinv(self.wheel_matrix())

    def forward(self, wheel_speeds_radps):
        """(..., n_wheels) wheel speeds rad/s -> (..., 3) body twist (v_x, v_y, omega)."""
        return np.asarray(wheel_speeds_radps, dtype=float) @ self.forward_matrix().T

    def inverse(self, twist_body):
        """(..., 3) body twist (v_x, v_y, omega) -> (..., n_wheels) wheel speeds rad/s."""
        return np.asarray(twist_body, dtype=float) @ self.wheel_matrix().T

    def motion(self, world_xytheta_body, wheel_speeds_radps, dt_s):
        return motion_twist(world_xytheta_body, self.forward(wheel_speeds_radps), dt_s)

    def motion_jacobians(self, world_xytheta_body, wheel_speeds_radps, dt_s):
        """F (..., 3, 3) and L = df/d(wheel speeds) (..., 3, n_wheels)."""
        F, L = motion_twist_jacobians(world_xytheta_body, self.forward(wheel_speeds_radps), dt_s)
        return F, L @ self.forward_matrix()
