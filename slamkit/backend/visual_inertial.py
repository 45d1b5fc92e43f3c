"""Visual-inertial smoothing in iSAM2: preintegrated IMU factors between camera-frame states and
the tracked features as smart projection factors.

State k (one per camera frame) is (X(k): world_T_body Pose3, V(k): velocity, B(k):
ConstantBias); consecutive states are tied by a ``CombinedImuFactor`` (Forster et al., "On-Manifold
Preintegration for Real-Time Visual-Inertial Odometry", T-RO 33(1), 2017; the preintegration
parameters of :func:`slamkit.backend.inertial.preintegration_params`, gravity along -z). Each
feature track j is one ``SmartProjectionPoseFactorCal3_S2`` over the poses that saw it (Carlone,
Kira, Beall, Indelman, Dellaert, "Eliminating conditionally independent sets in factor graphs: a
unifying perspective based on smart factors", ICRA 2014): the landmark is triangulated and
eliminated inside the factor, so no landmark variable enters the graph and a poorly triangulated
track contributes nothing (``ZERO_ON_DEGENERACY``) instead of making the system indeterminate.
Measurements are normalised image coordinates (camera Cal3_S2(1, 1, 0, 0, 0)); the camera sits at
``imu_T_camera`` on the body (the factor's ``body_P_sensor``).

iSAM2 (Kaess et al., IJRR 2012) takes one update per frame. A track that gains an observation is
a new smart factor: the old one is removed in the same update (``removeFactorIndices``), as GTSAM's
``ISAM2_SmartFactorStereo_IMU`` example does. A track enters the graph once it has
``min_track_length`` observations; it keeps at most ``max_track_length`` (the first and the newest).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np
from gtsam.symbol_shorthand import B, V, X

from slamkit.backend.inertial import _isam2_params, preintegration_params
from slamkit.errors import ConfigError, EstimationError
from slamkit.models.imu import ImuNoise

__all__ = ["SmartVioConfig", "SmartVioSmoother"]


@dataclass(frozen=True)
class SmartVioConfig:
    #: feature noise in normalised image coordinates (1 px at fx = 458 px is 2.2e-3)
    feature_sigma: float = 1.0 / 458.654
    #: Huber threshold in sigmas on each smart factor (0: no robust kernel)
    huber_k: float = 0.0
    min_track_length: int = 3
    #: a smart factor keeps the first and the newest observations of its track, this many in all:
    #: it bounds the factor's size and so iSAM2's fill-in. Measured on EuRoC V1_01 (30 s): no cap
    #: 169 s, SE(3) ATE 0.021 m; 100: 83 s, 0.018 m; 20-60: diverged after ~8 s of flight
    max_track_length: int = 100
    #: tracks triangulated farther than this are treated as degenerate (m)
    landmark_distance_threshold_m: float = 20.0
    #: smart-factor outlier rejection: a reprojection error above this (normalised units) drops the track
    outlier_threshold: float = 10.0 / 458.654
    integration_sigma: float = 1e-3
    relinearize_threshold: float = 0.01
    relinearize_skip: int = 1
    factorization: str = "cholesky"
    #: zero-velocity update sigmas (``add_frame(stationary=True)``)
    zupt_velocity_sigma_mps: float = 0.01
    zupt_position_sigma_m: float = 0.001
    zupt_rotation_sigma_rad: float = 0.001

    def __post_init__(self) -> None:
        if not (self.feature_sigma > 0 and 2 <= self.min_track_length <= self.max_track_length and self.huber_k >= 0):
            raise ConfigError("SmartVioConfig needs feature_sigma > 0, 2 <= min_track_length <= max_track_length, "
                              "huber_k >= 0")
        if self.factorization not in ("cholesky", "qr"):
            raise ConfigError(f"factorization must be 'cholesky' or 'qr', got {self.factorization!r}")


class SmartVioSmoother:
    """iSAM2 over IMU-linked camera-frame states with smart projection factors (module doc)."""

    def __init__(self, imu_noise: ImuNoise, gravity_mps2: np.ndarray, imu_T_camera: np.ndarray,
                 config: SmartVioConfig = SmartVioConfig()) -> None:
        self.config = config
        self._params = preintegration_params(imu_noise, gravity_mps2, config.integration_sigma)
        self._body_P_camera = gtsam.Pose3(np.asarray(imu_T_camera, dtype=float))
        self._K = gtsam.Cal3_S2(1.0, 1.0, 0.0, 0.0, 0.0)
        sp = gtsam.SmartProjectionParams()
        sp.setDegeneracyMode(gtsam.DegeneracyMode.ZERO_ON_DEGENERACY)
        sp.setLandmarkDistanceThreshold(config.landmark_distance_threshold_m)
        sp.setDynamicOutlierRejectionThreshold(config.outlier_threshold)
        self._smart_params = sp
        noise = gtsam.noiseModel.Isotropic.Sigma(2, config.feature_sigma)
        if config.huber_k > 0:
            noise = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(config.huber_k), noise)
        self._feature_noise = noise
        self._isam = gtsam.ISAM2(_isam2_params(config))
        self._tracks: dict[int, list[tuple[int, np.ndarray]]] = {}
        self._factor_index: dict[int, int] = {}
        self._k = -1

    @property
    def params(self) -> gtsam.PreintegrationCombinedParams:
        return self._params

    def new_preintegration(self, accel_bias: np.ndarray, gyro_bias: np.ndarray
                           ) -> gtsam.PreintegratedCombinedMeasurements:
        return gtsam.PreintegratedCombinedMeasurements(
            self._params, gtsam.imuBias.ConstantBias(np.asarray(accel_bias, float), np.asarray(gyro_bias, float)))

    def start(self, world_T_body: np.ndarray, world_v_body: np.ndarray, accel_bias: np.ndarray,
              gyro_bias: np.ndarray, sigmas: np.ndarray) -> None:
        """State 0 with priors; ``sigmas`` (12): rotation (3, body), position (3), velocity (3)
        as GTSAM orders the Pose3 tangent, then one accel and one gyro bias sigma."""
        s = np.asarray(sigmas, dtype=float)
        pose = gtsam.Pose3(np.asarray(world_T_body, dtype=float))
        bias = gtsam.imuBias.ConstantBias(np.asarray(accel_bias, float), np.asarray(gyro_bias, float))
        g = gtsam.NonlinearFactorGraph()
        g.add(gtsam.PriorFactorPose3(X(0), pose, gtsam.noiseModel.Diagonal.Sigmas(s[0:6])))
        g.add(gtsam.PriorFactorVector(V(0), np.asarray(world_v_body, float), gtsam.noiseModel.Diagonal.Sigmas(s[6:9])))
        g.add(gtsam.PriorFactorConstantBias(B(0), bias, gtsam.noiseModel.Diagonal.Sigmas(
            np.r_[np.full(3, s[9]), np.full(3, s[10])])))
        v = gtsam.Values()
        v.insert(X(0), pose)
        v.insert(V(0), np.asarray(world_v_body, float))
        v.insert(B(0), bias)
        self._isam.update(g, v)
        self._k = 0
        self._nav = gtsam.NavState(pose.rotation(), pose.translation(), np.asarray(world_v_body, float))
        self._bias = bias

    def add_frame(self, pim: gtsam.PreintegratedCombinedMeasurements, landmark_ids: np.ndarray,
                  xy_normalised: np.ndarray, stationary: bool = False) -> None:
        """A new state after ``pim`` (integrated from the previous state) seeing the features;
        ``stationary``: the caller detected no motion since the previous frame, so a zero-velocity
        prior on V(k) and an identity between X(k-1) and X(k) are added (a zero-velocity update:
        with no parallax the features constrain nothing and the IMU alone would drift)."""
        if self._k < 0:
            raise EstimationError("SmartVioSmoother.add_frame before start()")
        k = self._k + 1
        g = gtsam.NonlinearFactorGraph()
        g.add(gtsam.CombinedImuFactor(X(k - 1), V(k - 1), X(k), V(k), B(k - 1), B(k), pim))
        if stationary:
            c = self.config
            g.add(gtsam.PriorFactorVector(V(k), np.zeros(3), gtsam.noiseModel.Isotropic.Sigma(3, c.zupt_velocity_sigma_mps)))
            g.add(gtsam.BetweenFactorPose3(X(k - 1), X(k), gtsam.Pose3(), gtsam.noiseModel.Diagonal.Sigmas(
                np.r_[np.full(3, c.zupt_rotation_sigma_rad), np.full(3, c.zupt_position_sigma_m)])))
        predicted = pim.predict(self._nav, self._bias)
        v = gtsam.Values()
        v.insert(X(k), predicted.pose())
        v.insert(V(k), predicted.velocity())
        v.insert(B(k), self._bias)
        remove, slots = [], []
        for j, xy in zip(np.asarray(landmark_ids, int), np.asarray(xy_normalised, float)):
            if stationary:
                break  # no parallax: the zero-velocity update stands in for the features
            track = self._tracks.setdefault(int(j), [])
            track.append((k, xy.copy()))
            if len(track) > self.config.max_track_length:  # keep the first (the widest baseline)
                del track[1:len(track) - self.config.max_track_length + 1]
            if len(track) < self.config.min_track_length:
                continue
            f = gtsam.SmartProjectionPoseFactorCal3_S2(self._feature_noise, self._K, self._body_P_camera,
                                                        self._smart_params)
            for kk, z in track:
                f.add(gtsam.Point2(z), X(kk))
            if int(j) in self._factor_index:
                remove.append(self._factor_index[int(j)])
            slots.append(int(j))
            g.add(f)
        try:
            result = self._isam.update(g, v, remove)
        except RuntimeError as exc:
            raise EstimationError(f"SmartVioSmoother: iSAM2 update at state {k} failed "
                                  f"({' '.join(str(exc).split())[:200]})") from None
        new = list(result.getNewFactorsIndices())
        for j, idx in zip(slots, new[len(new) - len(slots):]):
            self._factor_index[j] = int(idx)
        self._k = k
        est = self._isam.calculateEstimate()
        self._values = est
        self._nav = gtsam.NavState(est.atPose3(X(k)).rotation(), est.atPose3(X(k)).translation(), est.atVector(V(k)))
        self._bias = est.atConstantBias(B(k))

    @property
    def latest_bias(self) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self._bias.accelerometer()), np.asarray(self._bias.gyroscope())

    def latest_world_T_body(self) -> np.ndarray:
        return np.asarray(self._nav.pose().matrix())

    def states(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Smoothed (K, 4, 4) world_T_body, (K, 3) velocities and (K, 6) biases (accel, gyro)."""
        est = self._isam.calculateEstimate()
        n = self._k + 1
        T = np.array([est.atPose3(X(k)).matrix() for k in range(n)])
        vel = np.array([est.atVector(V(k)) for k in range(n)])
        bias = np.array([est.atConstantBias(B(k)).vector() for k in range(n)])
        return T, vel, bias
