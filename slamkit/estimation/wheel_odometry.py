"""Dead reckoning from wheel encoders: every tick increment becomes (distance, heading change)
of the robot centre (``diff_drive.odometry_from_ticks``, with the wheel calibration the robot
believes) and moves the pose along the arc (``diff_drive.integrate_odometry``).

Covariance: each wheel's travelled distance d gets variance ``k^2 |d|`` (k =
``wheel_sigma_per_sqrt_m``, the error model of Borenstein & Feng, "Measurement and correction of
systematic odometry errors in mobile robots", IEEE T-RA 12(6), 1996, for non-systematic errors),
mapped to (distance, heading) and through the control Jacobian of the arc model (Thrun et al.,
*Probabilistic Robotics*, eq. 7.11). Systematic errors (a wrong wheel radius, slip) are not in
it: they are what fusing other sensors is for.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from slamkit.data.estimate import Prior
from slamkit.data.sequence import Odometry, RangeBearing, Sequence, WheelEncoders
from slamkit.errors import ConfigError
from slamkit.estimation._common import FilterBase
from slamkit.estimation.fusion_ekf import WheelCalibration
from slamkit.models import diff_drive


@dataclass(frozen=True)
class WheelOdometryConfig:
    #: standard deviation of a wheel's distance per sqrt(metre) travelled
    wheel_sigma_per_sqrt_m: float = 0.01

    def __post_init__(self) -> None:
        if not self.wheel_sigma_per_sqrt_m >= 0:
            raise ConfigError(f"WheelOdometryConfig.wheel_sigma_per_sqrt_m must be >= 0, got {self.wheel_sigma_per_sqrt_m}")


class WheelOdometry(FilterBase):
    """Encoder dead reckoning (registry name ``dead_reckoning``); other events are ignored."""

    name = "dead_reckoning"

    def __init__(self, calibration: WheelCalibration | None,
                 config: WheelOdometryConfig = WheelOdometryConfig()) -> None:
        super().__init__()
        self.calibration = calibration
        self.config = config

    @classmethod
    def from_sequence(cls, sequence: Sequence, config: WheelOdometryConfig = WheelOdometryConfig()
                      ) -> "WheelOdometry":
        """With the wheel calibration the sequence's metadata states (what the robot believes)."""
        return cls(WheelCalibration.from_metadata(sequence.metadata), config)

    def _reset(self, prior: Prior) -> None:
        self.x = np.asarray(prior.world_xytheta_body, dtype=float).copy()
        self.P = np.asarray(prior.covariance, dtype=float).copy()

    def _predict(self, odometry: Odometry) -> None:
        self._ignored += 1  # a velocity command is not a wheel measurement

    def _update(self, observation: RangeBearing) -> None:
        self._ignored += 1

    def _encoders(self, encoders: WheelEncoders) -> None:
        cal = WheelCalibration.required(self.calibration, self.name)
        d, dth = (float(v) for v in diff_drive.odometry_from_ticks(
            encoders.ticks_right, encoders.ticks_left, cal.ticks_per_rev, cal.wheel_radius_m, cal.half_axle_m))
        # wheel distances d_R, d_L -> (d, dtheta) = A (d_R, d_L)
        per_tick = 2.0 * np.pi * cal.wheel_radius_m / cal.ticks_per_rev
        var = self.config.wheel_sigma_per_sqrt_m ** 2 * np.abs(
            np.array([encoders.ticks_right, encoders.ticks_left], dtype=float) * per_tick)
        A = np.array([[0.5, 0.5], [0.5 / cal.half_axle_m, -0.5 / cal.half_axle_m]])
        u = np.array([d, dth])
        F, L = diff_drive.motion_jacobians(self.x, u, 1.0)
        self.P = F @ self.P @ F.T + L @ (A @ np.diag(var) @ A.T) @ L.T
        self.x = np.asarray(diff_drive.integrate_odometry(self.x, d, dth), dtype=float).reshape(3)

    def _pose_and_covariance(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x.copy(), self.P.copy()

    def _extras(self) -> dict[str, Any]:
        return {}
