"""Planar odometry preintegration: many small (distance, heading change) increments between two
keyframes summed into one relative pose i_T_j with its covariance, the planar counterpart of IMU
preintegration (Forster, Carlone, Dellaert & Scaramuzza, "On-manifold preintegration for
real-time visual-inertial odometry", IEEE T-RO 33(1), 2017, sec. VI: iterate the increments,
propagate the covariance of the right perturbation).

One increment (d, dtheta) -- the arc length from the wheel encoders, the heading change from
the gyro -- moves along the chord of the arc, u = d sinc(dtheta/2) (cos(dtheta/2), sin(dtheta/2))
with heading change dtheta (the exact arc of ``slamkit.models.diff_drive``). With
Delta' = Delta o u and the right perturbation Delta Exp(xi):

    Sigma' = Ad(u^-1) Sigma Ad(u^-1)^T + J diag(var_d, var_dtheta) J^T,    J = du / d(d, dtheta)

which is the noise model of GTSAM's ``BetweenFactor<Pose2>`` (right tangent).
"""

from __future__ import annotations

import numpy as np

from slamkit.geometry import se2
from slamkit.models import diff_drive


def chord_increment(distance_m: float, dtheta_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """(u (3,), J (3, 2)): the relative pose of an arc of length ``distance_m`` turning
    ``dtheta_rad`` (``diff_drive``'s exact-arc motion from the origin with v dt = d, omega dt =
    dtheta) and the Jacobian of its right perturbation (u^-1 u(d + dd, dtheta + ddtheta) =
    Exp(J (dd, ddtheta))): the motion model's control Jacobian with its translation rows rotated
    into u's own frame by R(dtheta)^T."""
    control = np.array([distance_m, dtheta_rad], dtype=float)
    u = np.asarray(diff_drive.motion(np.zeros(3), control, 1.0), dtype=float)
    # the heading of an increment is not wrapped: a preintegrated turn may exceed pi
    u[2] = dtheta_rad
    _, L = diff_drive.motion_jacobians(np.zeros(3), control, 1.0)
    c, s = np.cos(dtheta_rad), np.sin(dtheta_rad)
    J = np.array(L, dtype=float)
    J[:2] = np.array([[c, s], [-s, c]]) @ J[:2]
    return u, J


class PlanarPreintegration:
    """Accumulates increments since the last :meth:`reset` (an engine: holds the running sum)."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.delta = np.zeros(3)
        self.covariance = np.zeros((3, 3))
        self.duration_s = 0.0

    def integrate(self, distance_m: float, dtheta_rad: float, var_distance: float, var_dtheta: float,
                  dt_s: float = 0.0) -> None:
        u, J = chord_increment(distance_m, dtheta_rad)
        Ad = se2.adjoint(se2.inverse(u))
        self.covariance = Ad @ self.covariance @ Ad.T + J @ np.diag([var_distance, var_dtheta]) @ J.T
        self.delta = se2.compose(self.delta, u)
        self.duration_s += dt_s
