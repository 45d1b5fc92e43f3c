"""Four-wheel mecanum platform.

Wheels at (+-l, +-w) from the centre (l half the wheelbase, w half the track), each driving
forward with rollers at 45 degrees in the usual "X" layout (seen from above the rollers of
the four wheels form an X; front-left and rear-right have gamma = -45 deg). The rim speed of
wheel i is (Lynch & Park, *Modern Robotics*, sec. 13.2.1, with beta = 0, gamma = -+45 deg,
rows ordered FL, FR, RL, RR):

    r phi_FL = v_x - v_y - (l + w) omega
    r phi_FR = v_x + v_y + (l + w) omega
    r phi_RL = v_x + v_y - (l + w) omega
    r phi_RR = v_x - v_y + (l + w) omega

Four wheels, three degrees of freedom: ``forward`` is the least-squares twist, the
pseudo-inverse (r/4) [[1, 1, 1, 1], [-1, 1, 1, -1], [-1, 1, -1, 1] / (l + w)]; ``inverse`` is exact, so forward(inverse(twist)) = twist and
inverse(forward(w)) = w for every consistent set of wheel speeds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.models.planar import LinearWheelKinematics

__all__ = ["Mecanum"]

WHEEL_ORDER = ("front_left", "front_right", "rear_left", "rear_right")


@dataclass(frozen=True)
class Mecanum(LinearWheelKinematics):
    wheel_radius_m: float = 0.05
    half_length_m: float = 0.2
    half_width_m: float = 0.15

    def __post_init__(self) -> None:
        for name in ("wheel_radius_m", "half_length_m", "half_width_m"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"Mecanum.{name} must be positive, got {getattr(self, name)}")

    def wheel_matrix(self) -> np.ndarray:
        """(4, 3) H in wheel order FL, FR, RL, RR: wheel speeds rad/s = H @ (v_x, v_y, omega)."""
        k = self.half_length_m + self.half_width_m
        return np.array([[1.0, -1.0, -k], [1.0, 1.0, k], [1.0, 1.0, -k], [1.0, -1.0, k]]) / self.wheel_radius_m
