"""Linear Kalman filter, with the Joseph-form update and the steady-state gain.

Kalman (1960), "A New Approach to Linear Filtering and Prediction Problems"; notation of Thrun,
Burgard & Fox, *Probabilistic Robotics*, Table 3.1:

    predict   mu- = A mu + B u,              Sigma- = A Sigma A^T + Q
    update    S = H Sigma- H^T + R,          K = Sigma- H^T S^-1
              mu = mu- + K (z - H mu-),
              Sigma = (I - K H) Sigma- (I - K H)^T + K R K^T      (Joseph form)

The Joseph form (Bucy & Joseph 1968) is used because it stays symmetric positive definite for any
gain, including the steady-state gain, where the short form ``(I - K H) Sigma`` does not.

Steady state: for a time-invariant (A, H, Q, R) the predicted covariance converges to the
stabilising solution P of the discrete algebraic Riccati equation

    P = A P A^T - A P H^T (H P H^T + R)^-1 H P A^T + Q,

solved here with ``scipy.linalg.solve_discrete_are(A^T, H^T, Q, R)`` (the filtering DARE is the
dual of the control DARE), and ``K_inf = P H^T (H P H^T + R)^-1``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

from slamkit.data.estimate import check_covariance
from slamkit.errors import EstimationError


def _as2d(a) -> np.ndarray:
    return np.atleast_2d(np.asarray(a, dtype=float))


def kf_predict(mu: np.ndarray, Sigma: np.ndarray, A, Q, B=None, u=None) -> tuple[np.ndarray, np.ndarray]:
    """Prediction step; returns (mu-, Sigma-)."""
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    A, Q, Sigma = _as2d(A), _as2d(Q), _as2d(Sigma)
    mu_pred = A @ mu
    if B is not None and u is not None:
        mu_pred = mu_pred + _as2d(B) @ np.atleast_1d(np.asarray(u, dtype=float))
    return mu_pred, A @ Sigma @ A.T + Q


@dataclass(frozen=True)
class KalmanUpdate:
    """Result of one measurement update (innovation ``nu`` and its covariance ``S`` for NIS)."""

    mean: np.ndarray
    covariance: np.ndarray
    gain: np.ndarray
    innovation: np.ndarray
    innovation_cov: np.ndarray

    @property
    def nis(self) -> float:
        return float(self.innovation @ np.linalg.solve(self.innovation_cov, self.innovation))


def kf_update(mu: np.ndarray, Sigma: np.ndarray, z, H, R, gain: np.ndarray | None = None) -> KalmanUpdate:
    """Measurement update in Joseph form; ``gain`` overrides the optimal gain (steady state)."""
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    Sigma, H, R = _as2d(Sigma), _as2d(H), _as2d(R)
    z = np.atleast_1d(np.asarray(z, dtype=float))
    nu = z - H @ mu
    S = H @ Sigma @ H.T + R
    K = np.linalg.solve(S.T, (Sigma @ H.T).T).T if gain is None else _as2d(gain)
    I_KH = np.eye(len(mu)) - K @ H
    P = I_KH @ Sigma @ I_KH.T + K @ R @ K.T
    return KalmanUpdate(mu + K @ nu, 0.5 * (P + P.T), K, nu, S)


def steady_state_gain(A, H, Q, R) -> tuple[np.ndarray, np.ndarray]:
    """(K_inf, P_pred_inf): the steady-state Kalman gain and predicted covariance from the DARE.

    Raises EstimationError when no stabilising solution exists (for example (A, H) not
    detectable)."""
    A, H, Q, R = _as2d(A), _as2d(H), _as2d(Q), _as2d(R)
    try:
        P = solve_discrete_are(A.T, H.T, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise EstimationError(f"no stabilising DARE solution for this (A, H, Q, R): {exc}") from exc
    S = H @ P @ H.T + R
    K = np.linalg.solve(S.T, (P @ H.T).T).T
    return K, 0.5 * (P + P.T)


class KalmanFilter:
    """A time-invariant linear Kalman filter holding its own (mean, covariance).

    ``steady_state=True`` uses the constant DARE gain for every update (cheap, and optimal once
    the transient has died out); the covariance is still propagated in Joseph form so it remains
    the true covariance of the estimate under that gain.
    """

    def __init__(self, A, H, Q, R, B=None, steady_state: bool = False) -> None:
        self.A, self.H, self.Q, self.R = _as2d(A), _as2d(H), _as2d(Q), _as2d(R)
        self.B = None if B is None else _as2d(B)
        n = self.A.shape[0]
        if self.A.shape != (n, n) or self.Q.shape != (n, n) or self.H.shape[1] != n:
            raise EstimationError(
                f"inconsistent KF shapes: A {self.A.shape}, Q {self.Q.shape}, H {self.H.shape}")
        if self.R.shape != (self.H.shape[0],) * 2:
            raise EstimationError(f"R has shape {self.R.shape}, expected {(self.H.shape[0],) * 2}")
        check_covariance(self.R, "KF measurement noise R")
        check_covariance(self.Q, "KF process noise Q", semidefinite=True)
        self.gain_inf = steady_state_gain(self.A, self.H, self.Q, self.R)[0] if steady_state else None
        self.mean = np.zeros(n)
        self.covariance = np.eye(n)

    def reset(self, mean, covariance) -> None:
        self.mean = np.atleast_1d(np.asarray(mean, dtype=float)).copy()
        self.covariance = _as2d(covariance).copy()

    def predict(self, u=None) -> None:
        self.mean, self.covariance = kf_predict(self.mean, self.covariance, self.A, self.Q, self.B, u)

    def update(self, z) -> KalmanUpdate:
        result = kf_update(self.mean, self.covariance, z, self.H, self.R, gain=self.gain_inf)
        self.mean, self.covariance = result.mean, result.covariance
        return result
