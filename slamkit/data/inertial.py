"""What an inertial sequence declares: the start navigation state, its uncertainty, the IMU and
GPS noise, gravity -- read once here for the error-state EKF and the GTSAM IMU smoothers, so both
assume the same numbers -- and the GPS-outage windows used to score runs without ground truth.

A sequence is inertial when ``metadata["inertial"]`` holds the mapping :func:`setup_to_metadata`
writes (the simulator ``slamkit.sim.inertial_world`` and the KITTI reader
``slamkit.data.formats.kitti_imu_gps`` do). Conventions:

* frames: ``world`` is a local level frame with z up, gravity ``gravity_mps2 = (0, 0, -g)``;
  the IMU frame is the body frame (no lever arm, no IMU-to-body rotation);
* an :class:`~slamkit.data.sequence.Imu` event at ``stamp_s`` holds the body rates and specific
  force held constant over the interval that *ends* at ``stamp_s`` (like ``Odometry``, and like the
  ``dt`` column of KITTI's file); a GPS fix is the world position of the body origin (3,);
* the navigation state is (world_p_body, world_v_body, world_R_body, accel bias, gyro bias); its
  uncertainty is given as standard deviations in the order (position, velocity, attitude as a
  world-frame rotation vector, accel bias, gyro bias) -- the 15-dimensional error state of
  :mod:`slamkit.estimation.eskf`.

:class:`InertialEventLoop` is the ``step(event)`` of every inertial estimator (the timing rule
above, input checks, counters), so the filter and the smoothers cannot drift apart on it.

GPS outages (:func:`withhold_gps`): every ``Gps`` event inside a window is removed from the
sequence and kept in ``metadata["withheld_gps"]`` (stamps, positions, window index), so a scorer
can measure the position error at the fixes no estimator saw.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from slamkit.data.sequence import Gps, Imu, Sequence, event_problem
from slamkit.errors import ConfigError, DataError, EstimationError
from slamkit.models.imu import ImuNoise

#: standard gravity (m/s^2); the KITTI example of GTSAM uses 9.8
STANDARD_GRAVITY_MPS2 = 9.80665


@dataclass(frozen=True)
class NavState:
    """A navigation state at ``stamp_s``: position, velocity, attitude and the IMU biases."""

    stamp_s: float
    world_p_body: np.ndarray
    world_v_body: np.ndarray
    world_R_body: np.ndarray
    accel_bias_mps2: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    gyro_bias_radps: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        for name, shape in (("world_p_body", (3,)), ("world_v_body", (3,)), ("world_R_body", (3, 3)),
                            ("accel_bias_mps2", (3,)), ("gyro_bias_radps", (3,))):
            value = np.array(getattr(self, name), dtype=float).reshape(shape)
            if not np.isfinite(value).all():
                raise DataError(f"NavState.{name} is not finite: {value.tolist()}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)


@dataclass(frozen=True)
class InertialSetup:
    """The start state and every noise an inertial estimator assumes (SI units).

    ``initial_sigma`` holds 15 standard deviations in the error-state order (position m,
    velocity m/s, attitude rad, accel bias m/s^2, gyro bias rad/s); ``gps_sigma_m`` the
    per-axis standard deviation of a fix (an event's own ``sigma_m`` wins when given)."""

    initial: NavState
    initial_sigma: np.ndarray
    imu_noise: ImuNoise
    gravity_mps2: np.ndarray = dataclasses.field(
        default_factory=lambda: np.array([0.0, 0.0, -STANDARD_GRAVITY_MPS2]))
    gps_sigma_m: float = 1.0

    def __post_init__(self) -> None:
        sigma = np.array(self.initial_sigma, dtype=float).reshape(-1)
        if sigma.shape != (15,) or not (np.isfinite(sigma).all() and (sigma > 0).all()):
            raise ConfigError(f"InertialSetup.initial_sigma must be 15 positive sigmas, got {sigma.tolist()}")
        g = np.array(self.gravity_mps2, dtype=float).reshape(3)
        if not (np.isfinite(self.gps_sigma_m) and self.gps_sigma_m > 0):
            raise ConfigError(f"InertialSetup.gps_sigma_m must be positive, got {self.gps_sigma_m}")
        object.__setattr__(self, "initial_sigma", sigma)
        object.__setattr__(self, "gravity_mps2", g)

    @property
    def initial_covariance(self) -> np.ndarray:
        return np.diag(self.initial_sigma**2)


def setup_to_metadata(setup: InertialSetup) -> dict[str, Any]:
    """The plain mapping stored as ``Sequence.metadata["inertial"]`` (lists, so it survives JSON)."""
    s = setup.initial
    return {
        "stamp_s": float(s.stamp_s), "world_p_body": s.world_p_body.tolist(),
        "world_v_body": s.world_v_body.tolist(), "world_R_body": s.world_R_body.tolist(),
        "accel_bias_mps2": s.accel_bias_mps2.tolist(), "gyro_bias_radps": s.gyro_bias_radps.tolist(),
        "initial_sigma": setup.initial_sigma.tolist(), "imu_noise": dataclasses.asdict(setup.imu_noise),
        "gravity_mps2": setup.gravity_mps2.tolist(), "gps_sigma_m": float(setup.gps_sigma_m),
    }


def is_inertial(sequence: Sequence) -> bool:
    return isinstance(sequence.metadata.get("inertial"), Mapping)


def setup_of(sequence: Sequence, **overrides: Any) -> InertialSetup:
    """The sequence's :class:`InertialSetup`; ``overrides`` (``imu_noise``: an ImuNoise or a
    mapping of its fields, ``gps_sigma_m``, ``initial_sigma``) replace what it declares."""
    raw = sequence.metadata.get("inertial")
    if not isinstance(raw, Mapping):
        raise DataError(f"sequence {sequence.name!r} is not inertial: metadata['inertial'] is missing")
    try:
        initial = NavState(raw["stamp_s"], raw["world_p_body"], raw["world_v_body"], raw["world_R_body"],
                           raw.get("accel_bias_mps2", np.zeros(3)), raw.get("gyro_bias_radps", np.zeros(3)))
        fields = {"initial": initial, "initial_sigma": raw["initial_sigma"],
                  "imu_noise": ImuNoise(**dict(raw["imu_noise"])),
                  "gravity_mps2": raw.get("gravity_mps2", (0.0, 0.0, -STANDARD_GRAVITY_MPS2)),
                  "gps_sigma_m": raw.get("gps_sigma_m", 1.0)}
    except KeyError as exc:
        raise DataError(f"sequence {sequence.name!r}: metadata['inertial'] lacks {exc}") from None
    for key, value in overrides.items():
        if value is None:
            continue
        if key == "imu_noise" and isinstance(value, Mapping):
            value = dataclasses.replace(fields["imu_noise"], **dict(value))
        if key not in fields or key == "initial":
            raise ConfigError(f"unknown inertial override {key!r}; known: imu_noise, gps_sigma_m, initial_sigma")
        fields[key] = value
    return InertialSetup(**fields)


# ---- GPS outages ---------------------------------------------------------------------------------

#: the most GPS outage windows one sequence may have (a drive of hours has a few hundred)
MAX_OUTAGE_WINDOWS = 10_000


def outage_windows(start_s: float, end_s: float, outage_s: float, gap_s: float,
                   first_after_s: float) -> np.ndarray:
    """(K, 2) windows [t0, t0 + outage_s) starting ``first_after_s`` after ``start_s``, separated
    by ``gap_s`` of GPS, all ending before ``end_s``."""
    if not (outage_s > 0 and gap_s >= 0 and first_after_s >= 0):
        raise ConfigError(f"outage windows need outage_s > 0, gap_s >= 0, first_after_s >= 0; got "
                          f"{outage_s}, {gap_s}, {first_after_s}")
    count = (end_s - outage_s - start_s - first_after_s) / (outage_s + gap_s)
    if count > MAX_OUTAGE_WINDOWS:  # outage_s 1e-9 with gap_s 0 asked for terabytes of windows
        raise ConfigError(f"outage_s {outage_s:g} and gap_s {gap_s:g} make {count:.3g} GPS outage windows in "
                          f"{end_s - start_s:g} s; at most {MAX_OUTAGE_WINDOWS} (lengthen outage_s or gap_s)")
    starts = np.arange(start_s + first_after_s, end_s - outage_s, outage_s + gap_s)
    return np.column_stack([starts, starts + outage_s]) if len(starts) else np.zeros((0, 2))


def withhold_gps(sequence: Sequence, windows: np.ndarray, name: str | None = None) -> Sequence:
    """``sequence`` without the GPS fixes inside ``windows`` (K, 2); the removed fixes go to
    ``metadata["withheld_gps"]`` = {stamps_s, world_p_body, window, windows_s}."""
    w = np.asarray(windows, dtype=float).reshape(-1, 2)
    kept, stamps, positions, index = [], [], [], []
    for e in sequence.events:
        if isinstance(e, Gps):
            inside = np.flatnonzero((w[:, 0] <= e.stamp_s) & (e.stamp_s < w[:, 1]))
            if len(inside):
                stamps.append(e.stamp_s)
                positions.append(np.asarray(e.world_p_body, dtype=float).reshape(-1))
                index.append(int(inside[0]))
                continue
        kept.append(e)
    metadata = dict(sequence.metadata)
    metadata["withheld_gps"] = {"stamps_s": np.array(stamps), "world_p_body": np.array(positions).reshape(-1, 3),
                                "window": np.array(index, dtype=int), "windows_s": w}
    return dataclasses.replace(sequence, name=name or sequence.name, events=tuple(kept), metadata=metadata)


# ---- the event loop of inertial estimators -------------------------------------------------------

class InertialEventLoop:
    """``step(event)`` for inertial estimators, one timing rule for the filter and the smoothers.

    An ``Imu`` reading is integrated over the interval from the previous reading (or the start
    state, or the last fix) to its stamp; a ``Gps`` fix stamped after the last reading first
    extends that reading to the fix (a late fix is applied as it is and counted); every other
    event is checked (``event_problem``) and ignored. Subclasses set ``name`` and ``_ready`` and
    implement ``_integrate(accel, gyro, dt)`` (which refuses non-finite readings), ``_after_imu()``
    and ``_fix(world_p_body (3,), sigma_m)``; :meth:`_start_loop` resets the clock and counters.
    """

    name = "inertial"
    #: longer intervals between IMU readings are still integrated but counted
    max_imu_gap_s = float("inf")

    def _start_loop(self, stamp_s: float) -> None:
        self.t = float(stamp_s)
        self._last: tuple[np.ndarray, np.ndarray] | None = None
        self._latency: list[float] = []
        self._counts = {"imu": 0, "gps": 0, "late_gps": 0, "imu_gaps": 0, "ignored_events": 0}

    def step(self, event) -> None:
        if not getattr(self, "_ready", False):
            raise EstimationError(f"{self.name}: step() called before reset(prior)")
        t0 = time.perf_counter()
        if isinstance(event, Imu):
            stamp = float(event.stamp_s)
            accel, gyro = event.accel_mps2, event.gyro_radps
            if not math.isfinite(stamp):
                raise EstimationError(f"{self.name}: Imu stamp {event.stamp_s!r} is not finite")
            dt = stamp - self.t
            if dt > 0:
                if dt > self.max_imu_gap_s:
                    self._counts["imu_gaps"] += 1
                self._integrate(accel, gyro, dt)
                self.t = stamp
            elif not (np.isfinite(accel).all() and np.isfinite(gyro).all()):
                raise EstimationError(f"{self.name}: Imu at t={stamp}: a reading is not finite")
            self._last = (accel, gyro)
            self._counts["imu"] += 1
            self._after_imu()
        else:
            problem = event_problem(event)
            if problem is not None:  # refused even when unused: the input contract of every estimator
                raise EstimationError(f"{self.name}: {type(event).__name__} at t={event.stamp_s}: {problem}")
            if isinstance(event, Gps):
                dt = float(event.stamp_s) - self.t
                if dt > 0 and self._last is not None:
                    self._integrate(*self._last, dt)
                    self.t = float(event.stamp_s)
                elif dt < 0:
                    self._counts["late_gps"] += 1
                self._fix(np.asarray(event.world_p_body, dtype=float).reshape(3), float(event.sigma_m))
                self._counts["gps"] += 1
            else:
                self._counts["ignored_events"] += 1
        self._latency.append(time.perf_counter() - t0)

    def _integrate(self, accel: np.ndarray, gyro: np.ndarray, dt: float) -> None:
        raise NotImplementedError

    def _after_imu(self) -> None:
        raise NotImplementedError

    def _fix(self, world_p_body: np.ndarray, sigma_m: float) -> None:
        raise NotImplementedError
