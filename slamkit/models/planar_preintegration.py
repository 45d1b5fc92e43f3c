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
from slamkit.models.diff_drive import dsinc, sinc


def chord_increment(distance_m: float, dtheta_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """(u (3,), J (3, 2)): the relative pose of an arc of length ``distance_m`` turning
    ``dtheta_rad`` (its chord d sinc(dtheta/2) at dtheta/2) and the Jacobian of its right
    perturbation (u^-1 u(d + dd, dtheta + ddtheta) = Exp(J (dd, ddtheta))): the derivative of
    u's coordinates with its translation rows rotated into u's own frame by R(dtheta)^T."""
    h = 0.5 * dtheta_rad
    c, s = np.cos(h), np.sin(h)
    k, dk = float(sinc(h)), float(dsinc(h))
    u = np.array([distance_m * k * c, distance_m * k * s, dtheta_rad])
    # d(u_xy)/d(d, dtheta): [[k c, d (dk c - k s) / 2], [k s, d (dk s + k c) / 2]]
    coords = np.array([[k * c, 0.5 * distance_m * (dk * c - k * s)],
                       [k * s, 0.5 * distance_m * (dk * s + k * c)]])
    c2, s2 = np.cos(dtheta_rad), np.sin(dtheta_rad)
    J = np.vstack([np.array([[c2, s2], [-s2, c2]]) @ coords, [0.0, 1.0]])
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
