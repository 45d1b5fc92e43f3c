"""Strapdown inertial mechanisation in a local level frame, and its error-state linearisation.

Nominal propagation over one IMU interval dt with the bias-corrected specific force a (m/s^2)
and body rate w (rad/s), both held constant over the interval (Forster et al., "On-Manifold
Preintegration for Real-Time Visual-Inertial Odometry", T-RO 33(1) 2017, eq. 31 -- the same
discretisation GTSAM's preintegration uses, so the filter and the smoothers integrate alike):

    p' = p + v dt + 1/2 (R a + g) dt^2,     v' = v + (R a + g) dt,     R' = R Exp(w dt)

Error state (15): dx = (dp, dv, dtheta, dba, dbg) with the attitude error a world-frame (left)
perturbation, R_true = Exp(dtheta) R, and biases b_true = b + db (Sola, "Quaternion kinematics
for the error-state Kalman filter", 2017, sec. 7, global angular error). The true inputs are
a_true = a_m - b_a - db_a - n_a and w_true = w_m - b_g - db_g - n_g, so to first order

    dp'     = dp + dv dt - 1/2 dt^2 (hat(R a) dtheta + R dba + R n_a)
    dv'     = dv - dt (hat(R a) dtheta + R dba + R n_a)
    dtheta' = dtheta - dt R' J_r(w dt) (dbg + n_g)
    dba'    = dba + w_ba,      dbg' = dbg + w_bg

which is :func:`error_transition` (F, the exact first-order Jacobian of the discrete step, checked
numerically in the tests) and :func:`noise_jacobian` (G). White noise of density sigma sampled at
dt has variance sigma^2 / dt; a bias random walk of density sigma_b adds sigma_b^2 dt per step
(:mod:`slamkit.models.imu`), so Q_d = G diag(sigma_a^2/dt, sigma_g^2/dt, sigma_ba^2 dt,
sigma_bg^2 dt) G^T (:func:`process_noise`).
"""

from __future__ import annotations

import numpy as np

from slamkit.geometry import so3
from slamkit.models.imu import ImuNoise

__all__ = ["propagate", "error_transition", "noise_jacobian", "process_noise", "ERROR_STATE_DIM"]

ERROR_STATE_DIM = 15
#: slices of the error state
P, V, TH, BA, BG = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)


def propagate(world_p_body: np.ndarray, world_v_body: np.ndarray, world_R_body: np.ndarray,
              accel_mps2: np.ndarray, gyro_radps: np.ndarray, dt_s: float, gravity_mps2: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One nominal step with bias-corrected inputs; returns (p', v', R')."""
    world_a = world_R_body @ accel_mps2 + gravity_mps2
    p = world_p_body + world_v_body * dt_s + 0.5 * world_a * dt_s * dt_s
    v = world_v_body + world_a * dt_s
    R = world_R_body @ so3.exp(gyro_radps * dt_s)
    return p, v, R


def error_transition(world_R_body: np.ndarray, accel_mps2: np.ndarray, gyro_radps: np.ndarray,
                     dt_s: float) -> np.ndarray:
    """F (15, 15): dx' = F dx for one step from attitude ``world_R_body`` with bias-corrected
    inputs (see the module docstring)."""
    F = np.eye(ERROR_STATE_DIM)
    Ra_hat = so3.hat(world_R_body @ accel_mps2)
    R_next = world_R_body @ so3.exp(gyro_radps * dt_s)
    F[P, V] = np.eye(3) * dt_s
    F[P, TH] = -0.5 * dt_s * dt_s * Ra_hat
    F[P, BA] = -0.5 * dt_s * dt_s * world_R_body
    F[V, TH] = -dt_s * Ra_hat
    F[V, BA] = -dt_s * world_R_body
    F[TH, BG] = -dt_s * R_next @ so3.right_jacobian(gyro_radps * dt_s)
    return F


def noise_jacobian(world_R_body: np.ndarray, gyro_radps: np.ndarray, dt_s: float) -> np.ndarray:
    """G (15, 12): how (n_a, n_g, w_ba, w_bg) of one step enter the error state."""
    G = np.zeros((ERROR_STATE_DIM, 12))
    G[P, 0:3] = -0.5 * dt_s * dt_s * world_R_body
    G[V, 0:3] = -dt_s * world_R_body
    G[TH, 3:6] = -dt_s * world_R_body @ so3.exp(gyro_radps * dt_s) @ so3.right_jacobian(gyro_radps * dt_s)
    G[BA, 6:9] = np.eye(3)
    G[BG, 9:12] = np.eye(3)
    return G


def process_noise(noise: ImuNoise, world_R_body: np.ndarray, gyro_radps: np.ndarray, dt_s: float) -> np.ndarray:
    """Q_d (15, 15) of one step of length ``dt_s`` (see the module docstring)."""
    G = noise_jacobian(world_R_body, gyro_radps, dt_s)
    q = np.repeat([noise.accel_noise_density**2 / dt_s, noise.gyro_noise_density**2 / dt_s,
                   noise.accel_bias_random_walk**2 * dt_s, noise.gyro_bias_random_walk**2 * dt_s], 3)
    return (G * q) @ G.T
