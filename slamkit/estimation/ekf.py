"""Extended Kalman filter: a generic predict/update on user functions, and EKF localization of a
differential-drive robot against a known landmark map.

Thrun, Burgard & Fox, *Probabilistic Robotics*, Table 3.3 (EKF) and Table 7.2 (EKF localization
with known correspondences; range-only events update with the scalar r = |m - p|,
``slamkit.models.range_only``, here with velocity noise mapped through the control Jacobian, eq.
7.11, and the exact-arc motion model of ``slamkit.models.diff_drive``). Unknown correspondences
(``landmark_ids == -1``) are resolved by maximum likelihood over the map (Table 7.3) behind a
chi-square gate. Covariance updates use the Joseph form; innovations wrap the bearing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from slamkit.data.sequence import Gps, Odometry, Range, RangeBearing
from slamkit.estimation._gaussian_localization import GaussianLocalization
from slamkit.estimation._common import (
    NoiseParams,
    observation_rows,
    range_bearing_residual,
)
from slamkit.geometry.angles import wrap_angle
from slamkit.models import diff_drive, range_bearing, range_only


def ekf_predict(x: np.ndarray, P: np.ndarray, f: Callable[[np.ndarray], np.ndarray],
                F: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x- = f(x), P- = F P F^T + Q (F the Jacobian of f at x)."""
    return f(x), F @ P @ F.T + Q


def ekf_update(x: np.ndarray, P: np.ndarray, z: np.ndarray, z_hat: np.ndarray, H: np.ndarray,
               R: np.ndarray, residual: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One EKF update in Joseph form. Returns (x+, P+, nu, S); ``residual(z, z_hat)`` lets angles
    wrap (default plain difference)."""
    nu = residual(z, z_hat) if residual is not None else z - z_hat
    PHt = P @ H.T
    S = H @ PHt + R
    K = np.linalg.solve(S.T, PHt.T).T
    I_KH = np.eye(len(x)) - K @ H
    P_new = I_KH @ P @ I_KH.T + K @ R @ K.T
    return x + K @ nu, 0.5 * (P_new + P_new.T), nu, S


class ExtendedKalmanFilter:
    """Generic EKF holding (x, P) for user-supplied models.

    ``f(x, u) -> x'`` with ``F_jac(x, u) -> (n, n)``; ``h(x) -> z`` with ``H_jac(x) -> (m, n)``;
    optional ``residual(z, z_hat)`` and ``normalize(x)`` (for example wrap a heading).
    """

    def __init__(self, f, F_jac, h, H_jac, Q, R, residual=None, normalize=None) -> None:
        self.f, self.F_jac, self.h, self.H_jac = f, F_jac, h, H_jac
        self.Q, self.R = np.atleast_2d(Q), np.atleast_2d(R)
        self.residual = residual
        self.normalize = normalize or (lambda x: x)
        self.x = np.zeros(self.Q.shape[0])
        self.P = np.eye(self.Q.shape[0])

    def predict(self, u) -> None:
        F = self.F_jac(self.x, u)
        x, self.P = ekf_predict(self.x, self.P, lambda s: self.f(s, u), F, self.Q)
        self.x = self.normalize(x)

    def update(self, z) -> tuple[np.ndarray, np.ndarray]:
        """Returns the innovation and its covariance (nu, S)."""
        x, self.P, nu, S = ekf_update(self.x, self.P, np.asarray(z, float), self.h(self.x),
                                      self.H_jac(self.x), self.R, self.residual)
        self.x = self.normalize(x)
        return nu, S


@dataclass(frozen=True)
class EKFLocalizationConfig:
    #: probability mass inside the association gate for unknown correspondences
    gate_probability: float = 0.99
    #: also reject known-id measurements whose NIS exceeds the gate (outlier rejection)
    gate_known: bool = False
    #: True: one update per measurement, each relinearised at the previous posterior (Table
    #: 7.2's loop). False: the known-id measurements of one event are stacked into a single
    #: update (one linearisation; identical for linear models, ~10x cheaper in Python).
    sequential_updates: bool = False


class EKFLocalization(GaussianLocalization):
    """EKF localization (registry name ``ekf``) on a known landmark map."""

    name = "ekf"

    def __init__(self, world_p_landmarks: Mapping[int, np.ndarray], noise: NoiseParams = NoiseParams(),
                 config: EKFLocalizationConfig = EKFLocalizationConfig()) -> None:
        super().__init__(world_p_landmarks, noise, config)

    def _predict(self, odometry: Odometry) -> None:
        u = np.array([odometry.v_mps, odometry.omega_radps])
        F, L = diff_drive.motion_jacobians(self.x[:3], u, odometry.dt_s)
        F, Q = self._embed_motion(F, L @ self.noise.control_cov @ L.T)
        x, self.P = ekf_predict(self.x, self.P, lambda s: np.concatenate(
            [np.asarray(diff_drive.motion(s[:3], u, odometry.dt_s), dtype=float).reshape(3), s[3:]]), F, Q)
        self.x = np.asarray(x, dtype=float)

    def _update(self, observation: RangeBearing) -> None:
        ids, zs = observation_rows(observation)
        if not self.config.sequential_updates and not self.config.gate_known:
            known = np.array([int(i) in self._index for i in ids], dtype=bool)
            if known.any():
                self._stacked_update(ids[known], zs[known])
            self._rejected += int(np.sum((ids >= 0) & ~known))
            ids, zs = ids[ids < 0], zs[ids < 0]
        self._sequential_update(ids, zs)

    def _stacked_update(self, ids: np.ndarray, zs: np.ndarray) -> None:
        m = len(ids)
        lm = self.landmarks[[self._index[int(i)] for i in ids]]
        pose = np.broadcast_to(self.x[:3], (m, 3))
        z_hat = range_bearing.observe(pose, lm)
        H_pose, _ = range_bearing.observe_jacobians(pose, lm)
        H = self._pad(H_pose.reshape(2 * m, 3))
        R = np.kron(np.eye(m), self.noise.range_bearing_cov)
        nu = range_bearing_residual(zs, z_hat).reshape(2 * m)
        x, self.P, nu, S = ekf_update(self.x, self.P, nu, np.zeros(2 * m), H, R)
        # one NIS per measurement from the diagonal 2 x 2 blocks of S (each chi-square with 2 dof)
        k = np.arange(m)
        self._record_nis(nu.reshape(m, 2), S.reshape(m, 2, m, 2)[k, :, k, :])
        self.x = np.asarray(x, dtype=float)
        self.x[2] = wrap_angle(self.x[2])

    def _sequential_update(self, ids: np.ndarray, zs: np.ndarray) -> None:
        R = self.noise.range_bearing_cov
        # Sequential updates: each measurement is linearised at the estimate the previous ones
        # produced, which is exact for independent measurement noise and more accurate than one
        # stacked linearisation.
        for lid, z in zip(ids, zs):
            if lid >= 0:
                k = self._index.get(int(lid))
                if k is None:
                    self._rejected += 1
                    continue
                candidates = np.array([k])
            else:
                candidates = np.arange(len(self.landmarks))
            pose = np.broadcast_to(self.x[:3], (len(candidates), 3))
            z_hat = range_bearing.observe(pose, self.landmarks[candidates])
            H_all = self._pad(range_bearing.observe_jacobians(pose, self.landmarks[candidates])[0])
            nu_all = range_bearing_residual(np.broadcast_to(z, z_hat.shape), z_hat)
            S_all = H_all @ self.P @ H_all.transpose(0, 2, 1) + R
            d2 = np.einsum("ni,ni->n", nu_all, np.linalg.solve(S_all, nu_all[..., None])[..., 0])
            if lid < 0:
                # maximum likelihood: smallest d^2 + log|S| (negative log-likelihood up to a constant)
                best = int(np.argmin(d2 + np.log(np.linalg.det(S_all))))
            else:
                best = 0
            if (lid < 0 or self.config.gate_known) and d2[best] > self._gate:
                self._rejected += 1
                continue
            H = H_all[best]
            x, self.P, nu, S = ekf_update(self.x, self.P, z, z_hat[best], H, R, range_bearing_residual)
            self._record_nis(nu, S)
            self.x = np.asarray(x, dtype=float)
            self.x[2] = wrap_angle(self.x[2])

    def _update_range(self, event: Range) -> None:
        # one scalar update per range, each linearised at the previous posterior; with the
        # range scale in the state, r = s |m - p| and dr/ds = |m - p|
        R = np.array([[self.noise.sigma_range_m**2]])
        for k, r in self._known_ranges(event):
            scale = self._scale()
            Jp, _, distance = range_only.observe_scaled_jacobians(self.x[:2], self.landmarks[k], scale)
            H = np.zeros((1, len(self.x)))
            H[0, :2] = Jp
            if self._scale_index is not None:
                H[0, self._scale_index] = distance
            x, self.P, nu, S = ekf_update(self.x, self.P, np.array([r]), np.array([scale * distance]), H, R)
            self._record_nis(nu, S)
            self.x = np.asarray(x, dtype=float)
            self.x[2] = wrap_angle(self.x[2])

    def _update_gps(self, gps: Gps) -> None:
        H = self._pad(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
        R = np.eye(2) * gps.sigma_m**2
        z = np.asarray(gps.world_p_body, dtype=float).reshape(-1)[:2]
        x, self.P, nu, S = ekf_update(self.x, self.P, z, self.x[:2], H, R)
        self._record_nis(nu, S)
        self.x = x
