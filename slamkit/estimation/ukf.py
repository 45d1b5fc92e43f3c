"""Unscented Kalman filter with angle-aware sigma-point statistics, and UKF localization.

Julier & Uhlmann (1997), "A New Extension of the Kalman Filter to Nonlinear Systems"; the scaled
sigma points of van der Merwe & Wan (2001), "The square-root unscented Kalman filter":

    lambda = alpha^2 (n + kappa) - n
    X_0 = mu,  X_{i} = mu + [sqrt((n + lambda) P)]_i,  X_{n+i} = mu - [sqrt((n + lambda) P)]_i
    Wm_0 = lambda / (n + lambda),  Wc_0 = Wm_0 + (1 - alpha^2 + beta),  W_i = 1 / (2 (n + lambda))

Angles: a weighted arithmetic mean of headings near +-pi is wrong (the pitfall discussed in
filterpy issue #197), so every component flagged as an angle takes the circular mean
atan2(sum Wm sin, sum Wm cos), and every residual of such a component is wrapped to [-pi, pi)
before it enters a covariance or the innovation.

UKF localization (Thrun et al., *Probabilistic Robotics*, Table 7.4) augments the state with the
(v, omega) control noise for the prediction, so the exact-arc motion model is never linearised,
and updates on all range-bearing measurements of one event jointly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy.linalg import block_diag, cholesky

from slamkit.data.sequence import Gps, Odometry, Range, RangeBearing
from slamkit.errors import ConfigError, EstimationError
from slamkit.estimation._gaussian_localization import GaussianLocalization
from slamkit.estimation._common import (
    NoiseParams,
    observation_rows,
)
from slamkit.geometry.angles import wrap_angle
from slamkit.models import diff_drive, range_bearing, range_only


@dataclass(frozen=True)
class SigmaPointParams:
    """Scaled unscented transform parameters. The defaults (alpha = 1, beta = 2, kappa = 0) keep
    every weight non-negative, so the propagated covariance stays positive semi-definite."""

    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0

    def weights(self, n: int) -> tuple[np.ndarray, np.ndarray, float]:
        """(Wm (2n+1,), Wc (2n+1,), n + lambda)."""
        lam = self.alpha**2 * (n + self.kappa) - n
        c = n + lam
        if c <= 0:
            raise ConfigError(f"sigma-point scaling n + lambda = {c} must be positive "
                              f"(alpha={self.alpha}, kappa={self.kappa}, n={n})")
        Wm = np.full(2 * n + 1, 0.5 / c)
        Wc = Wm.copy()
        Wm[0] = lam / c
        Wc[0] = lam / c + (1.0 - self.alpha**2 + self.beta)
        return Wm, Wc, c


def sigma_points(x: np.ndarray, P: np.ndarray, params: SigmaPointParams = SigmaPointParams(),
                 angle_mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(X (2n+1, n), Wm, Wc); angle components of the points are wrapped."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    Wm, Wc, c = params.weights(n)
    try:
        S = cholesky(c * 0.5 * (P + P.T), lower=True)
    except np.linalg.LinAlgError as exc:
        raise EstimationError(f"UKF covariance is not positive definite: {exc}") from exc
    X = np.concatenate([x[None], x + S.T, x - S.T])
    if angle_mask is not None and np.any(angle_mask):
        X[:, angle_mask] = wrap_angle(X[:, angle_mask])
    return X, Wm, Wc


def weighted_mean(Y: np.ndarray, Wm: np.ndarray, angle_mask: np.ndarray | None = None) -> np.ndarray:
    """Weighted mean of sigma points (K, d); circular mean on angle components."""
    mean = Wm @ Y
    if angle_mask is not None and np.any(angle_mask):
        mean[angle_mask] = np.arctan2(Wm @ np.sin(Y[:, angle_mask]), Wm @ np.cos(Y[:, angle_mask]))
    return mean


def residuals(Y: np.ndarray, mean: np.ndarray, angle_mask: np.ndarray | None = None) -> np.ndarray:
    d = Y - mean
    if angle_mask is not None and np.any(angle_mask):
        d[..., angle_mask] = wrap_angle(d[..., angle_mask])
    return d


def unscented_transform(Y: np.ndarray, Wm: np.ndarray, Wc: np.ndarray,
                        angle_mask: np.ndarray | None = None, noise_cov: np.ndarray | None = None,
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of transformed sigma points (plus additive ``noise_cov``)."""
    mean = weighted_mean(Y, Wm, angle_mask)
    d = residuals(Y, mean, angle_mask)
    cov = (d * Wc[:, None]).T @ d
    if noise_cov is not None:
        cov = cov + noise_cov
    return mean, 0.5 * (cov + cov.T)


def ukf_update(x: np.ndarray, P: np.ndarray, X: np.ndarray, Wm: np.ndarray, Wc: np.ndarray,
               Z: np.ndarray, z: np.ndarray, R: np.ndarray, x_angle_mask=None, z_angle_mask=None,
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Measurement update from sigma points X (K, n) and their predicted measurements Z (K, m).
    Returns (x+, P+, nu, S)."""
    z_mean, S = unscented_transform(Z, Wm, Wc, z_angle_mask, R)
    dx = residuals(X, x, x_angle_mask)
    dz = residuals(Z, z_mean, z_angle_mask)
    Pxz = (dx * Wc[:, None]).T @ dz
    K = np.linalg.solve(S.T, Pxz.T).T
    nu = residuals(np.asarray(z, dtype=float), z_mean, z_angle_mask)
    x_new = x + K @ nu
    if x_angle_mask is not None and np.any(x_angle_mask):
        x_new[x_angle_mask] = wrap_angle(x_new[x_angle_mask])
    P_new = P - K @ S @ K.T
    return x_new, 0.5 * (P_new + P_new.T), nu, S


@dataclass(frozen=True)
class UKFLocalizationConfig:
    sigma_points: SigmaPointParams = SigmaPointParams()
    #: probability mass inside the association gate for unknown correspondences
    gate_probability: float = 0.99


class UKFLocalization(GaussianLocalization):
    """UKF localization (registry name ``ukf``) on a known landmark map."""

    name = "ukf"

    def __init__(self, world_p_landmarks: Mapping[int, np.ndarray], noise: NoiseParams = NoiseParams(),
                 config: UKFLocalizationConfig = UKFLocalizationConfig()) -> None:
        super().__init__(world_p_landmarks, noise, config)

    def _predict(self, odometry: Odometry) -> None:
        u = np.array([odometry.v_mps, odometry.omega_radps])
        n = len(self.x)
        xa = np.concatenate([self.x, np.zeros(2)])
        Pa = block_diag(self.P, self.noise.control_cov)
        X, Wm, Wc = sigma_points(xa, Pa, self.config.sigma_points, np.concatenate([self._angles, [False, False]]))
        Y = X[:, :n].copy()                       # the range scale (if in the state) is unchanged
        Y[:, :3] = diff_drive.motion(X[:, :3], u + X[:, n:], odometry.dt_s)
        self.x, self.P = unscented_transform(Y, Wm, Wc, self._angles)

    def _associate(self, X: np.ndarray, Wm, Wc, z: np.ndarray) -> int | None:
        """Maximum-likelihood landmark for one unknown-id measurement, or None outside the gate."""
        K, L = len(X), len(self.landmarks)
        Z = range_bearing.observe(np.broadcast_to(X[:, None, :3], (K, L, 3)),
                                  np.broadcast_to(self.landmarks[None], (K, L, 2)))  # (K, L, 2)
        z_mean = np.empty((L, 2))
        z_mean[:, 0] = Wm @ Z[..., 0]
        z_mean[:, 1] = np.arctan2(Wm @ np.sin(Z[..., 1]), Wm @ np.cos(Z[..., 1]))
        d = Z - z_mean
        d[..., 1] = wrap_angle(d[..., 1])
        S = np.einsum("k,kli,klj->lij", Wc, d, d) + self.noise.range_bearing_cov
        nu = z - z_mean
        nu[:, 1] = wrap_angle(nu[:, 1])
        d2 = np.einsum("li,li->l", nu, np.linalg.solve(S, nu[..., None])[..., 0])
        best = int(np.argmin(d2 + np.log(np.linalg.det(S))))
        return best if d2[best] <= self._gate else None

    def _update(self, observation: RangeBearing) -> None:
        ids, zs = observation_rows(observation)
        X, Wm, Wc = sigma_points(self.x, self.P, self.config.sigma_points, self._angles)
        rows, lm_index = [], []
        for row, lid in enumerate(ids):
            k = self._index.get(int(lid)) if lid >= 0 else self._associate(X, Wm, Wc, zs[row])
            if k is None:
                self._rejected += 1
                continue
            rows.append(row)
            lm_index.append(k)
        if not rows:
            return
        m = len(rows)
        lm = self.landmarks[np.array(lm_index)]
        Z = range_bearing.observe(np.broadcast_to(X[:, None, :3], (len(X), m, 3)),
                                  np.broadcast_to(lm[None], (len(X), m, 2))).reshape(len(X), 2 * m)
        z = zs[np.array(rows)].reshape(2 * m)
        z_mask = np.tile([False, True], m)
        R = np.kron(np.eye(m), self.noise.range_bearing_cov)
        self.x, self.P, nu, S = ukf_update(self.x, self.P, X, Wm, Wc, np.asarray(Z, float), z, R,
                                           self._angles, z_mask)
        # one NIS per measurement (dof 2) from the diagonal blocks of the joint S, as the EKF
        # records it, so NIS statistics compare across filters
        k = np.arange(m)
        self._record_nis(nu.reshape(m, 2), S.reshape(m, 2, m, 2)[k, :, k, :])

    def _update_range(self, event: Range) -> None:
        # the gated ranges of one event in one update through the same sigma points
        rows = self._known_ranges(event)
        if not rows:
            return
        lm = self.landmarks[[k for k, _ in rows]]
        X, Wm, Wc = sigma_points(self.x, self.P, self.config.sigma_points, self._angles)
        Z = range_only.observe(X[:, None, :2], lm[None])                      # (K, m)
        if self._scale_index is not None:
            Z = X[:, self._scale_index, None] * Z                             # r = s |m - p|
        R = np.eye(len(rows)) * self.noise.sigma_range_m**2
        self.x, self.P, nu, S = ukf_update(self.x, self.P, X, Wm, Wc, Z, np.array([r for _, r in rows]), R,
                                           self._angles, None)
        self._record_nis(nu[:, None], np.diagonal(S)[:, None, None])

    def _update_gps(self, gps: Gps) -> None:
        X, Wm, Wc = sigma_points(self.x, self.P, self.config.sigma_points, self._angles)
        z = np.asarray(gps.world_p_body, dtype=float).reshape(-1)[:2]
        self.x, self.P, nu, S = ukf_update(self.x, self.P, X, Wm, Wc, X[:, :2], z,
                                           np.eye(2) * gps.sigma_m**2, self._angles, None)
        self._record_nis(nu, S)
