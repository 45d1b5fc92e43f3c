"""GPS-aided inertial smoothing with preintegrated IMU factors: iSAM2 and a fixed-lag smoother.

IMU readings between two states are summarised by ``gtsam.PreintegratedCombinedMeasurements``
(Forster, Carlone, Dellaert, Scaramuzza, "On-Manifold Preintegration for Real-Time
Visual-Inertial Odometry", T-RO 33(1), 2017; the combined factor with bias evolution of Carlone
et al., "Eliminating conditionally independent sets in factor graphs", RSS 2014 workshop / GTSAM's
``CombinedImuFactor``), each state k is (X(k): Pose3, V(k): velocity, B(k): ConstantBias), and
each GPS fix adds a ``GPSFactor`` (world position of the body origin, isotropic sigma). The noise is
the sequence's :class:`~slamkit.data.inertial.InertialSetup` -- the numbers the error-state EKF
(:mod:`slamkit.estimation.eskf`) uses: continuous-time accelerometer and gyro densities squared
as GTSAM's accelerometer / gyroscope covariances, the bias random-walk densities squared as its
bias covariances, gravity (0, 0, -g) with z up (``MakeSharedU``), and the start state and its
15 sigmas as priors on X(0), V(0), B(0).

States are created at every GPS fix and, between fixes (GPS outages), every ``state_period_s``
seconds of IMU data, so the trajectory keeps a pose per period when no fix arrives. The IMU
convention is :mod:`slamkit.data.inertial`'s: a reading holds over the interval that ends at its
stamp; a fix stamped after the last reading extends that reading up to the fix (the same rule as
the filter). Every new state is one solver update (Kaess et al., iSAM2, IJRR 2012; the fixed-lag
smoother is ``gtsam.IncrementalFixedLagSmoother``, which marginalises states older than
``lag_s``); the preintegration then restarts at the newest bias estimate.

Conventions at the boundary: GTSAM's Pose3 tangent is (rotation, translation) in the body frame;
slamkit reports pose covariances as (position, attitude) in the world frame (the runner's
:func:`~slamkit.experiments.runner.world_pose_error`), so marginals are mapped with
A = [[0, R], [R, 0]]: Sigma_world = A Sigma_body A^T (first order, Pose3 retract t + R v).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import gtsam
import numpy as np
from gtsam.symbol_shorthand import B, V, X

from slamkit.data.estimate import Estimate, Prior
from slamkit.data.inertial import InertialEventLoop, InertialSetup, setup_of
from slamkit.data.sequence import Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.backend.graph import smoother_config
from slamkit.errors import ConfigError, EstimationError
from slamkit.geometry import so3
from slamkit.models.imu import ImuNoise

__all__ = ["InertialSmootherConfig", "FixedLagInertialConfig", "Isam2Inertial", "FixedLagInertial",
           "preintegration_params", "preintegrate"]


@dataclass(frozen=True)
class InertialSmootherConfig:
    """``isam2_imu``: ``imu_noise`` (ImuNoise fields) and ``gps_sigma_m`` override the sequence's
    (None: the sequence's, as the filter). ``integration_sigma`` is GTSAM's integration
    covariance (position from velocity, m/sqrt(s)), a regulariser the filter does not have: at
    1e-4 iSAM2's Cholesky reported an indeterminate system on states 0.1-0.3 s apart (consumer
    IMU, car3d); 1e-3 adds 1e-6 m^2 of position variance per second, far below the GPS's."""

    imu_noise: Mapping[str, float] | None = None
    gps_sigma_m: float | None = None
    state_period_s: float = 1.0
    integration_sigma: float = 1e-3
    relinearize_threshold: float = 0.01
    relinearize_skip: int = 1
    #: iSAM2's factorisation: 'cholesky' (GTSAM's default) or 'qr' (slower, survives worse conditioning)
    factorization: str = "cholesky"
    compute_covariances: bool = True

    def __post_init__(self) -> None:
        if self.factorization not in ("cholesky", "qr"):
            raise ConfigError(f"factorization must be 'cholesky' or 'qr', got {self.factorization!r}")
        if not (np.isfinite(self.state_period_s) and self.state_period_s > 0):
            raise ConfigError(f"state_period_s must be positive, got {self.state_period_s}")
        if self.gps_sigma_m is not None and not self.gps_sigma_m > 0:
            raise ConfigError(f"gps_sigma_m must be positive, got {self.gps_sigma_m}")
        if not self.integration_sigma > 0:
            raise ConfigError(f"integration_sigma must be positive, got {self.integration_sigma}")
        if self.relinearize_skip < 1:
            raise ConfigError(f"relinearize_skip must be >= 1, got {self.relinearize_skip}")


@dataclass(frozen=True)
class FixedLagInertialConfig(InertialSmootherConfig):
    """``fixed_lag_imu``: keeps the states of the last ``lag_s`` seconds. Its iSAM2 factorises
    with QR by default: with Cholesky it reported an indeterminate system inside a 60 s KITTI GPS
    outage (10 s lag: the window then holds IMU factors and a marginal prior only), QR runs it."""

    lag_s: float = 10.0
    factorization: str = "qr"

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (np.isfinite(self.lag_s) and self.lag_s > 0):
            raise ConfigError(f"lag_s must be positive, got {self.lag_s}")


def preintegration_params(noise: ImuNoise, gravity_mps2: np.ndarray,
                          integration_sigma: float = 1e-3) -> gtsam.PreintegrationCombinedParams:
    """GTSAM's combined preintegration parameters for ``noise`` (continuous-time densities)."""
    g = np.asarray(gravity_mps2, dtype=float).reshape(3)
    if abs(g[0]) + abs(g[1]) > 0 or g[2] >= 0:
        raise ConfigError(f"gravity must point along -z (z up), got {g.tolist()}")
    p = gtsam.PreintegrationCombinedParams.MakeSharedU(float(-g[2]))
    p.setAccelerometerCovariance(np.eye(3) * noise.accel_noise_density**2)
    p.setGyroscopeCovariance(np.eye(3) * noise.gyro_noise_density**2)
    p.setIntegrationCovariance(np.eye(3) * integration_sigma**2)
    p.setBiasAccCovariance(np.eye(3) * max(noise.accel_bias_random_walk, 1e-12)**2)
    p.setBiasOmegaCovariance(np.eye(3) * max(noise.gyro_bias_random_walk, 1e-12)**2)
    return p


def preintegrate(params: gtsam.PreintegrationCombinedParams, accel_mps2: np.ndarray, gyro_radps: np.ndarray,
                 dt_s: np.ndarray, accel_bias: np.ndarray = np.zeros(3), gyro_bias: np.ndarray = np.zeros(3)
                 ) -> gtsam.PreintegratedCombinedMeasurements:
    """(N, 3) readings held over (N,) intervals -> GTSAM's preintegrated measurement."""
    pim = gtsam.PreintegratedCombinedMeasurements(
        params, gtsam.imuBias.ConstantBias(np.asarray(accel_bias, float), np.asarray(gyro_bias, float)))
    for a, w, dt in zip(np.asarray(accel_mps2, float), np.asarray(gyro_radps, float), np.asarray(dt_s, float)):
        pim.integrateMeasurement(a, w, float(dt))
    return pim


def _world_pose_cov(R: np.ndarray, cov_body: np.ndarray) -> np.ndarray:
    """GTSAM Pose3 marginal (rot, trans; body) -> (position, attitude; world)."""
    A = np.zeros((6, 6))
    A[0:3, 3:6] = R
    A[3:6, 0:3] = R
    return A @ cov_body @ A.T


def _body_pose_cov(R: np.ndarray, cov_world: np.ndarray) -> np.ndarray:
    """The inverse map of :func:`_world_pose_cov` (A^-1 = A^T)."""
    A = np.zeros((6, 6))
    A[0:3, 3:6] = R
    A[3:6, 0:3] = R
    return A.T @ cov_world @ A


class _InertialSmootherBase(InertialEventLoop):
    """Turns IMU and GPS events into states and factors (``step`` is
    :class:`~slamkit.data.inertial.InertialEventLoop`'s); subclasses own the solver."""

    name = "inertial_smoother"
    config_class: type[InertialSmootherConfig] = InertialSmootherConfig

    def __init__(self, setup: InertialSetup, config: InertialSmootherConfig | None = None) -> None:
        config = smoother_config(self.name, self.config_class, config)
        self.setup = setup
        self.config = config
        self._ready = False

    @classmethod
    def from_sequence(cls, sequence: Sequence, config: InertialSmootherConfig | None = None):
        config = smoother_config(cls.name, cls.config_class, config)
        return cls(setup_of(sequence, imu_noise=config.imu_noise, gps_sigma_m=config.gps_sigma_m), config)

    # -- protocol --------------------------------------------------------------------------------
    def reset(self, prior: Prior | None = None) -> None:
        s, c = self.setup.initial, self.config
        self._params = preintegration_params(self.setup.imu_noise, self.setup.gravity_mps2, c.integration_sigma)
        bias = gtsam.imuBias.ConstantBias(s.accel_bias_mps2, s.gyro_bias_radps)
        self._bias = bias
        self._pim = gtsam.PreintegratedCombinedMeasurements(self._params, bias)
        pose = gtsam.Pose3(gtsam.Rot3(s.world_R_body), s.world_p_body)
        self._state = gtsam.NavState(pose.rotation(), pose.translation(), s.world_v_body)
        sig = self.setup.initial_sigma
        cov_world = np.diag(np.concatenate([sig[0:3], sig[6:9]]) ** 2)
        factors = gtsam.NonlinearFactorGraph()
        factors.add(gtsam.PriorFactorPose3(X(0), pose, gtsam.noiseModel.Gaussian.Covariance(
            _body_pose_cov(s.world_R_body, cov_world))))
        factors.add(gtsam.PriorFactorVector(V(0), s.world_v_body, gtsam.noiseModel.Diagonal.Sigmas(sig[3:6])))
        factors.add(gtsam.PriorFactorConstantBias(B(0), bias, gtsam.noiseModel.Diagonal.Sigmas(sig[9:15])))
        values = gtsam.Values()
        values.insert(X(0), pose)
        values.insert(V(0), s.world_v_body)
        values.insert(B(0), bias)
        self._stamps = [float(s.stamp_s)]
        self._start_loop(s.stamp_s)            # self.t: the end of the preintegrated interval
        self._counts["states"] = 1
        self._reset_solver()
        self._update(factors, values, {X(0): self._stamps[0], V(0): self._stamps[0], B(0): self._stamps[0]})
        self._ready = True

    def _integrate(self, accel: np.ndarray, gyro: np.ndarray, dt: float) -> None:
        accel = np.asarray(accel, dtype=float)
        gyro = np.asarray(gyro, dtype=float)
        if not (np.isfinite(accel).all() and np.isfinite(gyro).all()):
            raise EstimationError(f"{self.name}: Imu at t={self.t + dt}: a reading is not finite")
        self._pim.integrateMeasurement(accel, gyro, dt)

    def _after_imu(self) -> None:
        if self.t - self._stamps[-1] >= self.config.state_period_s - 1e-9:
            self._new_state(())

    def _fix(self, z: np.ndarray, sigma_m: float) -> None:
        sigma = sigma_m if self.config.gps_sigma_m is None else self.config.gps_sigma_m
        if self._pim.deltaTij() > 0:
            self._new_state((z, sigma))
        else:  # the fix lands on the newest state
            factors = gtsam.NonlinearFactorGraph()
            factors.add(gtsam.GPSFactor(X(len(self._stamps) - 1), z, gtsam.noiseModel.Isotropic.Sigma(3, sigma)))
            self._update(factors, gtsam.Values(), {})

    def estimate(self) -> Estimate:
        if not self._ready:
            raise EstimationError(f"{self.name}: estimate() called before reset(prior)")
        rows = [self._state_row(k) for k in range(len(self._stamps))]
        p = np.array([r[0] for r in rows])
        R = np.array([r[1] for r in rows])
        bias = np.array([r[2] for r in rows])
        covs = bias_sigma = None
        if self.config.compute_covariances and all(r[3] is not None for r in rows):
            covs = np.array([_world_pose_cov(r[1], r[3]) for r in rows])
            bias_sigma = np.array([np.sqrt(np.clip(np.diag(r[4]), 0.0, None)) for r in rows])
        stamps = np.array(self._stamps)
        extras = {**self._counts, "bias": bias, "bias_stamps_s": stamps,
                  "world_v_body": np.array([r[5] for r in rows])}
        if bias_sigma is not None:
            extras["bias_sigma"] = bias_sigma
        return Estimate(trajectory=Trajectory(stamps, p, so3.to_quat_wxyz(R)), pose_covariances=covs,
                        step_latency_s=np.array(self._latency), extras=extras)

    def latest_estimate(self) -> Estimate:
        """The newest state's pose alone, without marginals (constant cost; for observers)."""
        pose = self._state.pose()
        traj = Trajectory([self._stamps[-1]], np.asarray(pose.translation())[None],
                          so3.to_quat_wxyz(np.asarray(pose.rotation().matrix()))[None])
        return Estimate(trajectory=traj)

    # -- internals -------------------------------------------------------------------------------
    def _new_state(self, gps: tuple) -> None:
        k = len(self._stamps)
        factors = gtsam.NonlinearFactorGraph()
        factors.add(gtsam.CombinedImuFactor(X(k - 1), V(k - 1), X(k), V(k), B(k - 1), B(k), self._pim))
        predicted = self._pim.predict(self._state, self._bias)
        values = gtsam.Values()
        values.insert(X(k), predicted.pose())
        values.insert(V(k), predicted.velocity())
        values.insert(B(k), self._bias)
        if gps:
            z, sigma = gps
            factors.add(gtsam.GPSFactor(X(k), z, gtsam.noiseModel.Isotropic.Sigma(3, sigma)))
        self._stamps.append(self.t)
        self._counts["states"] += 1
        t = self.t
        self._update(factors, values, {X(k): t, V(k): t, B(k): t})
        self._state = gtsam.NavState(self._current(k, "pose"), self._current(k, "velocity"))
        self._bias = self._current(k, "bias")
        self._pim.resetIntegrationAndSetBias(self._bias)

    def _update(self, factors, values, stamps) -> None:
        """Hand new factors to the solver; GTSAM's failures become an EstimationError (the runner
        records the run as failed instead of stopping)."""
        try:
            self._commit(factors, values, stamps)
        except RuntimeError as exc:
            first = " ".join(str(exc).split())[:200]
            raise EstimationError(f"{self.name}: GTSAM update at t={self._stamps[-1]:.3f} s failed "
                                  f"({first}); try factorization: qr") from None

    # -- solver hooks ----------------------------------------------------------------------------
    def _reset_solver(self) -> None:
        raise NotImplementedError

    def _commit(self, factors, values, stamps) -> None:
        raise NotImplementedError

    def _current(self, k: int, what: str):
        raise NotImplementedError

    def _state_row(self, k: int):
        """(position (3,), R (3, 3), bias (6,), pose marginal (body, 6x6) | None, bias
        marginal | None, velocity (3,)) of state k."""
        raise NotImplementedError


def _isam2_params(config: InertialSmootherConfig) -> gtsam.ISAM2Params:
    p = gtsam.ISAM2Params()
    p.setRelinearizeThreshold(config.relinearize_threshold)
    p.relinearizeSkip = config.relinearize_skip
    if config.factorization == "qr":
        p.setFactorization("QR")
    return p


def _read(values_or_solver, key_kind: str, key: int):
    if key_kind == "pose":
        return values_or_solver.calculateEstimatePose3(key)
    if key_kind == "velocity":
        return values_or_solver.calculateEstimateVector(key)
    return values_or_solver.calculateEstimateConstantBias(key)


_KEY = {"pose": X, "velocity": V, "bias": B}


class Isam2Inertial(_InertialSmootherBase):
    """iSAM2 over every state (registry name ``isam2_imu``): one update per new state."""

    name = "isam2_imu"
    config_class = InertialSmootherConfig

    def _reset_solver(self) -> None:
        self._isam = gtsam.ISAM2(_isam2_params(self.config))
        self._result: gtsam.Values | None = None

    def _commit(self, factors, values, stamps) -> None:
        self._isam.update(factors, values)
        self._result = None

    def _current(self, k: int, what: str):
        return _read(self._isam, what, _KEY[what](k))

    def _state_row(self, k: int):
        if self._result is None:
            self._result = self._isam.calculateEstimate()
        est = self._result
        pose = est.atPose3(X(k))
        b = est.atConstantBias(B(k))
        cov_pose = cov_bias = None
        if self.config.compute_covariances:
            cov_pose = self._isam.marginalCovariance(X(k))
            cov_bias = self._isam.marginalCovariance(B(k))
        return (np.asarray(pose.translation()), np.asarray(pose.rotation().matrix()),
                np.asarray(b.vector()), cov_pose, cov_bias, np.asarray(est.atVector(V(k))))


class FixedLagInertial(_InertialSmootherBase):
    """Fixed-lag smoother (registry name ``fixed_lag_imu``) over the last ``config.lag_s`` s.
    A state that leaves the window keeps the value and marginals it had just before."""

    name = "fixed_lag_imu"
    config_class = FixedLagInertialConfig
    config: FixedLagInertialConfig

    def _reset_solver(self) -> None:
        self._smoother = gtsam.IncrementalFixedLagSmoother(float(self.config.lag_s), _isam2_params(self.config))
        self._key_stamp: dict[int, float] = {}
        self._frozen: dict[int, tuple] = {}

    def _commit(self, factors, values, stamps) -> None:
        self._key_stamp.update(stamps)
        newest = max(self._key_stamp.values())
        leaving = sorted({int(gtsam.Symbol(key).index()) for key, t in self._key_stamp.items()
                          if t < newest - self.config.lag_s})
        for k in leaving:
            if k not in self._frozen:
                self._frozen[k] = self._live_row(k)
        self._smoother.update(factors, values, stamps)
        for k in leaving:
            for key in (X(k), V(k), B(k)):
                self._key_stamp.pop(key, None)

    def _current(self, k: int, what: str):
        return _read(self._smoother, what, _KEY[what](k))

    def _live_row(self, k: int):
        pose = self._smoother.calculateEstimatePose3(X(k))
        b = self._smoother.calculateEstimateConstantBias(B(k))
        cov_pose = cov_bias = None
        if self.config.compute_covariances:
            cov_pose = self._smoother.marginalCovariance(X(k))
            cov_bias = self._smoother.marginalCovariance(B(k))
        return (np.asarray(pose.translation()), np.asarray(pose.rotation().matrix()),
                np.asarray(b.vector()), cov_pose, cov_bias,
                np.asarray(self._smoother.calculateEstimateVector(V(k))))

    def _state_row(self, k: int):
        if X(k) in self._key_stamp:
            return self._live_row(k)
        return self._frozen[k]
