"""Tracked (skid-steer) vehicle with a slip model.

Tracks slip on the ground, so the ideal diff-drive relation v = (V_R + V_L)/2,
omega = (V_R - V_L)/B over-predicts both speed and turn rate. We use the instantaneous-centres-
of-rotation (ICR) model of Martinez, Mandow, Morales, Pedraza & Garcia-Cerezo, "Approximating
kinematics for tracked mobile robots", IJRR 24(10), 2005, sec. 3, with longitudinal slip ratios
on top (Wong, *Theory of Ground Vehicles*, slip i = 1 - V_actual / V_track):

    V_L' = (1 - s_L) V_L,   V_R' = (1 - s_R) V_R          (effective track speeds, m/s)
    v_x   = (V_R' y_L - V_L' y_R) / (y_L - y_R)
    v_y   = (V_L' - V_R') x_v / (y_L - y_R)
    omega = (V_R' - V_L') / (y_L - y_R)

where y_L > 0 > y_R are the lateral positions of the tracks' ICRs and x_v is the longitudinal
shift of the vehicle ICR (a lateral skid when turning). With no slip, y_L = B/2, y_R = -B/2,
x_v = 0 this is exactly the differential drive. The map from track speeds to (v_x, omega) is
invertible, so ``inverse`` recovers the track speeds from (v_x, omega); v_y is then implied.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.models import planar

__all__ = ["Tracked"]


@dataclass(frozen=True)
class Tracked:
    """Track geometry and slip parameters. ``icr_left_m``/``icr_right_m`` default to the
    track positions +-B/2 (no lateral slip); slips are fractions in [0, 1)."""

    track_width_m: float = 0.5
    slip_left: float = 0.0
    slip_right: float = 0.0
    icr_left_m: float | None = None
    icr_right_m: float | None = None
    icr_x_m: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.track_width_m) and self.track_width_m > 0):
            raise ConfigError(f"Tracked.track_width_m must be positive, got {self.track_width_m}")
        for name in ("slip_left", "slip_right"):
            if not 0 <= getattr(self, name) < 1:
                raise ConfigError(f"Tracked.{name} must lie in [0, 1), got {getattr(self, name)}")
        if not self.y_left > 0 > self.y_right:
            raise ConfigError(f"Tracked ICRs need icr_left_m > 0 > icr_right_m, got {self.y_left}, {self.y_right}")

    @property
    def y_left(self) -> float:
        return 0.5 * self.track_width_m if self.icr_left_m is None else float(self.icr_left_m)

    @property
    def y_right(self) -> float:
        return -0.5 * self.track_width_m if self.icr_right_m is None else float(self.icr_right_m)

    def forward_matrix(self) -> np.ndarray:
        """(3, 2): body twist (v_x, v_y, omega) = A @ [V_R, V_L] track speeds (linear model)."""
        yl, yr, xv = self.y_left, self.y_right, self.icr_x_m
        d = yl - yr
        kr, kl = 1.0 - self.slip_right, 1.0 - self.slip_left
        return np.array([[kr * yl / d, -kl * yr / d], [-kr * xv / d, kl * xv / d], [kr / d, -kl / d]])

    def forward(self, track_speeds_mps):
        """(..., 2) track speeds [right, left] m/s -> (..., 3) body twist (v_x, v_y, omega)."""
        v = np.asarray(track_speeds_mps, dtype=float)
        return v @ self.forward_matrix().T

    def inverse(self, twist_body):
        """(..., 2) (v_x, omega) or (..., 3) (v_x, v_y, omega) -> (..., 2) track speeds [right, left].

        From omega and v_x alone (v_y is implied by the ICR shift and ignored):
        V_L' = v_x - omega y_L, V_R' = v_x - omega y_R, then undo the slip.
        """
        t = np.asarray(twist_body, dtype=float)
        vx, w = t[..., 0], t[..., -1]
        right = (vx - w * self.y_right) / (1.0 - self.slip_right)
        left = (vx - w * self.y_left) / (1.0 - self.slip_left)
        return np.stack([right, left], axis=-1)

    def motion(self, world_xytheta_body, track_speeds_mps, dt_s):
        """Exact SE(2) integration of the slipping twist held for dt -> (..., 3) pose."""
        return planar.motion_twist(world_xytheta_body, self.forward(track_speeds_mps), dt_s)

    def motion_jacobians(self, world_xytheta_body, track_speeds_mps, dt_s):
        """F (..., 3, 3) and L = df/d(track speeds) (..., 3, 2)."""
        F, L = planar.motion_twist_jacobians(world_xytheta_body, self.forward(track_speeds_mps), dt_s)
        return F, L @ self.forward_matrix()
