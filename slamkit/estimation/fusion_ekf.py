"""Multi-rate planar fusion EKF (course Example 11.1): state (x, y, theta, v, omega), predicted at
the IMU rate from the gyro and the forward accelerometer, updated by the wheel encoders and by
lidar pose fixes (scan matching, ``slamkit.systems.fusion``).

Model (Thrun, Burgard & Fox, *Probabilistic Robotics*, Table 3.3 for the EKF; the inputs are the
IMU readings, as in strapdown dead reckoning). Over dt with u = (a_x, omega_g):

    x'     = x + v cos(theta) dt          theta' = theta + omega_g dt
    y'     = y + v sin(theta) dt          v'     = v + a_x dt
                                          omega' = omega_g

so F = df/dx is the 5x5 kinematic Jacobian of :func:`motion_jacobians` and the input noise
(``accel_sigma_mps2``, ``gyro_sigma_radps``, per sample) enters through G = df/du:
P' = F P F^T + G diag(sigma_a^2, sigma_g^2) G^T + Q_extra dt, with Q_extra the process noise
densities ``v_random_walk``, ``omega_random_walk`` and ``pose_random_walk`` that stand for what
the five states cannot represent (a wheel-radius error, slip, a gyro bias): without them the
500 Hz encoder updates, whose errors are systematic rather than white, make the filter trust a
velocity 3% off and ignore the lidar. A measurement
at a stamp after the last IMU sample first predicts to its stamp with that sample held
(zero-order hold); the next IMU sample covers the rest of its interval.

Updates (Joseph form, :func:`slamkit.estimation.ekf.ekf_update`):

* wheel encoders, h(x) = (v, omega) with H = [0 0 0 1 0; 0 0 0 0 1], the tick increments over
  the time since the previous reading turned into rates by ``diff_drive.odometry_from_ticks``
  with the wheel calibration the robot believes; R_enc = ``encoder_covariance``
  (default diag(0.001, 0.001));
* pose fixes, h(x) = (x, y, theta), H = [I_3 0], heading innovation wrapped; R_lidar the fix's
  own covariance or ``lidar_covariance`` (default diag(0.01, 0.01, 0.001)).

Late and out-of-order events (the rule): every processed input is kept, with the state before
it, for ``replay_window_s``. An event older than the newest processed stamp but inside the
window is *buffered and replayed*: the state is restored to just before the first kept input
later than the event, the event is applied, and the later inputs are re-applied in stamp order
(the filter then equals one fed everything in order). An event older than the window is
*dropped and counted* (``extras["late_dropped"]``; replays are ``extras["late_replayed"]``).
Trajectory rows already output stay as they were (they are what the filter said in real time);
the newest row is refreshed.
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from slamkit.data.estimate import Prior
from slamkit.data.sequence import Event, Imu, WheelEncoders
from slamkit.errors import ConfigError, EstimationError
from slamkit.estimation._common import FilterBase
from slamkit.estimation.ekf import ekf_update
from slamkit.geometry.angles import wrap_angle
from slamkit.models.diff_drive import odometry_from_ticks

#: state order
X, Y, THETA, V, OMEGA = range(5)
H_ENCODERS = np.array([[0.0, 0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0]])
H_POSE = np.eye(3, 5)


def motion(x: np.ndarray, u: np.ndarray, dt_s: float) -> np.ndarray:
    """The 5-state prediction f(x, u) over ``dt_s`` with u = (a_x, omega_g) (module doc)."""
    x = np.asarray(x, dtype=float)
    c, s = np.cos(x[THETA]), np.sin(x[THETA])
    return np.array([x[X] + x[V] * c * dt_s, x[Y] + x[V] * s * dt_s,
                     wrap_angle(x[THETA] + u[1] * dt_s), x[V] + u[0] * dt_s, u[1]])


def motion_jacobians(x: np.ndarray, u: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(F (5, 5), G (5, 2)): the derivatives of :func:`motion` with respect to x and u."""
    c, s = np.cos(x[THETA]), np.sin(x[THETA])
    F = np.eye(5)
    F[X, THETA], F[X, V] = -x[V] * s * dt_s, c * dt_s
    F[Y, THETA], F[Y, V] = x[V] * c * dt_s, s * dt_s
    F[OMEGA, OMEGA] = 0.0
    G = np.zeros((5, 2))
    G[THETA, 1] = dt_s
    G[V, 0] = dt_s
    G[OMEGA, 1] = 1.0
    return F, G


@dataclass(frozen=True)
class WheelCalibration:
    """What the robot believes about its wheels (``encoder_ticks_per_rev``, ``wheel_radius_m``,
    ``half_axle_m`` of a Sequence's metadata)."""

    ticks_per_rev: int
    wheel_radius_m: float
    half_axle_m: float

    @classmethod
    def from_metadata(cls, metadata: Mapping[str, Any]) -> "WheelCalibration | None":
        keys = ("encoder_ticks_per_rev", "wheel_radius_m", "half_axle_m")
        if not all(k in metadata for k in keys):
            return None
        return cls(int(metadata[keys[0]]), float(metadata[keys[1]]), float(metadata[keys[2]]))

    @staticmethod
    def required(calibration: "WheelCalibration | None", who: str) -> "WheelCalibration":
        """``calibration``, or a ConfigError naming ``who`` when there is none."""
        if calibration is None:
            raise ConfigError(f"{who}: wheel encoder events need the wheel calibration "
                              "(metadata encoder_ticks_per_rev, wheel_radius_m, half_axle_m)")
        return calibration

    def rates(self, encoders: WheelEncoders, dt_s: float) -> np.ndarray:
        """(v_mps, omega_radps) over the ``dt_s`` the tick increments of ``encoders`` span."""
        d, dth = odometry_from_ticks(encoders.ticks_right, encoders.ticks_left, self.ticks_per_rev,
                                     self.wheel_radius_m, self.half_axle_m)
        return np.array([float(d), float(dth)]) / dt_s


@dataclass(frozen=True)
class PoseFix:
    """A world pose measurement (x, y, theta) with its covariance, e.g. from scan matching."""

    stamp_s: float
    world_xytheta_body: np.ndarray
    covariance: np.ndarray | None = None


@dataclass(frozen=True)
class FusionEkfConfig:
    #: per-sample white noise of the accelerometer (x) and the gyro (z) as prediction inputs
    accel_sigma_mps2: float = 0.05
    gyro_sigma_radps: float = 0.01
    #: process noise densities of v and omega (m/s/sqrt(s), rad/s/sqrt(s)) and of the pose
    #: (m/sqrt(s), m/sqrt(s), rad/sqrt(s)): what the five states cannot model
    v_random_walk: float = 0.05
    omega_random_walk: float = 0.05
    pose_random_walk: tuple[float, float, float] = (0.1, 0.1, 0.06)
    #: R_enc (v, omega) and the default R_lidar (x, y, theta)
    encoder_covariance: tuple[float, float] = (0.001, 0.001)
    lidar_covariance: tuple[float, float, float] = (0.01, 0.01, 0.001)
    #: "fixed": R_lidar = lidar_covariance; "measured": the fix's own covariance when it has one
    lidar_noise: str = "fixed"
    #: initial standard deviations of v and omega (the pose's come from the prior)
    initial_v_sigma_mps: float = 0.1
    initial_omega_sigma_radps: float = 0.1
    #: how far back a late event is replayed (older ones are dropped and counted)
    replay_window_s: float = 0.5

    def __post_init__(self) -> None:
        if self.lidar_noise not in ("fixed", "measured"):
            raise ConfigError(f"FusionEkfConfig.lidar_noise must be 'fixed' or 'measured', got {self.lidar_noise!r}")
        for name in ("accel_sigma_mps2", "gyro_sigma_radps", "v_random_walk", "omega_random_walk",
                     "replay_window_s", "initial_v_sigma_mps", "initial_omega_sigma_radps"):
            if not getattr(self, name) >= 0:
                raise ConfigError(f"FusionEkfConfig.{name} must be >= 0, got {getattr(self, name)}")
        if min(self.encoder_covariance) <= 0 or min(self.lidar_covariance) <= 0:
            raise ConfigError("FusionEkfConfig: encoder_covariance and lidar_covariance must be > 0")


class FusionEKF(FilterBase):
    """The 5-state multi-rate EKF (see the module doc). ``step`` takes Imu, WheelEncoders and
    :class:`PoseFix` events (others are counted as ignored); ``state`` and ``covariance`` are
    the full 5-state belief."""

    name = "fusion_ekf"

    def __init__(self, calibration: WheelCalibration | None, config: FusionEkfConfig = FusionEkfConfig()):
        super().__init__()
        self.calibration = calibration
        self.config = config
        self._R_enc = np.diag(np.asarray(config.encoder_covariance, dtype=float))
        self._R_lidar = np.diag(np.asarray(config.lidar_covariance, dtype=float))

    # -- state -------------------------------------------------------------------------------
    @property
    def state(self) -> np.ndarray:
        return self._s["x"].copy()

    @property
    def covariance(self) -> np.ndarray:
        return self._s["P"].copy()

    def _reset(self, prior: Prior) -> None:
        c = self.config
        P = np.zeros((5, 5))
        P[:3, :3] = prior.covariance
        P[V, V], P[OMEGA, OMEGA] = c.initial_v_sigma_mps ** 2, c.initial_omega_sigma_radps ** 2
        # t: the state's time; u: the last IMU input (held until the next); t_enc: previous encoder read
        self._s: dict[str, Any] = {"x": np.concatenate([prior.world_xytheta_body, [0.0, 0.0]]), "P": P,
                                   "t": None, "u": np.zeros(2), "t_enc": None}
        # (stamp, event, state before it) of every input within the replay window, oldest first
        self._history: deque[tuple[float, Event, dict[str, Any]]] = deque()
        self._replayed = 0
        self._dropped = 0
        self._lidar_updates: list[float] = []

    # -- the late-event rule -------------------------------------------------------------------
    def _dispatch(self, event: Event) -> None:
        if not isinstance(event, (Imu, WheelEncoders, PoseFix)):
            self._ignored += 1
            return
        stamp = float(event.stamp_s)
        newest = self._history[-1][0] if self._history else -np.inf
        if stamp >= newest:
            self._apply_recorded(event)
            return
        if stamp < newest - self.config.replay_window_s:
            self._dropped += 1
            return
        k = bisect.bisect_right([h[0] for h in self._history], stamp)
        later = [self._history.pop() for _ in range(len(self._history) - k)][::-1]
        self._s = _copy_state(later[0][2])
        self._apply_recorded(event)
        for _, e, _ in later:
            self._apply_recorded(e)
        self._replayed += 1

    def _apply_recorded(self, event: Event) -> None:
        stamp = float(event.stamp_s)
        self._history.append((stamp, event, _copy_state(self._s)))
        while self._history[0][0] < stamp - self.config.replay_window_s:
            self._history.popleft()
        self._apply(event)

    # -- the maths -----------------------------------------------------------------------------
    def _apply(self, event: Event) -> None:
        s = self._s
        stamp = float(event.stamp_s)
        if s["t"] is None:
            s["t"] = stamp
        if isinstance(event, Imu):
            self._predict_to(stamp)
            s["u"] = np.array([float(event.accel_mps2[0]), float(event.gyro_radps[2])])
        elif isinstance(event, WheelEncoders):
            self._predict_to(stamp)
            previous, s["t_enc"] = s["t_enc"], stamp
            if previous is None or stamp <= previous:
                return  # the first reading only starts the clock
            z = WheelCalibration.required(self.calibration, self.name).rates(event, stamp - previous)
            self._update(z, s["x"][3:], H_ENCODERS, self._R_enc, wrap=False)
        else:
            self._predict_to(stamp)
            R = self._R_lidar
            if self.config.lidar_noise == "measured" and event.covariance is not None:
                R = np.asarray(event.covariance, dtype=float).reshape(3, 3)
            z = np.asarray(event.world_xytheta_body, dtype=float).reshape(3)
            self._update(z, s["x"][:3], H_POSE, R, wrap=True)
            self._lidar_updates.append(stamp)

    def _predict_to(self, stamp: float) -> None:
        s = self._s
        dt = stamp - s["t"]
        if dt <= 0.0:
            return
        c = self.config
        F, G = motion_jacobians(s["x"], s["u"], dt)
        Q = G @ np.diag([c.accel_sigma_mps2 ** 2, c.gyro_sigma_radps ** 2]) @ G.T
        Q[V, V] += c.v_random_walk ** 2 * dt
        Q[OMEGA, OMEGA] += c.omega_random_walk ** 2 * dt
        Q[[X, Y, THETA], [X, Y, THETA]] += np.square(c.pose_random_walk) * dt
        s["x"] = motion(s["x"], s["u"], dt)
        s["P"] = F @ s["P"] @ F.T + Q
        s["t"] = stamp

    def _update(self, z: np.ndarray, z_hat: np.ndarray, H: np.ndarray, R: np.ndarray, wrap: bool) -> None:
        s = self._s
        nu = z - z_hat
        if wrap:
            nu[2] = wrap_angle(nu[2])
        x, s["P"], nu, S = ekf_update(s["x"], s["P"], nu, np.zeros_like(nu), H, R)
        x[THETA] = wrap_angle(x[THETA])
        s["x"] = x
        self._record_nis(nu, S)

    def _pose_and_covariance(self) -> tuple[np.ndarray, np.ndarray]:
        return self._s["x"][:3].copy(), self._s["P"][:3, :3].copy()

    def _extras(self) -> dict[str, Any]:
        return {"late_replayed": self._replayed, "late_dropped": self._dropped,
                "lidar_update_stamps_s": np.array(self._lidar_updates)}

    def predicted_pose(self) -> np.ndarray:
        """The current pose estimate (x, y, theta), e.g. as the guess of a scan matcher."""
        if not self._ready:
            raise EstimationError(f"{self.name}: predicted_pose() before reset(prior)")
        return self._s["x"][:3].copy()


def _copy_state(s: Mapping[str, Any]) -> dict[str, Any]:
    return {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in s.items()}
