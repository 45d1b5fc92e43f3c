"""Planar landmark SLAM as a factor graph: batch Levenberg-Marquardt, iSAM2 and fixed-lag smoothing.

The graph (Dellaert & Kaess, "Factor Graphs for Robot Perception", FnT Robotics 6(1-2) 2017,
sec. 1.3 and 5): a pose variable X(k) per Odometry event (the first, X(0), carries the prior), a
``BetweenFactorPose2`` per Odometry event and a ``BearingRangeFactor2D`` per range-bearing
observation of landmark L(j).

* Odometry -> between factor through the velocity motion model (Thrun, Burgard & Fox,
  Probabilistic Robotics, sec. 5.3): the measured relative pose is the exact arc
  ``slamkit.models.diff_drive.motion(0, u, dt)``; its covariance is the control noise pushed
  through the model, L M L^T (L = df/du at the origin, M = diag(sigma_v^2, sigma_omega^2)),
  re-expressed in the Pose2 tangent at the measurement (rotate the translation block by R_z^T).
  L M L^T has rank 2 (two controls drive three pose coordinates), so a small floor
  ``odometry_floor_sigma`` is added in quadrature to make the factor's information finite.
* RangeBearing -> ``BearingRangeFactor2D(X(k), L(j), bearing, range)`` with noise
  (sigma_bearing, sigma_range); a landmark is initialised from its first sighting,
  m = x + r (cos(theta + b), sin(theta + b)) with the current estimate of the pose. Observations
  with unknown correspondence (id -1) are skipped and counted: these smoothers need data
  association done upstream.
* An observation attaches to the most recent pose (the simulators emit the Odometry that ends at
  a stamp before the RangeBearing taken there).
* Range (range-only beacons) -> ``RangeFactor2D(X(k), L(j), range)`` after the beacon's delayed
  initialisation; when the sequence declares the ranges' scale unknown
  (``NoiseParams.range_scale_sigma`` > 0) a variable s (``RANGE_SCALE_KEY``, prior N(1, sigma^2))
  joins the graph and each range is :func:`scaled_range_factor`, r = s |m - p| (a
  ``gtsam.CustomFactor`` with analytic Jacobians: a Python call per evaluation; the batch solve
  then runs GTSAM's LM driven from Python, :mod:`slamkit.backend.levenberg_marquardt`, which
  explains why).

Estimators (``slamkit.data.estimate`` protocols, registry names ``batch``, ``isam2``,
``fixed_lag``):

* :class:`BatchLandmarkSLAM` keeps the whole graph and solves it with LM on ``estimate()`` /
  ``solve(sequence)``; marginals from ``gtsam.Marginals``.
* :class:`Isam2LandmarkSLAM` calls ``ISAM2.update`` once per event that adds factors (Kaess et al.,
  "iSAM2", IJRR 2012); ``estimate()`` returns the smoothed trajectory and
  ``extras['online_xytheta']`` the estimate each pose had when it was newest.
* :class:`FixedLagLandmarkSLAM` keeps only the last ``lag_s`` seconds of variables
  (``gtsam.IncrementalFixedLagSmoother`` or ``BatchFixedLagSmoother``); older variables are
  marginalised out and their last estimate (and covariance) before leaving is what it reports.
  A landmark is kept alive while it is being observed; one seen again after it was marginalised
  is re-initialised as a new variable (``keep_landmarks``: landmarks never leave, only poses
  do). The range scale s, when estimated, never leaves the window.

Pose covariances are reported, like the filters', in world-frame (x, y, theta): GTSAM's Pose2
marginals live in the body-frame tangent and are rotated by the heading (first order).

Configuration (issue 18: one config per smoother, where one class used to carry all three):
:class:`LandmarkSmootherConfig` holds what they share (noise, odometry floor, covariances);
:class:`BatchLandmarkSLAMConfig` adds the LM settings, :class:`Isam2LandmarkSLAMConfig` the
iSAM2 ones and :class:`FixedLagLandmarkSLAMConfig` the lag on top of iSAM2's (its incremental
kind runs iSAM2 inside). The pipeline's options for ``batch``, ``isam2`` and ``fixed_lag`` are
validated against these classes, so an LM option given to ``isam2`` is an unknown key. The noise
is :class:`slamkit.data.noise.NoiseParams`, the same reader of the sequence's metadata the
filters use.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from slamkit.data.estimate import Estimate, Prior
from slamkit.data.noise import NoiseParams, prior_of
from slamkit.data.sequence import Event, Odometry, Range, RangeBearing, Sequence, check_event
from slamkit.data.trajectory import Trajectory
from slamkit.geometry import se2
from slamkit.backend.graph import smoother_config
from slamkit.backend.levenberg_marquardt import levenberg_marquardt
from slamkit.errors import ConfigError, EstimationError
from slamkit.models import diff_drive, range_only
from slamkit.models.range_only import BeaconInitialiser, DelayedInitConfig


# ---- configuration ------------------------------------------------------------------------------

@dataclass(frozen=True)
class LandmarkSmootherConfig:
    """What every landmark smoother takes. ``noise`` None means "read it from the sequence
    metadata" (``solve``) or the defaults (``reset``). ``odometry_floor_sigma`` (m, m, rad) is
    added in quadrature to every odometry factor (see module docstring)."""

    noise: NoiseParams | None = None
    odometry_floor_sigma: tuple[float, float, float] = (1e-3, 1e-3, 1e-4)
    compute_covariances: bool = True
    #: range-only beacons: when one enters the graph (the filters' delayed-initialisation rule)
    range_init: DelayedInitConfig = DelayedInitConfig()

    def __post_init__(self) -> None:
        if len(self.odometry_floor_sigma) != 3 or min(self.odometry_floor_sigma) <= 0:
            raise ConfigError(f"odometry_floor_sigma must be 3 positive sigmas, got "
                              f"{self.odometry_floor_sigma}")


@dataclass(frozen=True)
class BatchLandmarkSLAMConfig(LandmarkSmootherConfig):
    """``batch``: Levenberg-Marquardt over the whole graph; tolerances are GTSAM's defaults."""

    max_iterations: int = 100
    relative_error_tol: float = 1e-5
    absolute_error_tol: float = 1e-5
    #: LM gives up when its damping reaches this; GTSAM's 1e5 default stops early here
    lambda_upper_bound: float = 1e10

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.max_iterations < 1:
            raise ConfigError(f"max_iterations must be >= 1, got {self.max_iterations}")


@dataclass(frozen=True)
class Isam2LandmarkSLAMConfig(LandmarkSmootherConfig):
    """``isam2``: ISAM2's fluid relinearisation (Kaess et al. 2012): a variable is relinearised
    when its update exceeds ``relinearize_threshold``, checked every ``relinearize_skip``
    updates."""

    relinearize_threshold: float = 0.01
    relinearize_skip: int = 1
    #: ISAM2.update once every this many events (their factors collected in between, new poses
    #: predicted by odometry from the last estimate), as Kaess's range-only Plaza examples
    #: update after every 25 ranges: on range-only graphs, where every beacon ties into every
    #: pose, each update re-solves from the root clique down
    update_every: int = 1

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.relinearize_skip < 1:
            raise ConfigError(f"relinearize_skip must be >= 1, got {self.relinearize_skip}")
        if self.update_every < 1:
            raise ConfigError(f"update_every must be >= 1, got {self.update_every}")


@dataclass(frozen=True)
class FixedLagLandmarkSLAMConfig(Isam2LandmarkSLAMConfig):
    """``fixed_lag``: keeps the last ``lag_s`` seconds. The ``incremental`` kind runs iSAM2
    inside (so it takes iSAM2's settings, inherited); ``batch`` re-solves the window with LM and
    exposes no marginals."""

    lag_s: float = 5.0
    fixed_lag_kind: str = "incremental"  # 'incremental' | 'batch'
    #: True: landmarks never leave the window (only poses are marginalised), so a landmark
    #: unobserved for ``lag_s`` is not re-initialised as a new variable when seen again (Plaza 1's
    #: 4 beacons took 57 variables with a 5 s lag)
    keep_landmarks: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (np.isfinite(self.lag_s) and self.lag_s > 0):
            raise ConfigError(f"lag_s must be positive, got {self.lag_s}")
        if self.fixed_lag_kind not in ("incremental", "batch"):
            raise ConfigError(f"fixed_lag_kind must be 'incremental' or 'batch', got "
                              f"{self.fixed_lag_kind!r}")


def _isam2_params(config: Isam2LandmarkSLAMConfig) -> gtsam.ISAM2Params:
    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(config.relinearize_threshold)
    params.relinearizeSkip = config.relinearize_skip
    return params


# ---- factor helpers -----------------------------------------------------------------------------

def odometry_factor_terms(odometry: Odometry, noise: NoiseParams,
                          floor_sigma: tuple[float, float, float]) -> tuple[gtsam.Pose2, np.ndarray]:
    """Relative pose and its covariance (Pose2 tangent at the measurement) for one Odometry."""
    u = np.array([odometry.v_mps, odometry.omega_radps])
    delta = diff_drive.motion(np.zeros(3), u, odometry.dt_s)
    _, Lu = diff_drive.motion_jacobians(np.zeros(3), u, odometry.dt_s)
    cov = Lu @ np.diag([noise.sigma_v_mps**2, noise.sigma_omega_radps**2]) @ Lu.T
    # Z Exp(xi) ~ (t_z + R_z xi_t, th_z + xi_th): the tangent error is R_z^T times the coordinate
    # error in the previous pose's frame
    c, s = np.cos(delta[2]), np.sin(delta[2])
    A = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    cov = A @ cov @ A.T + np.diag(np.square(floor_sigma))
    return gtsam.Pose2(*delta), 0.5 * (cov + cov.T)


#: the range-scale variable (a 1-vector s, ranges = s * true range) when the sequence declares
#: the ranges' scale unknown (``NoiseParams.range_scale_sigma`` > 0)
RANGE_SCALE_KEY = gtsam.symbol("s", 0)


def scaled_range_factor(pose_key: int, landmark_key: int, scale_key: int, range_m: float,
                        model: gtsam.noiseModel.Base) -> gtsam.CustomFactor:
    """The range factor with an unknown scale: error ``s |m - p| - r`` on (Pose2 X, Point2 L,
    Vector1 s), with the analytic Jacobians of
    :func:`slamkit.models.range_only.observe_scaled_jacobians`; a Pose2 retracts its
    translation in the body frame, so d/dxi = (dr/dp R(theta), 0)."""

    def error(this, values, jacobians):
        pose = values.atPose2(pose_key)
        m = values.atPoint2(landmark_key)
        scale = float(values.atVector(scale_key)[0])
        p = np.array([pose.x(), pose.y()])
        Jp, Jm, distance = range_only.observe_scaled_jacobians(p, m, scale)
        if jacobians is not None:
            c, sn = np.cos(pose.theta()), np.sin(pose.theta())
            jacobians[0] = np.array([[Jp[0] * c + Jp[1] * sn, -Jp[0] * sn + Jp[1] * c, 0.0]])
            jacobians[1] = Jm.reshape(1, 2)
            jacobians[2] = np.array([[distance]])
        return np.array([scale * distance - range_m])

    return gtsam.CustomFactor(model, [pose_key, landmark_key, scale_key], error)


def _world_cov_rotation(theta: float) -> np.ndarray:
    """A with X Exp(xi) ~ (t + R xi_t, theta + xi_theta): world-frame error = A xi (first order)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _world_cov(world_xytheta_body: np.ndarray, cov_body: np.ndarray) -> np.ndarray:
    return se2.covariance_body_to_world(world_xytheta_body, cov_body)


def _xytheta(pose: gtsam.Pose2) -> np.ndarray:
    return np.array([pose.x(), pose.y(), pose.theta()])


# ---- shared bookkeeping -------------------------------------------------------------------------

class _LandmarkSmootherBase:
    """Turns events into factors and new variables; subclasses decide when to optimise."""

    name = "landmark_smoother"
    #: the config dataclass this smoother takes (its fields are the registry params)
    config_class: type[LandmarkSmootherConfig] = LandmarkSmootherConfig

    def __init__(self, config: LandmarkSmootherConfig | None = None) -> None:
        config = smoother_config(self.name, self.config_class, config)
        self.config = config
        self._ready = False
        #: the noise a batch solve() takes from the sequence's metadata when the config has none
        self._sequence_noise: NoiseParams | None = None

    # -- protocol ------------------------------------------------------------------------------
    def reset(self, prior: Prior) -> None:
        mean = np.asarray(prior.world_xytheta_body, dtype=float).reshape(3)
        cov = np.asarray(prior.covariance, dtype=float).reshape(3, 3)
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(cov))):
            raise EstimationError(f"{self.name}: prior contains NaN or infinite values")
        if np.any(np.linalg.eigvalsh(0.5 * (cov + cov.T)) <= 0):
            raise EstimationError(f"{self.name}: prior covariance must be positive definite")
        self.noise = self.config.noise or self._sequence_noise or NoiseParams()
        self._bearing_range_model = gtsam.noiseModel.Diagonal.Sigmas(
            np.array([self.noise.sigma_bearing_rad, self.noise.sigma_range_m]))
        self._range_model = gtsam.noiseModel.Isotropic.Sigma(1, self.noise.sigma_range_m)
        self._beacons = BeaconInitialiser(self.config.range_init, self.noise.sigma_range_m)
        self._stamps: list[float | None] = [None]      # X(0)'s stamp is set by the first event
        self._landmark_key: dict[int, int] = {}
        self._landmark_ids_of_key: dict[int, int] = {}
        self._next_landmark_index = 0
        self._latency: list[float] = []
        self._counts = {"odometry": 0, "observations": 0, "unassociated": 0, "ignored_events": 0,
                        "zero_dt_odometry": 0, "ranges": 0, "rejected_ranges": 0}
        self._latest_pose = gtsam.Pose2(*mean)
        self._scale_key = RANGE_SCALE_KEY if self.noise.range_scale_sigma > 0 else None
        factors = gtsam.NonlinearFactorGraph()
        # the Prior's covariance is world-frame (x, y, theta) like the filters'; GTSAM's Pose2
        # prior lives in the body-frame tangent: Sigma_body = A^T Sigma_world A
        A = _world_cov_rotation(mean[2])
        factors.add(gtsam.PriorFactorPose2(X(0), self._latest_pose,
                                           gtsam.noiseModel.Gaussian.Covariance(A.T @ cov @ A)))
        values = gtsam.Values()
        values.insert(X(0), self._latest_pose)
        stamps = {X(0): None}
        if self._scale_key is not None:
            # the unknown range scale s: a weak prior around 1, estimated with everything else
            factors.add(gtsam.PriorFactorVector(self._scale_key, np.ones(1), gtsam.noiseModel.Isotropic.Sigma(
                1, self.noise.range_scale_sigma)))
            values.insert(self._scale_key, np.ones(1))
            stamps[self._scale_key] = None
        self._reset_solver()
        self._pending = (factors, values, stamps)
        self._events_pending = 0
        self._ready = True

    def step(self, event: Event) -> None:
        if not self._ready:
            raise EstimationError(f"{self.name}: step() called before reset(prior)")
        check_event(event, self.name)
        t0 = time.perf_counter()
        stamp = float(event.stamp_s)
        # self._pending stays the object being filled until processed, so _current_pose sees
        # variables created earlier in this same step
        factors, values, stamps = self._pending
        if self._stamps[0] is None:
            self._stamps[0] = stamp - event.dt_s if isinstance(event, Odometry) else stamp
            for key in [k for k, t in stamps.items() if t is None]:
                stamps[key] = self._stamps[0]
        if isinstance(event, Odometry):
            self._add_odometry(event, factors, values, stamps)
        elif isinstance(event, RangeBearing):
            self._add_observations(event, factors, values, stamps)
        elif isinstance(event, Range):
            self._add_ranges(event, factors, values, stamps)
        else:
            self._counts["ignored_events"] += 1
        self._events_pending += 1
        if (factors.size() or values.size()) and self._events_pending >= self._update_every:
            self._process(factors, values, stamps, stamp)
            self._pending = (gtsam.NonlinearFactorGraph(), gtsam.Values(), {})
            self._events_pending = 0
        self._latency.append(time.perf_counter() - t0)

    def estimate(self) -> Estimate:
        if not self._ready:
            raise EstimationError(f"{self.name}: estimate() called before reset(prior)")
        poses, covs, landmarks, landmark_covs, extras = self._collect()
        stamps = np.array([s if s is not None else 0.0 for s in self._stamps])
        return Estimate(
            trajectory=Trajectory.from_se2(stamps, poses),
            pose_covariances=covs,
            world_p_landmarks=landmarks,
            landmark_covariances=landmark_covs,
            step_latency_s=np.array(self._latency),
            extras={**self._counts, "num_poses": len(self._stamps),
                    "num_landmarks": len(landmarks),
                    "landmark_variables": self._next_landmark_index, **extras},
        )

    def latest_estimate(self) -> Estimate:
        """The newest pose and the landmarks' current estimates, without covariances or the
        trajectory (:class:`~slamkit.data.estimate.LatestBelief`: what an observer draws every
        few events; ``estimate()`` recovers every pose and marginal, O(n) per call)."""
        if not self._ready:
            raise EstimationError(f"{self.name}: latest_estimate() called before reset(prior)")
        k = len(self._stamps) - 1
        pose = _xytheta(self._current_pose(k))
        stamp = self._stamps[k] if self._stamps[k] is not None else 0.0
        landmarks = {}
        for lid, key in self._landmark_key.items():
            if self._pending[1].exists(key) or self._alive(key):   # not marginalised out
                landmarks[lid] = np.asarray(self._current_point(key), dtype=float).reshape(2)
        return Estimate(trajectory=Trajectory.from_se2(np.array([stamp]), pose.reshape(1, 3)),
                        world_p_landmarks=landmarks)

    # -- event -> factors ------------------------------------------------------------------------
    def _add_odometry(self, event: Odometry, factors, values, stamps) -> None:
        if not (np.isfinite(event.dt_s) and event.dt_s >= 0):
            raise EstimationError(f"{self.name}: Odometry at t={event.stamp_s} has dt_s={event.dt_s}")
        if event.dt_s == 0:
            self._counts["zero_dt_odometry"] += 1
            return
        k = len(self._stamps)
        z, cov = odometry_factor_terms(event, self.noise, self.config.odometry_floor_sigma)
        factors.add(gtsam.BetweenFactorPose2(X(k - 1), X(k), z,
                                             gtsam.noiseModel.Gaussian.Covariance(cov)))
        self._latest_pose = self._current_pose(k - 1).compose(z)
        values.insert(X(k), self._latest_pose)
        self._stamps.append(float(event.stamp_s))
        stamps[X(k)] = float(event.stamp_s)
        self._counts["odometry"] += 1

    def _add_observations(self, event: RangeBearing, factors, values, stamps) -> None:
        ids = np.asarray(event.landmark_ids, dtype=np.int64).reshape(-1)
        ranges = np.asarray(event.range_m, dtype=float).reshape(-1)
        bearings = np.asarray(event.bearing_rad, dtype=float).reshape(-1)
        if not (len(ids) == len(ranges) == len(bearings)):
            raise EstimationError(f"{self.name}: RangeBearing at t={event.stamp_s} has "
                                  f"{len(ids)} ids, {len(ranges)} ranges, {len(bearings)} bearings")
        k = len(self._stamps) - 1
        pose = self._current_pose(k)
        for lid, r, b in zip(ids.tolist(), ranges.tolist(), bearings.tolist()):
            if lid < 0:
                self._counts["unassociated"] += 1
                continue
            key = self._landmark_key.get(lid)
            if key is None or not self._alive(key):
                key = L(self._next_landmark_index)
                self._next_landmark_index += 1
                self._landmark_key[lid] = key
                self._landmark_ids_of_key[key] = lid
                values.insert(key, pose.transformFrom(gtsam.Point2(r * np.cos(b), r * np.sin(b))))
            stamps[key] = float(event.stamp_s)
            factors.add(gtsam.BearingRangeFactor2D(X(k), key, gtsam.Rot2.fromAngle(b), r,
                                                   self._bearing_range_model))
            self._counts["observations"] += 1

    def _add_ranges(self, event: Range, factors, values, stamps) -> None:
        """Range-only beacons (known ids; the filters' rules): a beacon not yet in the graph
        buffers its ranges in :class:`BeaconInitialiser` with the pose index they attach to; once
        trilaterated it enters as L(j) at the chosen candidate with a ``RangeFactor2D`` for every
        buffered range whose pose is still a variable (a fixed-lag smoother may have marginalised
        the oldest: those ranges enter as a prior with the trilateration's covariance). Later ranges pass the range gate
        against the current pose and beacon estimates (:meth:`_gate_ranges_online`; the batch
        solver gates against its own solution instead) before their factor is added."""
        ids = np.asarray(event.landmark_ids, dtype=np.int64).reshape(-1)
        ranges = np.asarray(event.range_m, dtype=float).reshape(-1)
        k = len(self._stamps) - 1
        pose = self._current_pose(k)
        xy = np.array([pose.x(), pose.y()])
        scale = self._current_scale()
        for lid, r in zip(ids.tolist(), ranges.tolist()):
            if lid < 0:
                self._counts["unassociated"] += 1
                continue
            key = self._landmark_key.get(lid)
            if key is None or not self._alive(key):
                # trilaterated from the ranges divided by the scale estimate of their time; the
                # factors take the ranges as measured (the tag keeps them)
                fix = self._beacons.add(lid, xy, r / scale, tag=(k, r))
                if fix is None:
                    continue
                key = L(self._next_landmark_index)
                self._next_landmark_index += 1
                self._landmark_key[lid] = key
                self._landmark_ids_of_key[key] = lid
                values.insert(key, gtsam.Point2(*fix.trilateration.world_p_landmark))
                stamps[key] = float(event.stamp_s)
                dropped = 0
                for tag, rr in fix.tags:
                    if tag == k or self._alive(X(tag)):
                        factors.add(self._range_factor(X(tag), key, rr))
                        self._counts["ranges"] += 1
                    else:
                        dropped += 1
                if dropped:
                    # ranges from poses a fixed-lag smoother has already marginalised: what they
                    # said about the beacon enters as the trilateration's covariance instead
                    factors.add(gtsam.PriorFactorPoint2(key, gtsam.Point2(*fix.trilateration.world_p_landmark),
                                                        gtsam.noiseModel.Gaussian.Covariance(fix.covariance)))
                continue
            if self._gate_ranges_online and self.noise.range_rejected(
                    r - scale * range_only.observe(xy, np.asarray(self._current_point(key), dtype=float))):
                self._counts["rejected_ranges"] += 1
                continue
            stamps[key] = float(event.stamp_s)
            factors.add(self._range_factor(X(k), key, r))
            self._counts["ranges"] += 1

    def _range_factor(self, pose_key: int, landmark_key: int, range_m: float) -> gtsam.NoiseModelFactor:
        """``RangeFactor2D``, or :func:`scaled_range_factor` when the range scale is estimated."""
        if self._scale_key is None:
            return gtsam.RangeFactor2D(pose_key, landmark_key, range_m, self._range_model)
        return scaled_range_factor(pose_key, landmark_key, self._scale_key, range_m, self._range_model)

    def _current_scale(self) -> float:
        """The newest estimate of the range scale (1 when it is not estimated)."""
        if self._scale_key is None:
            return 1.0
        if self._pending[1].exists(self._scale_key):
            return float(self._pending[1].atVector(self._scale_key)[0])
        return float(self._solver_scale(self._scale_key))

    def _solver_scale(self, key: int) -> float:
        raise NotImplementedError

    def _scale_extras(self, estimate: gtsam.Values) -> dict:
        """``{'range_scale': s}`` at ``estimate`` when the range scale is estimated."""
        if self._scale_key is None or not estimate.exists(self._scale_key):
            return {}
        return {"range_scale": float(estimate.atVector(self._scale_key)[0])}

    #: online smoothers gate a range against their current estimate when it arrives
    _gate_ranges_online = True
    #: events whose factors are collected before the solver is updated (1: every event)
    _update_every = 1

    def _current_point(self, key: int):
        """The newest estimate of landmark ``key`` (its initial value while it is pending)."""
        if self._pending[1].exists(key):
            return self._pending[1].atPoint2(key)
        return self._solver_point(key)

    def _solver_point(self, key: int):
        raise NotImplementedError

    # -- subclass hooks ----------------------------------------------------------------------------
    def _reset_solver(self) -> None:
        raise NotImplementedError

    def _process(self, factors, values, stamps, stamp) -> None:
        raise NotImplementedError

    def _current_pose(self, k: int) -> gtsam.Pose2:
        raise NotImplementedError

    def _alive(self, key: int) -> bool:
        return True

    def _collect(self):
        raise NotImplementedError

    def _landmark_output(self, estimate: gtsam.Values, cov_of) -> tuple[dict, dict]:
        landmarks, covs = {}, {}
        for lid, key in self._landmark_key.items():
            if estimate.exists(key):
                landmarks[lid] = np.asarray(estimate.atPoint2(key), dtype=float).reshape(2)
                if cov_of is not None:
                    covs[lid] = cov_of(key)
        return landmarks, covs


# ---- batch ----------------------------------------------------------------------------------------

class BatchLandmarkSLAM(_LandmarkSmootherBase):
    """Full-batch smoother (registry name ``batch``): every factor kept, LM over all of them."""

    name = "batch"
    config_class = BatchLandmarkSLAMConfig
    config: BatchLandmarkSLAMConfig

    def solve(self, sequence: Sequence) -> Estimate:
        """reset from the sequence's start pose and metadata noise, feed every event, solve.

        The prior is the declared start pose (the origin if none) with ``initial_pose_sigma``
        as given: :func:`slamkit.data.noise.prior_of` without the runner's ground-truth start
        and sigma floor (see there why)."""
        noise = self.config.noise or NoiseParams.from_metadata(sequence.metadata)
        self._sequence_noise = noise
        try:
            self.reset(prior_of(sequence, noise, sigma_floor=0.0, start_from_ground_truth=False))
        finally:
            self._sequence_noise = None
        for event in sequence:
            self.step(event)
        return self.estimate()

    def _reset_solver(self) -> None:
        self._graph = gtsam.NonlinearFactorGraph()
        self._initial = gtsam.Values()
        self._solution: gtsam.Values | None = None
        self._result_info: dict[str, Any] = {}

    def _process(self, factors, values, stamps, stamp) -> None:
        self._graph.push_back(factors)
        self._initial.insert(values)
        self._solution = None

    def _current_pose(self, k: int) -> gtsam.Pose2:
        # dead reckoning / first sighting: the batch solve starts from the chained odometry
        if self._pending[1].exists(X(k)):
            return self._pending[1].atPose2(X(k))
        return self._initial.atPose2(X(k))

    # the chained odometry drifts: a range is gated against the batch solution instead
    _gate_ranges_online = False

    def _solver_point(self, key: int):
        return self._initial.atPoint2(key)

    def _solver_scale(self, key: int) -> float:
        return self._initial.atVector(key)[0]

    def _optimize(self, graph: gtsam.NonlinearFactorGraph, initial: gtsam.Values
                  ) -> tuple[gtsam.Values, int]:
        if self._scale_key is not None:
            # the scaled range factors are Python CustomFactors: GTSAM's C++ LM would hand each
            # callback a copy of all the values (~50 s on Plaza 2); the same LM driven from
            # Python passes them by reference (slamkit.backend.levenberg_marquardt)
            result = levenberg_marquardt(graph, initial, max_iterations=self.config.max_iterations,
                                         relative_error_tol=self.config.relative_error_tol,
                                         absolute_error_tol=self.config.absolute_error_tol,
                                         lambda_upper_bound=self.config.lambda_upper_bound)
            return result.values, result.iterations
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(self.config.max_iterations)
        params.setRelativeErrorTol(self.config.relative_error_tol)
        params.setAbsoluteErrorTol(self.config.absolute_error_tol)
        # GTSAM's default lambda ceiling (1e5) makes LM give up early from a drifted
        # dead-reckoning start (measured: error 17672 after 3 iterations vs 3822 after 16)
        params.setlambdaUpperBound(self.config.lambda_upper_bound)
        optimizer = gtsam.LevenbergMarquardtOptimizer(graph, initial, params)
        return gtsam.Values(optimizer.optimize()), optimizer.iterations()

    def _gate_ranges(self, solution: gtsam.Values) -> int:
        """Drop the range factors whose residual at ``solution`` lies outside the range gate
        (the online estimators' rule, applied to the batch solution); returns how many."""
        kept, dropped = gtsam.NonlinearFactorGraph(), 0
        for i in range(self._graph.size()):
            f = self._graph.at(i)
            # the range factors: RangeFactor2D, or the scaled CustomFactor (the only custom one)
            if (isinstance(f, (gtsam.RangeFactor2D, gtsam.CustomFactor))
                    and self.noise.range_rejected(f.unwhitenedError(solution)[0])):
                dropped += 1
                continue
            kept.add(f)
        if dropped:
            self._graph = kept
        return dropped

    def _solve(self) -> gtsam.Values:
        if self._solution is None:
            factors, values, _ = self._pending
            if factors.size():
                self._process(factors, values, {}, None)
                self._pending = (gtsam.NonlinearFactorGraph(), gtsam.Values(), {})
            t0 = time.perf_counter()
            self._solution, iterations = self._optimize(self._graph, self._initial)
            if np.isfinite(self.noise.range_gate_m):
                dropped = self._gate_ranges(self._solution)
                if dropped:
                    self._counts["rejected_ranges"] += dropped
                    self._counts["ranges"] -= dropped
                    self._solution, more = self._optimize(self._graph, self._solution)
                    iterations += more
            self._result_info = {"solve_s": time.perf_counter() - t0,
                                 "iterations": iterations,
                                 "initial_error": self._graph.error(self._initial),
                                 "final_error": self._graph.error(self._solution)}
        return self._solution

    def _collect(self):
        solution = self._solve()
        n = len(self._stamps)
        poses = np.array([_xytheta(solution.atPose2(X(k))) for k in range(n)])
        covs, cov_of = None, None
        info = dict(self._result_info)
        if self.config.compute_covariances:
            try:
                marginals = gtsam.Marginals(self._graph, solution)
                covs = np.stack([_world_cov(poses[k], marginals.marginalCovariance(X(k)))
                                 for k in range(n)])
                cov_of = marginals.marginalCovariance
            except RuntimeError as exc:
                # the LM solve is damped, the marginals' Cholesky is not: very confident
                # odometry (lateral sigma at the floor) can leave the information too poorly
                # conditioned to factor; report the estimate without covariances
                covs, cov_of = None, None
                info["warnings"] = [f"marginal covariances unavailable: "
                                    f"{str(exc).strip().splitlines()[0]}"]
        landmarks, landmark_covs = self._landmark_output(solution, cov_of)
        return poses, covs, landmarks, landmark_covs, {**info, **self._scale_extras(solution)}


# ---- iSAM2 ---------------------------------------------------------------------------------------

class Isam2LandmarkSLAM(_LandmarkSmootherBase):
    """Incremental smoother (registry name ``isam2``): one ISAM2.update per event."""

    name = "isam2"
    config_class = Isam2LandmarkSLAMConfig
    config: Isam2LandmarkSLAMConfig

    def _reset_solver(self) -> None:
        self._isam = gtsam.ISAM2(_isam2_params(self.config))
        self._online: list[np.ndarray] = []
        self._update_every = self.config.update_every

    def _process(self, factors, values, stamps, stamp) -> None:
        # the poses added since the last update were newest with their odometry prediction
        k = len(self._stamps) - 1
        for j in range(len(self._online), k):
            self._online.append(_xytheta(values.atPose2(X(j))))
        self._isam.update(factors, values)
        self._latest_pose = self._isam.calculateEstimatePose2(X(k))
        online = _xytheta(self._latest_pose)
        if len(self._online) == k + 1:
            self._online[k] = online
        else:
            self._online.append(online)

    def _current_pose(self, k: int) -> gtsam.Pose2:
        if self._pending[1].exists(X(k)):
            return self._pending[1].atPose2(X(k))
        if k == len(self._stamps) - 1:
            return self._latest_pose
        return self._isam.calculateEstimatePose2(X(k))

    def _solver_point(self, key: int):
        return self._isam.calculateEstimatePoint2(key)

    def _solver_scale(self, key: int) -> float:
        return self._isam.calculateEstimateVector(key)[0]

    def _collect(self):
        factors, values, stamps = self._pending
        if factors.size():
            self._process(factors, values, stamps, None)
            self._pending = (gtsam.NonlinearFactorGraph(), gtsam.Values(), {})
        estimate = self._isam.calculateEstimate()
        n = len(self._stamps)
        poses = np.array([_xytheta(estimate.atPose2(X(k))) for k in range(n)])
        covs, cov_of = None, None
        if self.config.compute_covariances:
            covs = np.stack([_world_cov(poses[k], self._isam.marginalCovariance(X(k)))
                             for k in range(n)])
            cov_of = self._isam.marginalCovariance
        landmarks, landmark_covs = self._landmark_output(estimate, cov_of)
        return poses, covs, landmarks, landmark_covs, {"online_xytheta": np.array(self._online),
                                                       **self._scale_extras(estimate)}


# ---- fixed lag -----------------------------------------------------------------------------------

class FixedLagLandmarkSLAM(_LandmarkSmootherBase):
    """Fixed-lag smoother (registry name ``fixed_lag``) over the last ``config.lag_s`` seconds."""

    name = "fixed_lag"
    config_class = FixedLagLandmarkSLAMConfig
    config: FixedLagLandmarkSLAMConfig

    def _reset_solver(self) -> None:
        lag = float(self.config.lag_s)
        if self.config.fixed_lag_kind == "incremental":
            self._smoother = gtsam.IncrementalFixedLagSmoother(lag, _isam2_params(self.config))
        else:
            self._smoother = gtsam.BatchFixedLagSmoother(lag)
        self._key_stamp: dict[int, float] = {}
        self._frozen: dict[int, tuple[np.ndarray, np.ndarray | None]] = {}

    def _alive(self, key: int) -> bool:
        return key in self._key_stamp

    def _snapshot(self, key: int, estimate: gtsam.Values) -> tuple[np.ndarray, np.ndarray | None]:
        if key in self._landmark_ids_of_key:
            value = np.asarray(estimate.atPoint2(key), dtype=float).reshape(2)
        else:
            value = _xytheta(estimate.atPose2(key))
        cov = None
        if self.config.compute_covariances and self.config.fixed_lag_kind == "incremental":
            cov = self._smoother.marginalCovariance(key)
        return value, cov

    def _process(self, factors, values, stamps, stamp) -> None:
        start = self._stamps[0] if self._stamps[0] is not None else 0.0
        stamps = {k: (start if t is None else t) for k, t in stamps.items()}
        if self._scale_key is not None:
            # the range scale concerns every range: it never leaves the window
            stamps[self._scale_key] = max([*stamps.values(), *self._key_stamp.values()])
        if self.config.keep_landmarks:
            # the map stays in the window (a sliding window over poses only)
            newest = max([*stamps.values(), *self._key_stamp.values()])
            stamps.update({key: newest for key in self._landmark_ids_of_key
                           if key in self._key_stamp or key in stamps})
        self._key_stamp.update(stamps)
        newest = max(self._key_stamp.values())
        leaving = [k for k, t in self._key_stamp.items() if t < newest - self.config.lag_s]
        if leaving and self._has_run:
            # remember what the smoother believes about them just before they are marginalised
            estimate = self._smoother.calculateEstimate()
            for key in leaving:
                if estimate.exists(key):
                    self._frozen[key] = self._snapshot(key, estimate)
        self._smoother.update(factors, values, stamps)
        self._has_run = True
        for key in leaving:
            del self._key_stamp[key]
        k = len(self._stamps) - 1
        if X(k) in self._key_stamp:
            self._latest_pose = self._smoother.calculateEstimatePose2(X(k))

    _has_run = False

    def _current_pose(self, k: int) -> gtsam.Pose2:
        if self._pending[1].exists(X(k)):
            return self._pending[1].atPose2(X(k))
        if k == len(self._stamps) - 1:
            return self._latest_pose
        return self._smoother.calculateEstimatePose2(X(k))

    def _solver_point(self, key: int):
        return self._smoother.calculateEstimatePoint2(key)

    def _solver_scale(self, key: int) -> float:
        return self._smoother.calculateEstimateVector(key)[0]

    def _collect(self):
        factors, values, stamps = self._pending
        if factors.size():
            self._process(factors, values, stamps, None)
            self._pending = (gtsam.NonlinearFactorGraph(), gtsam.Values(), {})
        estimate = self._smoother.calculateEstimate()
        n = len(self._stamps)
        poses = np.empty((n, 3))
        covs = np.full((n, 3, 3), np.nan) if self.config.compute_covariances else None
        for k in range(n):
            key = X(k)
            value, cov = (self._snapshot(key, estimate) if estimate.exists(key)
                          else self._frozen[key])
            poses[k] = value
            if covs is not None and cov is not None:
                covs[k] = _world_cov(value, cov)
        if covs is not None and np.isnan(covs).any():
            covs = None  # the batch fixed-lag smoother exposes no marginals
        landmarks, landmark_covs = {}, {}
        for key, lid in self._landmark_ids_of_key.items():
            if estimate.exists(key):
                value, cov = self._snapshot(key, estimate)
            elif key in self._frozen:
                value, cov = self._frozen[key]
            else:
                continue
            # a landmark re-initialised after marginalisation: report its newest variable
            if self._landmark_key.get(lid) == key or lid not in landmarks:
                landmarks[lid] = value
                if cov is not None:
                    landmark_covs[lid] = cov
        return poses, covs, landmarks, landmark_covs, {"lag_s": self.config.lag_s, **self._scale_extras(estimate)}
