"""Planar odometry preintegration: many small (distance, heading change) increments between two
keyframes summed into one relative pose i_T_j with its covariance, the planar counterpart of IMU
preintegration (Forster, Carlone, Dellaert & Scaramuzza, "On-manifold preintegration for
real-time visual-inertial odometry", IEEE T-RO 33(1), 2017, sec. VI: iterate the increments,
propagate the covariance of the right perturbation).

One increment (d, dtheta) -- the distance from the wheel encoders, the heading change from the
gyro -- moves along the chord of the arc, u = (d cos(dtheta/2), d sin(dtheta/2), dtheta). With
Delta' = Delta o u and the right perturbation Delta Exp(xi):

    Sigma' = Ad(u^-1) Sigma Ad(u^-1)^T + J diag(var_d, var_dtheta) J^T,    J = du / d(d, dtheta)

which is the noise model of GTSAM's ``BetweenFactor<Pose2>`` (right tangent).
"""

from __future__ import annotations

import numpy as np

from slamkit.geometry import se2


def chord_increment(distance_m: float, dtheta_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """(u (3,), J (3, 2)): the relative pose of one increment and its Jacobian wrt (d, dtheta)."""
    h = 0.5 * dtheta_rad
    c, s = np.cos(h), np.sin(h)
    u = np.array([distance_m * c, distance_m * s, dtheta_rad])
    J = np.array([[c, -0.5 * distance_m * s], [s, 0.5 * distance_m * c], [0.0, 1.0]])
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
