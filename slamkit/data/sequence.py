"""Sequences: timestamped sensor events plus ground truth, the input of every estimator.

Events are small frozen dataclasses; a ``Sequence`` iterates them in the order they were taken,
which is time order except where a recording's stamps are known to be late (a CARMEN log in log
order, ``metadata['event_order'] == 'log'``: slamkit.data.formats.carmen). Frames: all
body-frame quantities are in the robot body frame (x forward, y left); world quantities in
the world frame; angles in radians, distances in metres, times in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable, Iterator, Mapping

import numpy as np

from slamkit.data.trajectory import Trajectory
from slamkit.errors import EstimationError
from slamkit.maps.occupancy_grid import OccupancyGrid


@dataclass(frozen=True)
class Odometry:
    """Body-frame velocity command or odometry reading held over ``dt_s`` ending at ``stamp_s``."""

    stamp_s: float
    dt_s: float
    v_mps: float
    omega_radps: float


@dataclass(frozen=True)
class RangeBearing:
    """Range-bearing observations taken at ``stamp_s``; ``landmark_ids`` is -1 where unknown."""

    stamp_s: float
    landmark_ids: np.ndarray
    range_m: np.ndarray
    bearing_rad: np.ndarray


@dataclass(frozen=True)
class Range:
    """Range-only observations taken at ``stamp_s`` (ranging radios, UWB beacons): ``range_m[k]``
    is the distance from the body origin to landmark ``landmark_ids[k]`` (-1 where unknown)."""

    stamp_s: float
    landmark_ids: np.ndarray
    range_m: np.ndarray


@dataclass(frozen=True)
class Gps:
    stamp_s: float
    world_p_body: np.ndarray
    sigma_m: float


@dataclass(frozen=True)
class Imu:
    stamp_s: float
    gyro_radps: np.ndarray
    accel_mps2: np.ndarray


@dataclass(frozen=True)
class WheelEncoders:
    stamp_s: float
    ticks_left: int
    ticks_right: int


@dataclass(frozen=True)
class Scan:
    """A 2D lidar scan in the body frame: ``ranges_m`` is NaN where a beam returned nothing."""

    stamp_s: float
    angles_rad: np.ndarray
    ranges_m: np.ndarray
    max_range_m: float


Event = Odometry | RangeBearing | Range | Gps | Imu | WheelEncoders | Scan


def event_problem(event: Event) -> str | None:
    """What makes ``event`` unusable for an estimator (NaN or inf in a measurement, a negative
    or non-finite time step, a non-positive GPS sigma), or None. Checked at every ``step``, so it
    stays a handful of cheap tests; scans may hold NaN ranges (no return)."""
    if not np.isfinite(event.stamp_s):
        return f"stamp {event.stamp_s!r} is not finite"
    if isinstance(event, Odometry):
        if not (np.isfinite(event.dt_s) and event.dt_s >= 0):
            return f"dt_s={event.dt_s!r} must be finite and >= 0"
        if not (np.isfinite(event.v_mps) and np.isfinite(event.omega_radps)):
            return f"(v, omega) = ({event.v_mps!r}, {event.omega_radps!r}) is not finite"
    elif isinstance(event, RangeBearing):
        # a slightly negative range is what additive noise on a near landmark gives: allowed
        if not (np.isfinite(event.range_m).all() and np.isfinite(event.bearing_rad).all()):
            return "a range or bearing is not finite"
    elif isinstance(event, Range):
        if not np.isfinite(event.range_m).all():
            return "a range is not finite"
        if np.size(event.landmark_ids) != np.size(event.range_m):
            return f"{np.size(event.landmark_ids)} landmark_ids but {np.size(event.range_m)} ranges"
    elif isinstance(event, Gps):
        if not np.isfinite(event.world_p_body).all():
            return "the position is not finite"
        if not (np.isfinite(event.sigma_m) and event.sigma_m > 0):
            return f"sigma_m={event.sigma_m!r} must be finite and > 0"
    elif isinstance(event, Imu):
        if not (np.isfinite(event.gyro_radps).all() and np.isfinite(event.accel_mps2).all()):
            return "a gyro or accelerometer reading is not finite"
    return None


def check_event(event: Event, who: str) -> None:
    """An EstimationError naming ``who``, the event type and stamp when ``event_problem`` finds
    one (what every estimator's ``step`` checks first)."""
    problem = event_problem(event)
    if problem is not None:
        raise EstimationError(f"{who}: {type(event).__name__} at t={event.stamp_s}: {problem}")


def beam_angles_rad(angle_min_rad: float, increment_rad: float, n: int) -> np.ndarray:
    """The (n,) beam angles of an evenly spaced scan: angle_min + k increment, with both numbers
    rounded to float32 first -- the precision ``sensor_msgs/LaserScan`` carries -- so a scan
    built here survives a ROS bag round trip bit for bit (every reader of evenly spaced scans
    uses this one rule)."""
    return np.float64(np.float32(angle_min_rad)) + np.arange(int(n)) * np.float64(np.float32(increment_rad))


@dataclass(frozen=True)
class Sequence:
    """A named, finite, time-ordered run of events with optional ground truth.

    ``ground_truth`` is the true ``world_T_body`` at (at least) every event stamp that changes
    the robot state; ``world_p_landmarks`` maps landmark id to its true (x, y) when known.
    ``metadata`` carries units, frames and noise parameters (for example ``odometry_sigma``
    or ``range_bearing_sigma``) that estimators use as their noise models. ``occupancy_grid``
    is the world's map when the sequence comes with one (simulated grid worlds): what a robot
    localising against a known map is given, as ``world_p_landmarks`` is for landmark maps.
    """

    name: str
    events: tuple[Event, ...]
    ground_truth: Trajectory | None = None
    world_p_landmarks: Mapping[int, np.ndarray] | None = None
    initial_world_xytheta_body: np.ndarray | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)
    occupancy_grid: OccupancyGrid | None = None

    def __iter__(self) -> Iterator[Event]:
        return iter(self.events)

    def __len__(self) -> int:
        return len(self.events)

    @classmethod
    def from_events(cls, name: str, events: Iterable[Event], **kwargs) -> "Sequence":
        ordered = sorted(events, key=lambda e: e.stamp_s)
        return cls(name=name, events=tuple(ordered), **kwargs)

    def of_type(self, kind: type) -> list:
        return [e for e in self.events if isinstance(e, kind)]
