"""What every planar filter shares: the bookkeeping that turns a stream of ``step`` calls into an
:class:`~slamkit.data.estimate.Estimate`, and small numeric helpers (circular weighted
statistics, Gaussian log-densities, chi-square gates). The noise the filters assume is
:class:`slamkit.data.noise.NoiseParams` (one reader of a Sequence's noise metadata for filters
and smoothers alike), re-exported here for the filter modules.

The filters themselves live one per module (``kalman``, ``ekf``, ``ukf``, ``histogram_filter``,
``particle_filter``, ``mcl``, ``ekf_slam``, ``fastslam``).
"""

from __future__ import annotations

import time
from typing import Any, Mapping

import numpy as np
from scipy.stats import chi2

from slamkit.data.estimate import Estimate, Prior
from slamkit.data.noise import NoiseParams  # noqa: F401  (the filters import it from here)
from slamkit.data.sequence import Event, Gps, Imu, Odometry, Range, RangeBearing, Scan, WheelEncoders, check_event
from slamkit.data.trajectory import Trajectory
from slamkit.errors import EstimationError
from slamkit.geometry.angles import wrap_angle


def landmark_array(world_p_landmarks: Mapping[int, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray]:
    """Map ``{id: (x, y)}`` -> (ids (L,), positions (L, 2)), sorted by id."""
    if not world_p_landmarks:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 2))
    ids = np.array(sorted(int(k) for k in world_p_landmarks), dtype=np.int64)
    pos = np.array([np.asarray(world_p_landmarks[int(i)], dtype=float).reshape(-1)[:2] for i in ids])
    return ids, pos.reshape(-1, 2)


def observation_rows(event: RangeBearing) -> tuple[np.ndarray, np.ndarray]:
    """(ids (m,), z (m, 2)) from a RangeBearing event."""
    ids = np.asarray(event.landmark_ids, dtype=np.int64).reshape(-1)
    z = np.column_stack([np.asarray(event.range_m, dtype=float).reshape(-1),
                         np.asarray(event.bearing_rad, dtype=float).reshape(-1)])
    if len(ids) != len(z):
        raise EstimationError(
            f"RangeBearing at t={event.stamp_s}: {len(ids)} landmark_ids but {len(z)} ranges")
    return ids, z


def range_rows(event: Range) -> tuple[np.ndarray, np.ndarray]:
    """(ids (m,), ranges (m,)) from a Range event."""
    ids = np.asarray(event.landmark_ids, dtype=np.int64).reshape(-1)
    r = np.asarray(event.range_m, dtype=float).reshape(-1)
    if len(ids) != len(r):
        raise EstimationError(f"Range at t={event.stamp_s}: {len(ids)} landmark_ids but {len(r)} ranges")
    return ids, r


def range_bearing_residual(z: np.ndarray, z_hat: np.ndarray) -> np.ndarray:
    """z - z_hat with the bearing (last axis, index 1) wrapped to [-pi, pi)."""
    nu = np.asarray(z, dtype=float) - np.asarray(z_hat, dtype=float)
    nu[..., 1] = wrap_angle(nu[..., 1])
    return nu


def chi2_gate(probability: float, dof: int) -> float:
    """Squared Mahalanobis distance below which ``probability`` of true associations fall."""
    return float(chi2.ppf(probability, dof))


# --------------------------------------------------------------------------------------------
# weighted statistics with angles
# --------------------------------------------------------------------------------------------
def weighted_pose_mean_cov(poses: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of weighted planar poses (N, 3); the heading mean is the circular
    mean atan2(sum w sin, sum w cos) and heading residuals are wrapped before squaring."""
    w = np.asarray(weights, dtype=float)
    w = w / np.sum(w)
    mean = np.empty(3)
    mean[:2] = w @ poses[:, :2]
    mean[2] = np.arctan2(w @ np.sin(poses[:, 2]), w @ np.cos(poses[:, 2]))
    d = poses - mean
    d[:, 2] = wrap_angle(d[:, 2])
    cov = (d * w[:, None]).T @ d
    return mean, 0.5 * (cov + cov.T)


def gaussian_logpdf_2d(nu: np.ndarray, cov_inv: np.ndarray, log_det: float | np.ndarray) -> np.ndarray:
    """log N(nu; 0, S) for residuals (..., 2) given S^-1 (..., 2, 2) and log|S|."""
    maha = np.einsum("...i,...ij,...j->...", nu, cov_inv, nu)
    return -0.5 * maha - 0.5 * log_det - np.log(2.0 * np.pi)


def symmetrize(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + np.swapaxes(P, -1, -2))


# --------------------------------------------------------------------------------------------
# bookkeeping shared by every filter
# --------------------------------------------------------------------------------------------
def nis_values(nu: np.ndarray, S: np.ndarray) -> np.ndarray:
    """nu^T S^-1 nu for one innovation (d,) with S (d, d), or a stack (n, d) with (n, d, d)."""
    nu = np.asarray(nu, dtype=float)
    S = np.asarray(S, dtype=float)
    if nu.ndim == 1:
        nu, S = nu[None], S[None]
    return np.einsum("ni,ni->n", nu, np.linalg.solve(S, nu[..., None])[..., 0])


class FilterBase:
    """Implements the Estimator protocol's plumbing; subclasses implement the maths.

    Subclasses override ``_reset(prior)``, ``_predict(odometry)``, ``_update(range_bearing)``
    (and optionally ``_update_gps``) and ``_pose_and_covariance()``. One trajectory row is kept
    per distinct event stamp (the posterior after the last event at that stamp), so the
    trajectory lines up with the ground truth's stamps.
    """

    name: str = "filter"

    def __init__(self) -> None:
        self._ready = False

    # -- protocol ------------------------------------------------------------------------
    def reset(self, prior: Prior) -> None:
        mean = np.asarray(prior.world_xytheta_body, dtype=float).reshape(3)
        cov = np.asarray(prior.covariance, dtype=float).reshape(3, 3)  # checked by Prior itself
        self._stamps: list[float] = []
        self._poses: list[np.ndarray] = []
        self._covs: list[np.ndarray] = []
        self._nis: list[float] = []
        self._nis_dof: list[int] = []
        self._latency: list[float] = []
        self._ignored = 0
        self._pending: float | None = None
        self._reset(Prior(mean, cov))
        self._ready = True

    def step(self, event: Event) -> None:
        if not self._ready:
            raise EstimationError(f"{self.name}: step() called before reset(prior)")
        t0 = time.perf_counter()
        stamp = float(event.stamp_s)
        # The trajectory row of a stamp is the posterior after the *last* event at that stamp,
        # so it is summarised lazily when the next stamp begins (or in estimate()): a predict
        # followed by an update at the same stamp costs one summary, not two. A late event
        # (stamp before the pending one; only filters with a late-event rule accept it) refreshes
        # the newest row instead of appending one out of order.
        if self._pending is not None and stamp > self._pending:
            self._finalize()
        check_event(event, self.name)
        self._dispatch(event)
        self._pending = stamp if self._pending is None else max(stamp, self._pending)
        self._latency.append(time.perf_counter() - t0)

    def _dispatch(self, event: Event) -> None:
        """Hand ``event`` to its hook by type (an event type without a hook counts as ignored)."""
        if isinstance(event, Odometry):
            self._predict(event)
        elif isinstance(event, RangeBearing):
            self._update(event)
        elif isinstance(event, Range):
            self._update_range(event)
        elif isinstance(event, Gps):
            self._update_gps(event)
        elif isinstance(event, Imu):
            self._imu(event)
        elif isinstance(event, WheelEncoders):
            self._encoders(event)
        elif isinstance(event, Scan):
            self._scan(event)
        else:
            self._ignored += 1

    def _finalize(self) -> None:
        mean, cov = self._pose_and_covariance()
        if self._stamps and self._stamps[-1] == self._pending:
            self._poses[-1], self._covs[-1] = mean, cov
        else:
            self._stamps.append(self._pending)
            self._poses.append(mean)
            self._covs.append(cov)
        self._pending = None

    def estimate(self) -> Estimate:
        if not self._ready:
            raise EstimationError(f"{self.name}: estimate() called before reset(prior)")
        if self._pending is not None:
            self._finalize()
        poses = np.array(self._poses).reshape(-1, 3)
        lm, lm_cov = self._landmarks()
        return Estimate(
            trajectory=Trajectory.from_se2(np.array(self._stamps), poses),
            pose_covariances=np.array(self._covs).reshape(-1, 3, 3),
            world_p_landmarks=lm,
            landmark_covariances=lm_cov,
            nis=np.array(self._nis, dtype=float),
            nis_dof=np.array(self._nis_dof, dtype=np.int64),
            step_latency_s=np.array(self._latency),
            extras={"ignored_events": self._ignored, **self._extras()},
        )

    def latest_estimate(self) -> Estimate:
        """The newest pose, its covariance and the landmarks only (what an observer draws at a
        snapshot), without rebuilding the trajectory."""
        if not self._ready:
            raise EstimationError(f"{self.name}: latest_estimate() called before reset(prior)")
        mean, cov = self._pose_and_covariance()
        stamp = self._pending if self._pending is not None else (self._stamps[-1] if self._stamps else 0.0)
        lm, lm_cov = self._landmarks()
        return Estimate(trajectory=Trajectory.from_se2(np.array([stamp]), np.asarray(mean).reshape(1, 3)),
                        pose_covariances=np.asarray(cov).reshape(1, 3, 3), world_p_landmarks=lm,
                        landmark_covariances=lm_cov)

    # -- hooks -----------------------------------------------------------------------------
    def _reset(self, prior: Prior) -> None:
        raise NotImplementedError

    def _predict(self, odometry: Odometry) -> None:
        raise NotImplementedError

    def _update(self, observation: RangeBearing) -> None:
        raise NotImplementedError

    def _update_gps(self, gps: Gps) -> None:
        # Filters that cannot use GPS count it as ignored rather than failing the run.
        self._ignored += 1

    def _update_range(self, ranges: Range) -> None:
        # filters without a range-only update count the event as ignored
        self._ignored += 1

    def _imu(self, imu: Imu) -> None:
        self._ignored += 1

    def _encoders(self, encoders: WheelEncoders) -> None:
        self._ignored += 1

    def _scan(self, scan: Scan) -> None:
        self._ignored += 1

    def _pose_and_covariance(self) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _landmarks(self) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
        return {}, {}

    def _extras(self) -> dict[str, Any]:
        return {}

    def _record_nis(self, nu: np.ndarray, S: np.ndarray) -> None:
        """Record nu^T S^-1 nu for one (or a stack of) innovation(s) of dimension d."""
        nu = np.asarray(nu, dtype=float)
        self._record_nis_values(nis_values(nu, S), dof=nu.shape[-1])

    def _record_nis_values(self, values: np.ndarray, dof: int) -> None:
        """Record NIS values already computed (e.g. by a fused kernel) of innovations of ``dof``."""
        self._nis.extend(np.asarray(values, dtype=float).ravel().tolist())
        self._nis_dof.extend([dof] * np.size(values))
