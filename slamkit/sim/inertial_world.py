"""Seeded 3D inertial scenarios: a car-like vehicle on rolling terrain with an IMU (white noise
plus bias random walk, :mod:`slamkit.models.imu`) and 3D GPS fixes, with ground truth.

The motion is defined by smooth body rates w(t) (yaw weaving, small pitch and roll oscillations)
and a forward speed profile s(t). The vehicle keeps its velocity along its body x axis: the true
specific force at step k is f = s'(t) e_x + w x v_body - R^T g, which makes d(v_body)/dt =
s'(t) e_x in continuous time. Ground truth is the strapdown integration of these noiseless
inputs with :func:`slamkit.models.strapdown.propagate` -- the zero-order-hold model every
slamkit inertial estimator (and GTSAM's preintegration) uses, so the estimators carry no
discretisation error and the NEES measures their consistency alone. Input k is held over
(t_{k-1}, t_k] and stamped t_k, the convention of :mod:`slamkit.data.inertial`.

GPS fixes (every ``1 / gps_rate_hz`` s, on IMU stamps) are the true position plus white
Gaussian noise of ``gps_sigma_m`` per axis (white, unlike the planar Gauss-Markov model of
:mod:`slamkit.models.gps`, so the filters' white-noise assumption holds and NEES can be judged).

The initial state the estimators receive is the truth perturbed by draws from ``initial_sigma``
(the same sigmas go into the sequence's :class:`~slamkit.data.inertial.InertialSetup`); the true
biases start as draws from the IMU preset's turn-on sigmas, or ``initial_bias_sigma`` when given.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from slamkit.data.inertial import InertialSetup, NavState, STANDARD_GRAVITY_MPS2, setup_to_metadata
from slamkit.data.sequence import Gps, Imu, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError
from slamkit.geometry import so3
from slamkit.models import strapdown
from slamkit.models.imu import ImuNoise, simulate_imu


@dataclass(frozen=True)
class InertialScenario:
    """A simulated inertial run (SI units). ``imu_preset`` names an :data:`IMU_PRESETS` entry."""

    name: str = "car3d"
    duration_s: float = 60.0
    imu_rate_hz: float = 100.0
    gps_rate_hz: float = 1.0
    gps_sigma_m: float = 0.5
    imu_preset: str = "consumer_mems"
    speed_mps: float = 8.0
    speed_amplitude_mps: float = 2.0
    yaw_rate_amplitude_radps: float = 0.15
    pitch_amplitude_rad: float = 0.05
    roll_amplitude_rad: float = 0.03
    #: start-state sigmas given to (and drawn for) the estimators: position, velocity, attitude
    initial_pose_sigma: tuple[float, float, float] = (0.5, 0.2, 0.02)
    #: sigmas of the estimators' bias prior (accel m/s^2, gyro rad/s); None: the preset's turn-on
    initial_bias_sigma: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        for name in ("duration_s", "imu_rate_hz", "gps_rate_hz", "gps_sigma_m"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ConfigError(f"InertialScenario.{name} must be positive, got {value}")
        if self.imu_rate_hz < self.gps_rate_hz:
            raise ConfigError("InertialScenario: the IMU rate must be at least the GPS rate")
        ImuNoise.preset(self.imu_preset)

    @property
    def imu_noise(self) -> ImuNoise:
        return ImuNoise.preset(self.imu_preset)

    @property
    def bias_sigma(self) -> tuple[float, float]:
        """(accel, gyro) sigma of the true initial bias and of the estimators' bias prior; a
        floor keeps the prior positive definite for presets without turn-on bias."""
        if self.initial_bias_sigma is not None:
            return tuple(float(s) for s in self.initial_bias_sigma)
        n = self.imu_noise
        return max(n.accel_bias_sigma, 1e-4), max(n.gyro_bias_sigma, 1e-6)


PRESETS: dict[str, Callable[..., InertialScenario]] = {
    # a car with a consumer MEMS IMU and a 0.5 m GPS at 1 Hz
    "car3d": lambda **kw: InertialScenario(**{"name": "car3d", **kw}),
    # the same drive with a tactical-grade IMU (fibre-optic gyro class)
    "car3d_tactical": lambda **kw: InertialScenario(**{"name": "car3d_tactical", "imu_preset": "tactical", **kw}),
}


def _body_rates(c: InertialScenario, t: np.ndarray) -> np.ndarray:
    """Smooth (N, 3) body rates: roll and pitch oscillate about level, yaw weaves."""
    wr = 2 * np.pi / 17.0
    wp = 2 * np.pi / 23.0
    roll_rate = c.roll_amplitude_rad * wr * np.cos(wr * t)
    pitch_rate = c.pitch_amplitude_rad * wp * np.cos(wp * t)
    yaw_rate = c.yaw_rate_amplitude_radps * (np.sin(2 * np.pi * t / 29.0) + 0.5 * np.sin(2 * np.pi * t / 11.0 + 1.0))
    return np.column_stack([roll_rate, pitch_rate, yaw_rate])


def _speed(c: InertialScenario, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    w = 2 * np.pi / 31.0
    return c.speed_mps + c.speed_amplitude_mps * np.sin(w * t), c.speed_amplitude_mps * w * np.cos(w * t)


def simulate_inertial_sequence(config: InertialScenario, rng: np.random.Generator) -> Sequence:
    """A seeded inertial :class:`Sequence` (see the module docstring). Metadata: ``inertial``
    (the :class:`InertialSetup`), ``true_imu_bias`` (stamps, accel, gyro biases per IMU event)."""
    c = config
    dt = 1.0 / c.imu_rate_hz
    n = int(round(c.duration_s * c.imu_rate_hz))
    stamps = np.arange(n + 1) * dt
    g = np.array([0.0, 0.0, -STANDARD_GRAVITY_MPS2])
    # inputs over (t_{k-1}, t_k], evaluated at the interval midpoint
    mid = stamps[1:] - 0.5 * dt
    gyro = _body_rates(c, mid)
    _, dspeed = _speed(c, mid)
    speed0, _ = _speed(c, np.zeros(1))
    p = np.zeros((n + 1, 3))
    v = np.zeros((n + 1, 3))
    R = np.zeros((n + 1, 3, 3))
    R[0] = so3.from_euler_zyx(0.3, 0.0, 0.0)
    v[0] = R[0] @ np.array([speed0[0], 0.0, 0.0])
    accel = np.zeros((n, 3))
    for k in range(n):  # a recurrence in time: the specific force depends on the current attitude
        v_body = R[k].T @ v[k]
        accel[k] = np.array([dspeed[k], 0.0, 0.0]) + np.cross(gyro[k], v_body) - R[k].T @ g
        p[k + 1], v[k + 1], R[k + 1] = strapdown.propagate(p[k], v[k], R[k], accel[k], gyro[k], dt, g)
    noise = c.imu_noise
    sigma_ba, sigma_bg = c.bias_sigma
    bias_a0 = rng.standard_normal(3) * sigma_ba
    bias_g0 = rng.standard_normal(3) * sigma_bg
    samples = simulate_imu(rng, gyro, accel, dt, noise, gyro_bias0_radps=bias_g0, accel_bias0_mps2=bias_a0)
    gps_every = int(round(c.imu_rate_hz / c.gps_rate_hz))
    gps_index = np.arange(gps_every, n + 1, gps_every)
    fixes = p[gps_index] + rng.standard_normal((len(gps_index), 3)) * c.gps_sigma_m
    sp, sv, sth = c.initial_pose_sigma
    sigma = np.concatenate([np.full(3, sp), np.full(3, sv), np.full(3, sth), np.full(3, sigma_ba),
                            np.full(3, sigma_bg)])
    start = NavState(0.0, p[0] + rng.standard_normal(3) * sp, v[0] + rng.standard_normal(3) * sv,
                     so3.exp(rng.standard_normal(3) * sth) @ R[0])
    setup = InertialSetup(start, sigma, noise, g, c.gps_sigma_m)
    events: list = [Imu(float(stamps[k + 1]), samples.gyro_radps[k], samples.accel_mps2[k]) for k in range(n)]
    events += [Gps(float(stamps[i]), fixes[j], c.gps_sigma_m) for j, i in enumerate(gps_index)]
    T = np.tile(np.eye(4), (n + 1, 1, 1))
    T[:, :3, :3] = R
    T[:, :3, 3] = p
    truth = Trajectory.from_matrices(stamps, T)
    metadata = {
        "inertial": setup_to_metadata(setup),
        "true_imu_bias": {"stamps_s": stamps[1:], "accel_mps2": samples.accel_bias_mps2,
                          "gyro_radps": samples.gyro_bias_radps},
        "world_v_body_truth": v,
        "scenario": dataclasses.asdict(c),
        "frames": "world: level, z up; body = IMU frame (x forward, y left, z up)",
    }
    return Sequence.from_events(c.name, events, ground_truth=truth, metadata=metadata)
