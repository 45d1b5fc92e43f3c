"""What every estimator returns, and the protocols filters and smoothers satisfy."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Protocol, runtime_checkable

import numpy as np

from slamkit.data.sequence import Event, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import EstimationError


@dataclass(frozen=True)
class Estimate:
    """An estimator's answer.

    ``trajectory`` holds the estimate at the sequence's pose stamps; ``pose_covariances``
    (N, 3, 3) or (N, 6, 6) in the pose's tangent order (x, y, theta for SE(2)) when the
    estimator provides them; ``world_p_landmarks`` and ``landmark_covariances`` keyed by
    landmark id; ``innovations`` holds (nu, S) pairs for NIS where a filter records them;
    ``step_latency_s`` the wall time of every ``step`` call.
    """

    trajectory: Trajectory
    pose_covariances: np.ndarray | None = None
    world_p_landmarks: Mapping[int, np.ndarray] = field(default_factory=dict)
    landmark_covariances: Mapping[int, np.ndarray] = field(default_factory=dict)
    nis: np.ndarray | None = None
    nis_dof: np.ndarray | None = None
    step_latency_s: np.ndarray | None = None
    extras: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Prior:
    """Initial belief: planar pose (x, y, theta) and its covariance, checked once here for
    every estimator: finite, and the covariance symmetric positive semidefinite (a zero
    covariance -- a start pose known exactly -- is a common SLAM convention; the GTSAM smoothers
    additionally need it positive definite and say so)."""

    world_xytheta_body: np.ndarray
    covariance: np.ndarray

    def __post_init__(self) -> None:
        mean = np.asarray(self.world_xytheta_body, dtype=float).reshape(-1)
        cov = np.asarray(self.covariance, dtype=float)
        if mean.shape != (3,) or cov.shape != (3, 3):
            raise EstimationError(f"Prior needs world_xytheta_body (3,) and covariance (3, 3), got {mean.shape} "
                                  f"and {cov.shape}")
        if not (np.isfinite(mean).all() and np.isfinite(cov).all()):
            raise EstimationError("prior contains NaN or infinite values")
        check_covariance(cov, "prior covariance", semidefinite=True)


def check_covariance(cov: np.ndarray, what: str, tol: float = 1e-9, semidefinite: bool = False) -> None:
    """An EstimationError naming ``what`` unless ``cov`` is symmetric positive definite
    (``semidefinite``: eigenvalues >= -tol * scale allowed down to zero)."""
    P = np.asarray(cov, dtype=float)
    if P.ndim != 2 or P.shape[0] != P.shape[1] or not np.isfinite(P).all():
        raise EstimationError(f"{what} must be a finite square matrix, got shape {P.shape}")
    if np.abs(P - P.T).max(initial=0.0) > tol * max(1.0, np.abs(P).max(initial=0.0)):
        raise EstimationError(f"{what} is not symmetric: {P.tolist()}")
    if semidefinite:
        w = np.linalg.eigvalsh(0.5 * (P + P.T))
        if w.min(initial=0.0) < -tol * max(1.0, np.abs(P).max(initial=0.0)):
            raise EstimationError(f"{what} is not positive semidefinite (eigenvalues {np.round(w, 12).tolist()})")
        return
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        raise EstimationError(f"{what} is not positive definite (eigenvalues "
                              f"{np.round(np.linalg.eigvalsh(P), 12).tolist()})") from None


@runtime_checkable
class Estimator(Protocol):
    """Online estimators (filters, iSAM2, fixed-lag smoothers)."""

    name: str

    def reset(self, prior: Prior) -> None: ...

    def step(self, event: Event) -> None: ...

    def estimate(self) -> Estimate: ...


@runtime_checkable
class LatestBelief(Protocol):
    """An online estimator whose ``estimate()`` grows with the run (high-rate inertial and fusion
    estimators) offers its newest pose alone, at constant cost: an Estimate whose trajectory is
    that one pose (with its covariance and any landmarks). Observers' snapshots use it instead of
    rebuilding the whole trajectory every few events."""

    def latest_estimate(self) -> Estimate: ...


@runtime_checkable
class ParticleBelief(Protocol):
    """An estimator whose belief is a particle set exposes it as (N, >= 3) poses (viewers draw it)."""

    particles: np.ndarray


@runtime_checkable
class BatchEstimator(Protocol):
    name: str

    def solve(self, sequence: Sequence) -> Estimate: ...
