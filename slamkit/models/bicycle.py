"""Kinematic bicycle (Ackermann) model, referenced at the centre of the rear axle.

Control u = (v_mps, steer_rad): rear-axle speed and front-wheel steering angle. Without slip
the rear axle moves along a circle of curvature (Rajamani, *Vehicle Dynamics and Control*,
2nd ed., sec. 2.2; Thrun et al. use the same geometry for car-like robots):

    kappa = tan(delta) / L,   omega = v kappa,   R = 1 / kappa = L / tan(delta)

and the instantaneous centre of curvature (ICC) lies on the rear-axle line, a distance R to
the left of the robot: ICC = (x - R sin(theta), y + R cos(theta)). At delta = 0 the centre is
at infinity (returned as NaN).

The steering angle is clipped to +-max_steer_rad. The discrete motion is the exact arc of
``slamkit.models.diff_drive.motion`` with omega = v tan(delta) / L, so by the chain rule
L_bicycle = L_unicycle @ d(v, omega)/d(v, delta), with d omega / d delta = v / (L cos^2 delta)
inside the limits and 0 where the steering is saturated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.models import diff_drive

__all__ = ["Bicycle"]


@dataclass(frozen=True)
class Bicycle:
    """Car-like robot: wheelbase and symmetric steering limit (SI units)."""

    wheelbase_m: float = 2.5
    max_steer_rad: float = float(np.deg2rad(35.0))

    def __post_init__(self) -> None:
        if not (np.isfinite(self.wheelbase_m) and self.wheelbase_m > 0):
            raise ConfigError(f"Bicycle.wheelbase_m must be positive, got {self.wheelbase_m}")
        if not (0 < self.max_steer_rad < np.pi / 2):
            raise ConfigError(f"Bicycle.max_steer_rad must lie in (0, pi/2), got {self.max_steer_rad}")

    def clip_steer(self, steer_rad):
        return np.clip(np.asarray(steer_rad, dtype=float), -self.max_steer_rad, self.max_steer_rad)

    def curvature(self, steer_rad):
        """kappa = tan(delta) / L in 1/m (steering clipped to the limits)."""
        return np.tan(self.clip_steer(steer_rad)) / self.wheelbase_m

    @property
    def min_turning_radius_m(self) -> float:
        return self.wheelbase_m / np.tan(self.max_steer_rad)

    def icc(self, world_xytheta_body, steer_rad):
        """(..., 2) world position of the instantaneous centre of curvature; NaN when straight."""
        x = np.asarray(world_xytheta_body, dtype=float)
        kappa = np.asarray(self.curvature(steer_rad))
        with np.errstate(divide="ignore"):
            radius = np.where(kappa == 0.0, np.nan, 1.0 / np.where(kappa == 0.0, 1.0, kappa))
        return np.stack([x[..., 0] - radius * np.sin(x[..., 2]), x[..., 1] + radius * np.cos(x[..., 2])], axis=-1)

    def to_unicycle(self, u):
        """(..., 2) (v, delta) -> (..., 2) (v, omega) with clipped steering."""
        u = np.asarray(u, dtype=float)
        return np.stack([u[..., 0], u[..., 0] * self.curvature(u[..., 1])], axis=-1)

    def from_unicycle(self, v_omega):
        """(..., 2) (v, omega) -> (..., 2) (v, delta): delta = atan(omega L / v). Raises when
        v = 0 with omega != 0 (a car cannot turn on the spot) or the steering limit is exceeded."""
        u = np.asarray(v_omega, dtype=float)
        v, w = u[..., 0], u[..., 1]
        if np.any((v == 0) & (w != 0)):
            raise ConfigError("bicycle cannot realise omega != 0 at v = 0")
        with np.errstate(divide="ignore", invalid="ignore"):
            delta = np.where(v == 0, 0.0, np.arctan(w * self.wheelbase_m / np.where(v == 0, 1.0, v)))
        if np.any(np.abs(delta) > self.max_steer_rad + 1e-12):
            raise ConfigError(f"requested curvature needs |steer| > max_steer_rad = {self.max_steer_rad}")
        return np.stack([v, delta], axis=-1)

    def motion(self, world_xytheta_body, u, dt_s):
        """Exact arc for (..., 2) controls (v_mps, steer_rad) held for dt -> (..., 3) pose."""
        return diff_drive.motion(world_xytheta_body, self.to_unicycle(u), dt_s)

    def motion_jacobians(self, world_xytheta_body, u, dt_s):
        """F = df/dx (..., 3, 3) and L = df/d(v, steer) (..., 3, 2)."""
        u = np.asarray(u, dtype=float)
        F, L_uni = diff_drive.motion_jacobians(world_xytheta_body, self.to_unicycle(u), dt_s)
        v, delta = u[..., 0], u[..., 1]
        inside = np.abs(delta) < self.max_steer_rad
        dw_ddelta = np.where(inside, v / (self.wheelbase_m * np.cos(self.clip_steer(delta)) ** 2), 0.0)
        J = np.zeros(np.shape(v) + (2, 2))
        J[..., 0, 0] = 1.0
        J[..., 1, 0] = self.curvature(delta)
        J[..., 1, 1] = dw_ddelta
        return F, L_uni @ J
