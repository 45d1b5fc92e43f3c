"""Visual-inertial odometry as a running system: IMU readings and tracked-feature frames in,
IMU (body) poses out.

The back-end is :class:`slamkit.backend.visual_inertial.SmartVioSmoother` (iSAM2 over one
navigation state per camera frame, preintegrated IMU factors, the feature tracks as smart
projection factors). This module does what happens around it:

1. **Static initialisation** (as OpenVINS' static initialiser; Geneva et al., "OpenVINS", ICRA
   2020, sec. VI): the system must start at rest. The first ``static_init_s`` seconds of IMU
   readings give the gravity direction (the mean specific force points up in the body frame: the
   attitude is the smallest rotation taking it to world +z; the yaw is unobservable and set to
   that rotation's) and the gyro bias (the mean rate). The first frame after that window is state
   0, at the world origin, at rest.
2. **Preintegration** between frames of the readings, each held over the interval that ends at
   its stamp (:mod:`slamkit.data.inertial`'s convention), from the newest bias estimate.
3. **Zero-velocity updates**: a frame whose tracks moved less than ``stationary_flow`` (median,
   normalised image units) since the previous frame is stationary: no parallax, so its features
   would constrain nothing; a zero-velocity prior and an identity between the two poses keep the
   IMU from drifting while the platform waits.

Frames and readings must arrive in time order. Feature coordinates are undistorted, normalised
(x/z, y/z in the camera frame), with a track id per feature. The world frame is gravity-aligned
(z up), its origin the body at state 0. The system knows nothing of ground truth or files;
:func:`run_vio` feeds it a recording read into memory (the gtsam wheel's EuRoC replay file,
:class:`~slamkit.data.formats.eqvio_csv.EqvioData`), and the tests score it against EuRoC's
ground truth beside OpenVINS (``tests/systems/peer_comparison.py``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from slamkit.backend.visual_inertial import SmartVioConfig, SmartVioSmoother
from slamkit.data.formats.eqvio_csv import EqvioData
from slamkit.data.inertial import STANDARD_GRAVITY_MPS2
from slamkit.errors import ConfigError, EstimationError
from slamkit.geometry import so3
from slamkit.models.imu import ImuNoise

__all__ = ["EUROC_IMU_NOISE", "VioConfig", "VioFrameResult", "VioEstimate", "VisualInertialOdometry", "run_vio"]

#: EuRoC MAV's ADIS16448 (``imu0/sensor.yaml`` of every EuRoC sequence): continuous-time densities
EUROC_IMU_NOISE = ImuNoise(gyro_noise_density=1.6968e-4, gyro_bias_random_walk=1.9393e-5,
                           accel_noise_density=2.0e-3, accel_bias_random_walk=3.0e-3)


@dataclass(frozen=True)
class VioConfig:
    imu_noise: ImuNoise = EUROC_IMU_NOISE
    gravity_mps2: float = STANDARD_GRAVITY_MPS2
    smoother: SmartVioConfig = field(default_factory=SmartVioConfig)
    #: seconds of IMU at rest used for the static initialisation
    static_init_s: float = 1.0
    #: a frame whose tracks moved less than this (median, normalised units) is stationary;
    #: 0.5 px at EuRoC's fx = 458.654 px
    stationary_flow: float = 0.5 / 458.654
    #: prior sigmas of state 0: attitude (rad), position (m), velocity (m/s), accel bias
    #: (m/s^2), gyro bias (rad/s)
    initial_attitude_sigma_rad: float = 1e-3
    initial_position_sigma_m: float = 1e-3
    initial_velocity_sigma_mps: float = 1e-2
    initial_accel_bias_sigma: float = 0.1
    initial_gyro_bias_sigma: float = 5e-3

    def __post_init__(self) -> None:
        if not (self.static_init_s > 0 and self.stationary_flow >= 0 and self.gravity_mps2 > 0):
            raise ConfigError("VioConfig needs static_init_s > 0, stationary_flow >= 0, gravity_mps2 > 0")


@dataclass(frozen=True)
class VioFrameResult:
    index: int                     #: state index (-1: the frame came before initialisation)
    stamp_s: float
    world_T_body: np.ndarray | None
    num_features: int
    stationary: bool
    step_ms: float


@dataclass(frozen=True)
class VioEstimate:
    stamps_s: np.ndarray           #: (K,) the frames that became states
    world_T_body: np.ndarray       #: (K, 4, 4) smoothed
    world_v_body: np.ndarray       #: (K, 3)
    bias: np.ndarray               #: (K, 6) accel (m/s^2), gyro (rad/s)
    step_ms: np.ndarray            #: (K,) time of each frame's update
    stationary_frames: int


class VisualInertialOdometry:
    """Streaming VIO: ``step_imu(stamp_s, accel, gyro)``, ``step_frame(stamp_s, ids, xy)``,
    ``estimate()`` (module doc)."""

    def __init__(self, imu_T_camera: np.ndarray, config: VioConfig = VioConfig()) -> None:
        if not isinstance(config, VioConfig):
            raise ConfigError(f"VisualInertialOdometry is configured by VioConfig, not {type(config).__name__}")
        self.config = config
        self.imu_T_camera = np.asarray(imu_T_camera, dtype=float).reshape(4, 4)
        self._smoother = SmartVioSmoother(config.imu_noise, np.array([0.0, 0.0, -config.gravity_mps2]),
                                          self.imu_T_camera, config.smoother)
        self._imu: list[tuple[float, np.ndarray, np.ndarray]] = []   # readings before initialisation
        self._pim = None
        self._t = None            # the end of the preintegrated interval
        self._stamps: list[float] = []
        self._step_ms: list[float] = []
        self._prev: tuple[np.ndarray, np.ndarray] | None = None
        self._stationary = 0

    # -- input ------------------------------------------------------------------------------
    def step_imu(self, stamp_s: float, accel_mps2: np.ndarray, gyro_radps: np.ndarray) -> None:
        accel = np.asarray(accel_mps2, dtype=float).reshape(3)
        gyro = np.asarray(gyro_radps, dtype=float).reshape(3)
        if not (np.isfinite(accel).all() and np.isfinite(gyro).all() and np.isfinite(stamp_s)):
            raise EstimationError(f"VisualInertialOdometry: Imu at t={stamp_s}: a value is not finite")
        if self._pim is None:
            self._imu.append((float(stamp_s), accel, gyro))
            return
        dt = float(stamp_s) - self._t
        if dt > 0:
            self._pim.integrateMeasurement(accel, gyro, dt)
            self._t = float(stamp_s)

    def step_frame(self, stamp_s: float, landmark_ids: np.ndarray, xy_normalised: np.ndarray) -> VioFrameResult:
        t0 = time.perf_counter()
        ids = np.asarray(landmark_ids, dtype=int).reshape(-1)
        xy = np.asarray(xy_normalised, dtype=float).reshape(-1, 2)
        if len(ids) != len(xy) or not np.isfinite(xy).all():
            raise EstimationError(f"VisualInertialOdometry: frame at t={stamp_s}: ids and finite xy must pair up")
        if self._pim is None:
            if not self._imu or self._imu[-1][0] - self._imu[0][0] < self.config.static_init_s:
                return VioFrameResult(-1, float(stamp_s), None, len(ids), False, 0.0)
            self._initialise(float(stamp_s))
            stationary = False
        else:
            stationary = self._is_stationary(ids, xy)
            self._stationary += stationary
            self._smoother.add_frame(self._pim, ids, xy, stationary=stationary)
            self._pim = self._smoother.new_preintegration(*self._smoother.latest_bias)
        self._prev = (ids, xy)
        self._stamps.append(float(stamp_s))
        ms = (time.perf_counter() - t0) * 1e3
        self._step_ms.append(ms)
        return VioFrameResult(len(self._stamps) - 1, float(stamp_s), self._smoother.latest_world_T_body(), len(ids),
                              stationary, ms)

    # -- internals --------------------------------------------------------------------------
    def _initialise(self, stamp_s: float) -> None:
        c = self.config
        accel = np.array([a for _, a, _ in self._imu])
        gyro = np.array([w for _, _, w in self._imu])
        up = accel.mean(axis=0)
        up /= np.linalg.norm(up)
        axis = np.cross(up, [0.0, 0.0, 1.0])
        s = np.linalg.norm(axis)
        world_R_body = so3.exp(axis / s * np.arctan2(s, up[2])) if s > 1e-12 else np.eye(3)
        T = np.eye(4)
        T[:3, :3] = world_R_body
        gyro_bias = gyro.mean(axis=0)
        sig = np.r_[np.full(3, c.initial_attitude_sigma_rad), np.full(3, c.initial_position_sigma_m),
                    np.full(3, c.initial_velocity_sigma_mps), c.initial_accel_bias_sigma, c.initial_gyro_bias_sigma]
        self._smoother.start(T, np.zeros(3), np.zeros(3), gyro_bias, sig)
        self._pim = self._smoother.new_preintegration(np.zeros(3), gyro_bias)
        self._t = stamp_s
        self._imu = []

    def _is_stationary(self, ids: np.ndarray, xy: np.ndarray) -> bool:
        if self._prev is None:
            return False
        pids, pxy = self._prev
        _, a, b = np.intersect1d(pids, ids, return_indices=True)
        if len(a) == 0:
            return False
        return bool(np.median(np.linalg.norm(pxy[a] - xy[b], axis=1)) < self.config.stationary_flow)

    def estimate(self) -> VioEstimate:
        if not self._stamps:
            raise EstimationError("VisualInertialOdometry.estimate(): not initialised (no frame after the static window)")
        T, v, bias = self._smoother.states()
        return VioEstimate(np.array(self._stamps), T, v, bias, np.array(self._step_ms), self._stationary)


def run_vio(data: EqvioData, config: VioConfig = VioConfig(), until_s: float | None = None) -> VioEstimate:
    """Feed a recording's IMU readings and frames (up to ``until_s`` seconds after the first
    reading) to a fresh system in time order and return its estimate."""
    vio = VisualInertialOdometry(data.imu_T_camera, config)
    end = np.inf if until_s is None else data.imu_stamps_s[0] + until_s + 1e-9
    i = 0
    for t, (ids, xy) in zip(data.frame_stamps_s, data.frame_features):
        if t > end:
            break
        while i < len(data.imu_stamps_s) and data.imu_stamps_s[i] <= t + 1e-9:
            vio.step_imu(data.imu_stamps_s[i], data.accel_mps2[i], data.gyro_radps[i])
            i += 1
        vio.step_frame(t, ids, xy)
    return vio.estimate()
