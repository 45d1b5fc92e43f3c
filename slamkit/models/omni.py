"""Three-wheel omnidirectional robot (omni wheels with free rollers, "Kiwi drive").

Wheel i sits at distance d from the centre at angle alpha_i in the body frame, and drives
tangentially, direction (-sin alpha_i, cos alpha_i); its rollers make it free radially. The
rim speed of wheel i is the body velocity at the wheel projected on that direction
(Siegwart et al., *Introduction to Autonomous Mobile Robots*, sec. 3.2.3; Lynch & Park,
*Modern Robotics*, sec. 13.2.1, with roller angle gamma = 0):

    r phi_dot_i = -sin(alpha_i) v_x + cos(alpha_i) v_y + d omega

det H = d / r^3 times twice the area of the triangle of the points (-sin alpha_i, cos alpha_i)
on the unit circle, so H is invertible whenever the three wheel angles are distinct modulo
2 pi, and forward and inverse kinematics are exact inverses. Default angles 0, 120, 240 degrees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.models.planar import LinearWheelKinematics

__all__ = ["Omni3"]


@dataclass(frozen=True)
class Omni3(LinearWheelKinematics):
    wheel_radius_m: float = 0.05
    center_distance_m: float = 0.2
    wheel_angles_rad: tuple[float, float, float] = (0.0, 2.0 * np.pi / 3.0, 4.0 * np.pi / 3.0)

    def __post_init__(self) -> None:
        if not (self.wheel_radius_m > 0 and self.center_distance_m > 0):
            raise ConfigError("Omni3.wheel_radius_m and center_distance_m must be positive, got "
                              f"{self.wheel_radius_m}, {self.center_distance_m}")
        if len(self.wheel_angles_rad) != 3:
            raise ConfigError(f"Omni3.wheel_angles_rad needs 3 angles, got {self.wheel_angles_rad}")
        object.__setattr__(self, "wheel_angles_rad", tuple(float(a) for a in self.wheel_angles_rad))
        if np.linalg.cond(self.wheel_matrix()) > 1e8:
            raise ConfigError(f"Omni3.wheel_angles_rad {self.wheel_angles_rad} give a singular "
                              "wheel matrix (two wheels at the same angle)")

    def wheel_matrix(self) -> np.ndarray:
        """(3, 3) H: wheel speeds rad/s = H @ (v_x, v_y, omega)."""
        a = np.asarray(self.wheel_angles_rad)
        return np.stack([-np.sin(a), np.cos(a), np.full(3, self.center_distance_m)], axis=-1) / self.wheel_radius_m
