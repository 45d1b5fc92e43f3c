"""Landmark worlds: a differential-drive robot drives a loop, a figure eight, random waypoints
or a velocity profile through a field of point landmarks; it reads noisy odometry and
range-bearing observations with known (or hidden) landmark ids.

What the estimators are promised (``Sequence.metadata``, all SI):

* ``odometry_sigma`` = [sigma_v_mps, sigma_omega_radps]: each ``Odometry`` event carries the
  true command held over ``dt_s`` plus independent zero-mean Gaussian noise with these standard
  deviations, so the control covariance is M = diag(sigma_v^2, sigma_omega^2) and the true
  motion is exactly ``slamkit.models.diff_drive.motion(x, u_true, dt_s)`` (``odometry_covariance``
  gives M).
* ``range_bearing_sigma`` = [sigma_range_m, sigma_bearing_rad]: additive Gaussian noise on
  range and bearing (R = diag of their squares), observed within ``range_bearing_max_range_m``
  and ``range_bearing_fov_rad`` (centred on the body x axis), each landmark dropped with
  probability ``range_bearing_dropout``. Ids are -1 when ``known_correspondences`` is false.
* ``initial_pose_sigma``: the prior on ``initial_world_xytheta_body`` (the true start pose).
* Optional ``Gps`` fixes (``gps_sigma_m`` per axis, ``gps_rate_hz``) when the scenario has ``gps``.
* Event order: at a stamp where both occur, the ``Odometry`` that ends there comes before the
  ``RangeBearing`` taken there (predict, then update). Ground truth holds the true pose at every
  control stamp, which includes every event stamp.

Randomness: ``rng`` is split (``Generator.spawn``) into independent streams for the world, the
odometry noise and the landmark sensor, so changing one sensor's settings does not change the
others' noise; one seed always gives the same sequence.

The "mildly nonlinear" preset keeps the heading uncertainty small between observations, where
an EKF's linearisation is good; the "strongly nonlinear" one has large heading noise, sparse
landmarks, a narrow field of view and dropouts, where linearisation errors make the EKF
overconfident (Bailey et al., "Consistency of the EKF-SLAM algorithm", IROS 2006).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from slamkit.data.sequence import Event, Gps, Odometry, RangeBearing, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError
from slamkit.models.gps import Gps as GpsModel
from slamkit.models.range_bearing import RangeBearingSensor
from slamkit.sim import paths


# ---------------------------------------------------------------------------------------------
# Landmark fields


def uniform_landmarks(rng: np.random.Generator, num: int,
                      extent_m: tuple[float, float, float, float]) -> np.ndarray:
    """(num, 2) landmarks uniform in (xmin, xmax, ymin, ymax)."""
    xmin, xmax, ymin, ymax = extent_m
    return rng.uniform([xmin, ymin], [xmax, ymax], size=(num, 2))


def clustered_landmarks(rng: np.random.Generator, num: int,
                        extent_m: tuple[float, float, float, float], num_clusters: int,
                        cluster_sigma_m: float) -> np.ndarray:
    """(num, 2) landmarks in Gaussian clusters whose centres are uniform in the extent
    (tree stands, furniture groups): the density varies, so some stretches see few landmarks."""
    centres = uniform_landmarks(rng, max(1, num_clusters), extent_m)
    which = rng.integers(0, len(centres), size=num)
    return centres[which] + cluster_sigma_m * rng.standard_normal((num, 2))


# ---------------------------------------------------------------------------------------------
# Scenario


@dataclass(frozen=True)
class LandmarkScenario:
    name: str = "landmark_loop"
    #: "loop" (stadium), "circle", "figure_eight", "random_waypoints" or "profile"
    path: str = "loop"
    #: loop: (length, width); circle: diameter = size[0]; figure_eight: span = size[0];
    #: random_waypoints: the extent (width, height) centred on the origin
    path_size_m: tuple[float, float] = (20.0, 12.0)
    num_waypoints: int = 8
    #: for path = "profile": (duration_s, v_mps, omega_radps) segments
    profile: tuple[tuple[float, float, float], ...] = ()
    duration_s: float = 120.0
    speed_mps: float = 1.0
    lookahead_m: float = 2.0
    max_omega_radps: float = 1.0
    #: "uniform" or "clustered"
    landmarks: str = "uniform"
    num_landmarks: int = 40
    #: the landmark field covers the path's bounding box grown by this margin
    landmark_margin_m: float = 4.0
    num_clusters: int = 6
    cluster_sigma_m: float = 1.5
    odometry_rate_hz: float = 10.0
    odometry_sigma_v_mps: float = 0.05
    odometry_sigma_omega_radps: float = float(np.deg2rad(2.0))
    sensor: RangeBearingSensor = field(default_factory=lambda: RangeBearingSensor(
        sigma_range_m=0.1, sigma_bearing_rad=float(np.deg2rad(1.0)), fov_rad=float(2 * np.pi),
        max_range_m=8.0, dropout_prob=0.0, rate_hz=10.0))
    known_correspondences: bool = True
    initial_pose_sigma: tuple[float, float, float] = (1e-3, 1e-3, 1e-3)
    #: optional GNSS fixes (``slamkit.models.gps.Gps``: sigma, rate, lever arm, correlation)
    gps: GpsModel | None = None

    def __post_init__(self) -> None:
        if self.path not in ("loop", "circle", "figure_eight", "random_waypoints", "profile"):
            raise ConfigError(f"LandmarkScenario.path: unknown path {self.path!r}")
        if self.landmarks not in ("uniform", "clustered"):
            raise ConfigError(f"LandmarkScenario.landmarks: unknown layout {self.landmarks!r}")
        if self.path == "profile" and not self.profile:
            raise ConfigError("LandmarkScenario.profile: path 'profile' needs segments")
        if not self.odometry_rate_hz > 0:
            raise ConfigError(f"LandmarkScenario.odometry_rate_hz must be > 0, got {self.odometry_rate_hz}")
        ratio = self.odometry_rate_hz / self.sensor.rate_hz
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ConfigError("LandmarkScenario.sensor.rate_hz must divide odometry_rate_hz "
                              f"(observations are taken at control stamps), got {self.sensor.rate_hz} "
                              f"and {self.odometry_rate_hz}")
        if self.odometry_sigma_v_mps < 0 or self.odometry_sigma_omega_radps < 0:
            raise ConfigError("LandmarkScenario odometry sigmas must be >= 0")
        if self.num_landmarks < 0:
            raise ConfigError(f"LandmarkScenario.num_landmarks must be >= 0, got {self.num_landmarks}")


def mildly_nonlinear(**overrides) -> LandmarkScenario:
    """A stadium loop in a dense uniform field: small heading noise, 360 degree sensing."""
    return LandmarkScenario(**{"name": "landmark_mild", **overrides})


def strongly_nonlinear(**overrides) -> LandmarkScenario:
    """Large heading noise, sparse clustered landmarks, a 120 degree field of view, short range,
    noisy bearings and dropouts: the heading uncertainty grows large between sightings."""
    base = dict(
        name="landmark_strong", path="figure_eight", path_size_m=(24.0, 12.0), landmarks="clustered",
        num_landmarks=20, num_clusters=5, cluster_sigma_m=2.0, odometry_sigma_v_mps=0.1,
        odometry_sigma_omega_radps=float(np.deg2rad(15.0)),
        sensor=RangeBearingSensor(sigma_range_m=0.2, sigma_bearing_rad=float(np.deg2rad(3.0)),
                                  fov_rad=float(np.deg2rad(120.0)), max_range_m=8.0,
                                  dropout_prob=0.2, rate_hz=5.0),
    )
    return LandmarkScenario(**{**base, **overrides})


PRESETS = {"mild": mildly_nonlinear, "strong": strongly_nonlinear}


def _drive(config: LandmarkScenario, rng: np.random.Generator) -> paths.Drive:
    dt = 1.0 / config.odometry_rate_hz
    pp = paths.PurePursuit(config.speed_mps, config.lookahead_m, config.max_omega_radps)
    sx, sy = config.path_size_m
    if config.path == "profile":
        return paths.velocity_profile(list(config.profile), dt)
    if config.path == "loop":
        return paths.pure_pursuit(paths.rounded_rectangle(sx, sy, 0.35 * sy), True, config.duration_s, dt, pp)
    if config.path == "circle":
        return paths.pure_pursuit(paths.circle(0.5 * sx), True, config.duration_s, dt, pp)
    if config.path == "figure_eight":
        return paths.pure_pursuit(paths.figure_eight(sx), True, config.duration_s, dt, pp)
    pts = paths.random_waypoints(rng, config.num_waypoints, (-sx / 2, sx / 2, -sy / 2, sy / 2))
    return paths.pure_pursuit(pts, False, config.duration_s, dt, pp)


def simulate_landmark_sequence(config: LandmarkScenario, rng: np.random.Generator) -> Sequence:
    """One seeded run of ``config``: odometry and range-bearing events plus ground truth."""
    world_rng, odo_rng, rb_rng, gps_rng = rng.spawn(4)
    drive = _drive(config, world_rng)
    xy = drive.world_xytheta_body[:, :2]
    m = config.landmark_margin_m
    extent = (xy[:, 0].min() - m, xy[:, 0].max() + m, xy[:, 1].min() - m, xy[:, 1].max() + m)
    if config.landmarks == "uniform":
        lms = uniform_landmarks(world_rng, config.num_landmarks, extent)
    else:
        lms = clustered_landmarks(world_rng, config.num_landmarks, extent, config.num_clusters,
                                  config.cluster_sigma_m)
    ids = np.arange(len(lms), dtype=np.int64)

    dt = drive.dt_s
    sigma_u = np.array([config.odometry_sigma_v_mps, config.odometry_sigma_omega_radps])
    u_meas = drive.controls + odo_rng.standard_normal(drive.controls.shape) * sigma_u
    every = int(round(config.odometry_rate_hz / config.sensor.rate_hz))

    events: list[Event] = []
    for k in range(len(drive.stamps_s)):
        t = float(drive.stamps_s[k])
        if k > 0:
            events.append(Odometry(t, dt, float(u_meas[k - 1, 0]), float(u_meas[k - 1, 1])))
        if k % every == 0:
            seen, r, b = config.sensor.measure(rb_rng, drive.world_xytheta_body[k], lms, ids)
            if not config.known_correspondences:
                seen = np.full(len(seen), -1, dtype=np.int64)
            events.append(RangeBearing(t, seen, r, b))

    if config.gps is not None and len(drive.controls):
        g = config.gps
        n = int(np.floor(drive.stamps_s[-1] * g.rate_hz + 1e-9))
        t = np.arange(1, n + 1) / g.rate_hz
        if n:
            fixes = g.simulate_fixes(gps_rng, drive.pose_at(t), t)
            gps_events = [Gps(float(ti), fix, g.sigma_m) for ti, fix in zip(t, fixes)]
            # after the odometry and observation at the same stamp (stable sort keeps that order)
            events = sorted(events + gps_events, key=lambda e: e.stamp_s)

    sensor = config.sensor
    metadata = {
        "generator": "slamkit.sim.landmark_world",
        "scenario": _plain(asdict(config)),
        "motion_model": "diff_drive_arc",
        "odometry_rate_hz": config.odometry_rate_hz,
        "odometry_sigma": [float(s) for s in sigma_u],
        "odometry_covariance": np.diag(sigma_u**2).tolist(),
        "range_bearing_rate_hz": sensor.rate_hz,
        "range_bearing_sigma": [sensor.sigma_range_m, sensor.sigma_bearing_rad],
        "range_bearing_max_range_m": sensor.max_range_m,
        "range_bearing_fov_rad": sensor.fov_rad,
        "range_bearing_dropout": sensor.dropout_prob,
        "known_correspondences": config.known_correspondences,
        "initial_pose_sigma": list(config.initial_pose_sigma),
        **({} if config.gps is None else {
            "gps_rate_hz": config.gps.rate_hz, "gps_sigma_m": config.gps.sigma_m,
            "gps_body_p_antenna": list(config.gps.body_p_antenna),
            "gps_correlation_time_s": config.gps.correlation_time_s}),
        "units": "SI (m, s, rad)",
        "frames": "world fixed; body x forward, y left; bearings from the body x axis",
    }
    return Sequence(
        name=config.name,
        events=tuple(events),
        ground_truth=Trajectory.from_se2(drive.stamps_s, drive.world_xytheta_body),
        world_p_landmarks={int(i): lms[i].copy() for i in ids},
        initial_world_xytheta_body=drive.world_xytheta_body[0].copy(),
        metadata=metadata,
    )


def _plain(value):
    """Dataclass dicts -> JSON-ready values (tuples to lists, numpy scalars to floats)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
