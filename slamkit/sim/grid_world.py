"""Occupancy-grid worlds: a differential-drive robot tours a generated office or warehouse (or
any ``OccupancyGrid``) and every sensor runs at its own rate.

Sensors and what each event means (all stamps on one clock starting at 0):

* ``Odometry`` at ``control_rate_hz``: the command (v, omega) held over the period ending at the
  stamp, plus Gaussian noise ``odometry_sigma`` (as in :mod:`slamkit.sim.landmark_world`).
* ``WheelEncoders`` at ``encoder.rate_hz``: tick increments of each wheel since the previous
  reading (``slamkit.models.encoders``), from the exact wheel angles
  phi_R = (s + l theta) / r, phi_L = (s - l theta) / r of the cumulative arc length s and
  unwrapped heading theta; ``diff_drive.odometry_from_ticks`` turns them back into motion.
  What the robot believes and the truth can differ (a calibration error and slip):
  ``wheel_radius_error`` makes the true radius r (1 + error) while the metadata states the nominal
  r (so an estimator reading ``wheel_radius_m`` is wrong by that factor), and during the slip
  windows (``slip_windows_s`` stated, plus ``slip_episodes`` windows of ``slip_duration_s`` drawn
  from the slip stream of ``rng``) each wheel turns (1 + ``slip_ratio_lr``) times what rolling
  over the ground needs; the windows are in ``metadata["truth"]``.
* ``Imu`` at ``imu_rate_hz``: body-frame gyro (0, 0, omega) and specific force
  (dv/dt over the sample interval, v omega, +g) with white noise and bias random walk
  (``slamkit.models.imu``); the initial biases are in the metadata.
* ``Scan`` at ``lidar.rate_hz``: ``lidar.num_beams`` beams over ``lidar.fov_rad`` centred on the
  body x axis, ray cast on the grid (``slamkit.maps.raycast``) and corrupted by the beam-model
  mixture (``slamkit.models.lidar.BeamModel``); no return (nothing within range, or a
  max-range reading from the mixture) is NaN.
* ``Gps`` at ``gps.rate_hz``: 2D antenna fixes with Gauss-Markov error (``slamkit.models.gps``).

Optional ``moving_obstacles`` (discs shuttling across the route, ``slamkit.sim.moving_obstacles``)
appear in the scans; their parameters are in ``metadata["moving_obstacles"]`` so their positions at
any stamp can be rebuilt with ``MovingObstacles(**...).position_at(t)``.

The robot visits ``num_goals`` random free places in turn along shortest routes on a 0.25 m
routing grid that keeps ``clearance_m`` from walls (Dijkstra, ``scipy.sparse.csgraph``), driven by
pure pursuit (:mod:`slamkit.sim.paths`). ``rng`` is split into independent streams (world, route,
odometry, encoders, IMU, lidar, GPS), so one seed gives one sequence, byte for byte.
"""

from __future__ import annotations

import dataclasses
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from slamkit.data.sequence import Event, Gps, Imu, Odometry, Scan, Sequence, WheelEncoders
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError
from slamkit.maps import generators, movingai
from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.maps.raycast import RayCaster, cast_circles
from slamkit.models import gps as gps_model
from slamkit.models.diff_drive import DiffDrive
from slamkit.models.encoders import Encoder
from slamkit.models.imu import ImuNoise, simulate_imu
from slamkit.models.lidar import BeamModel
from slamkit.sim import paths
from slamkit.sim.landmark_world import _plain
from slamkit.sim.moving_obstacles import MovingObstacles, crossing_obstacles
from slamkit.sim.ros_map import load_ros_map

GRAVITY_MPS2 = 9.81


@dataclass(frozen=True)
class Lidar:
    num_beams: int = 360
    fov_rad: float = float(2 * np.pi)
    max_range_m: float = 20.0
    rate_hz: float = 10.0
    #: mixture weights and hit sigma of the beam model used to corrupt ray-cast ranges
    beam_model: BeamModel = field(default_factory=lambda: BeamModel(
        z_hit=0.95, z_short=0.02, z_max=0.01, z_rand=0.02, sigma_hit_m=0.02, lambda_short=0.5))

    def angles_rad(self) -> np.ndarray:
        if self.fov_rad >= 2 * np.pi - 1e-12:
            return np.linspace(-np.pi, np.pi, self.num_beams, endpoint=False)
        return np.linspace(-0.5 * self.fov_rad, 0.5 * self.fov_rad, self.num_beams)


@dataclass(frozen=True)
class GridScenario:
    name: str = "office_tour"
    #: "office" or "warehouse" (generated from the world stream of ``rng``), or "file":
    #: ``map_file``, a ROS map_server YAML (.yaml/.yml) or a MovingAI .map
    world: str = "office"
    map_file: str | None = None
    #: cell size given to a MovingAI map (its cells are unit-less); ROS maps carry their own
    map_resolution_m: float = 0.5
    world_size_m: tuple[float, float] = (30.0, 30.0)
    world_resolution_m: float = 0.05
    num_goals: int = 4
    #: ``random``: goals drawn uniformly among the routing cells; ``spread``: a mapping tour --
    #: each goal the routing cell farthest (along the routes) from the start and the goals so far
    goal_choice: str = "random"
    clearance_m: float = 0.45
    duration_s: float = 120.0
    speed_mps: float = 0.8
    lookahead_m: float = 0.6
    max_omega_radps: float = 1.5
    control_rate_hz: float = 20.0
    odometry_sigma_v_mps: float = 0.02
    odometry_sigma_omega_radps: float = float(np.deg2rad(1.0))
    robot: DiffDrive = field(default_factory=lambda: DiffDrive())
    encoder: Encoder | None = field(default_factory=lambda: Encoder(ticks_per_rev=4096, rate_hz=500.0))
    imu_rate_hz: float | None = 200.0
    imu_noise: ImuNoise = field(default_factory=lambda: ImuNoise.preset("consumer_mems"))
    lidar: Lidar | None = field(default_factory=Lidar)
    gps: gps_model.Gps | None = field(default_factory=lambda: gps_model.Gps(sigma_m=2.5, rate_hz=1.0))
    #: discs shuttling across the route (``slamkit.sim.moving_obstacles``) that the lidar sees;
    #: the robot does not avoid them (dynamic clutter for estimation, not a planning test)
    moving_obstacles: int = 0
    #: relative error of the wheel radius the robot believes: the true radius is
    #: robot.wheel_radius_m (1 + wheel_radius_error), the ticks come from it (see module doc)
    wheel_radius_error: float = 0.0
    #: stated slip windows (start, end) in seconds, and the number and length of random ones
    slip_windows_s: tuple[tuple[float, float], ...] = ()
    slip_episodes: int = 0
    slip_duration_s: float = 2.0
    #: during slip each wheel (left, right) turns (1 + ratio) times the rolling rate
    slip_ratio_lr: tuple[float, float] = (0.10, 0.05)

    def __post_init__(self) -> None:
        if self.world not in ("office", "warehouse", "file"):
            raise ConfigError(f"GridScenario.world: unknown world {self.world!r} (office, warehouse, file)")
        if (self.world == "file") != (self.map_file is not None):
            raise ConfigError("GridScenario: world 'file' and map_file go together")
        for name in ("control_rate_hz", "duration_s", "speed_mps", "world_resolution_m"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"GridScenario.{name} must be > 0, got {getattr(self, name)}")
        if self.goal_choice not in ("random", "spread"):
            raise ConfigError(f"GridScenario.goal_choice: {self.goal_choice!r} (random, spread)")
        if self.num_goals < 1:
            raise ConfigError(f"GridScenario.num_goals must be >= 1, got {self.num_goals}")
        if not self.wheel_radius_error > -1.0:
            raise ConfigError(f"GridScenario.wheel_radius_error must be > -1, got {self.wheel_radius_error}")
        if any(not 0.0 <= a < b for a, b in self.slip_windows_s):
            raise ConfigError(f"GridScenario.slip_windows_s: each window needs 0 <= start < end, "
                              f"got {self.slip_windows_s}")
        if self.slip_episodes < 0 or not self.slip_duration_s > 0 or min(self.slip_ratio_lr) < 0:
            raise ConfigError("GridScenario: slip_episodes >= 0, slip_duration_s > 0 and slip_ratio_lr >= 0 "
                              f"needed, got {self.slip_episodes}, {self.slip_duration_s}, {self.slip_ratio_lr}")


def slip_windows(config: GridScenario, end_s: float, rng: np.random.Generator) -> np.ndarray:
    """(K, 2) slip windows (start, end) in seconds: the stated ones, then ``slip_episodes`` of
    ``slip_duration_s`` with starts uniform over the run (drawn from ``rng``)."""
    starts = rng.uniform(0.0, max(end_s - config.slip_duration_s, 0.0), config.slip_episodes)
    drawn = np.column_stack([starts, starts + config.slip_duration_s])
    return np.vstack([np.asarray(config.slip_windows_s, dtype=float).reshape(-1, 2), drawn])


def wheel_angles_rad(arc_m: np.ndarray, heading_rad: np.ndarray, stamps_s: np.ndarray, robot: DiffDrive,
                     radius_error: float, windows_s: np.ndarray, slip_ratio_lr) -> np.ndarray:
    """(N, 2) cumulative (left, right) wheel angles at ``stamps_s`` of a robot whose true wheel
    radius is ``robot.wheel_radius_m`` (1 + ``radius_error``), each interval whose midpoint lies in
    a slip window turned (1 + ``slip_ratio_lr``) times further than rolling needs."""
    r, l = robot.wheel_radius_m * (1.0 + radius_error), robot.half_axle_m
    angles = np.column_stack([(arc_m - l * heading_rad) / r, (arc_m + l * heading_rad) / r])
    if len(windows_s) == 0 or len(stamps_s) < 2:
        return angles
    mid = 0.5 * (stamps_s[1:] + stamps_s[:-1])
    slipping = ((mid[:, None] >= windows_s[:, 0]) & (mid[:, None] < windows_s[:, 1])).any(axis=1)
    rate = np.diff(angles, axis=0)
    rate[slipping] *= 1.0 + np.asarray(slip_ratio_lr, dtype=float)
    return np.vstack([angles[:1], angles[0] + np.cumsum(rate, axis=0)])


def make_world(config: GridScenario, rng: np.random.Generator) -> OccupancyGrid:
    w, h = config.world_size_m
    if config.world == "file":
        path = Path(str(config.map_file))
        if path.suffix in (".yaml", ".yml"):
            return load_ros_map(path).grid
        if path.suffix == ".map":
            g = movingai.load_map(path)
            return OccupancyGrid(g.occupied, config.map_resolution_m, g.origin_xy_m, name=g.name)
        raise ConfigError(f"GridScenario.map_file: {path} is neither a ROS map YAML nor a MovingAI .map")
    if config.world == "office":
        return generators.office(rng, generators.OfficeConfig(width_m=w, height_m=h,
                                                              resolution_m=config.world_resolution_m))
    return generators.warehouse(rng, generators.WarehouseConfig(width_m=w, height_m=h,
                                                                resolution_m=config.world_resolution_m))


# ---------------------------------------------------------------------------------------------
# Routing


def route(grid: OccupancyGrid, rng: np.random.Generator, num_goals: int, clearance_m: float,
          cell_m: float = 0.25, goal_choice: str = "random") -> np.ndarray:
    """(K, 2) waypoints: a start and ``num_goals`` goals among routing cells that keep
    ``clearance_m`` from obstacles, joined by shortest 8-connected routes (Dijkstra). Goals are
    drawn uniformly (``random``) or, after a random start, each is the cell farthest along the
    routes from the start and the goals before it (``spread``: farthest-point sampling, so a
    few goals reach every room), visited nearest first."""
    factor = max(1, int(round(cell_m / grid.resolution_m)))
    dist = distance_field_m(grid)
    h, w = (grid.height // factor) * factor, (grid.width // factor) * factor
    # a routing cell is usable when every fine cell inside it keeps the clearance
    coarse = dist[:h, :w].reshape(h // factor, factor, w // factor, factor).min(axis=(1, 3))
    ok = coarse > clearance_m
    # keep the largest connected region so every goal is reachable
    from scipy import ndimage

    labels, n = ndimage.label(ok, structure=np.ones((3, 3)))
    if n == 0:
        raise ConfigError(f"no free space with clearance {clearance_m} m in {grid.name!r}")
    biggest = np.argmax(np.bincount(labels.ravel())[1:]) + 1
    ok = labels == biggest
    ch, cw = ok.shape
    node = -np.ones(ok.shape, dtype=np.int64)
    iy, ix = np.nonzero(ok)
    node[iy, ix] = np.arange(len(iy))
    rows, cols, costs = [], [], []
    padded = np.pad(node, 1, constant_values=-1)  # neighbours outside the grid are not nodes
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        nb = padded[1 + dy:1 + dy + ch, 1 + dx:1 + dx + cw]
        both = (node >= 0) & (nb >= 0)
        rows.append(node[both])
        cols.append(nb[both])
        costs.append(np.full(int(both.sum()), np.hypot(dx, dy)))
    r, c, d = np.concatenate(rows), np.concatenate(cols), np.concatenate(costs)
    graph = coo_matrix((np.concatenate([d, d]), (np.concatenate([r, c]), np.concatenate([c, r]))),
                       shape=(len(iy), len(iy))).tocsr()
    if goal_choice == "spread":
        picks = _spread_goals(graph, int(rng.integers(len(iy))), num_goals)
    else:
        picks = rng.choice(len(iy), size=num_goals + 1, replace=len(iy) < num_goals + 1)
    centres = grid.origin_xy_m + (np.column_stack([ix, iy]) + 0.5) * factor * grid.resolution_m
    pts = [centres[picks[0]]]
    for a, b in zip(picks[:-1], picks[1:]):
        _, pred = dijkstra(graph, indices=int(a), return_predecessors=True)
        chain = [int(b)]
        while chain[-1] != a and pred[chain[-1]] >= 0:
            chain.append(int(pred[chain[-1]]))
        pts.extend(centres[chain[::-1][1:]])
    return np.asarray(pts)


def _spread_goals(graph, start: int, num_goals: int) -> list[int]:
    """Farthest-point sampling along the routes from ``start``, then the goals reordered into a
    nearest-neighbour tour from the start (the route distances of the graph)."""
    chosen = [start]
    nearest = dijkstra(graph, indices=start)
    for _ in range(num_goals):
        far = int(np.argmax(np.where(np.isfinite(nearest), nearest, -1.0)))
        if nearest[far] <= 0.0:
            break
        chosen.append(far)
        nearest = np.minimum(nearest, dijkstra(graph, indices=far))
    dist = dijkstra(graph, indices=chosen)[:, chosen]
    order, left = [0], set(range(1, len(chosen)))
    while left:
        nxt = min(left, key=lambda j: dist[order[-1], j])
        order.append(nxt)
        left.remove(nxt)
    return [chosen[i] for i in order]


# ---------------------------------------------------------------------------------------------
# Simulation


def _stamps(rate_hz: float, end_s: float) -> np.ndarray:
    n = int(np.floor(end_s * rate_hz + 1e-9))
    return np.arange(1, n + 1) / rate_hz


def simulate_grid_sequence(config: GridScenario, rng: np.random.Generator,
                           grid: OccupancyGrid | None = None) -> tuple[Sequence, OccupancyGrid]:
    """One seeded tour of ``config`` (or of ``grid`` when given). Returns the sequence and the map."""
    # a ninth stream (slip) leaves the first eight, and so every older sequence, unchanged
    world_rng, route_rng, odo_rng, enc_rng, imu_rng, lidar_rng, gps_rng, obs_rng, slip_rng = rng.spawn(9)
    if grid is None:
        grid = make_world(config, world_rng)
    waypoints = route(grid, route_rng, config.num_goals, config.clearance_m, goal_choice=config.goal_choice)
    dt = 1.0 / config.control_rate_hz
    drive = paths.pure_pursuit(waypoints, False, config.duration_s, dt,
                               paths.PurePursuit(config.speed_mps, config.lookahead_m,
                                                 config.max_omega_radps), goal_tolerance_m=0.3)
    end_s = float(drive.stamps_s[-1])
    obstacles = MovingObstacles.empty()
    if config.moving_obstacles > 0:
        obstacles = crossing_obstacles(waypoints, config.moving_obstacles, obs_rng, grid,
                                       nominal_speed_mps=config.speed_mps)
        # random phases: the generator times obstacles to meet the robot, which would drive
        # through them here since this robot does not avoid anything
        obstacles = dataclasses.replace(obstacles, phase=obs_rng.uniform(0.0, 2.0, len(obstacles)))
    events: list[tuple[float, int, Event]] = []  # (stamp, priority, event): motion before sensing

    sigma_u = np.array([config.odometry_sigma_v_mps, config.odometry_sigma_omega_radps])
    u_meas = drive.controls + odo_rng.standard_normal(drive.controls.shape) * sigma_u
    for k in range(len(drive.controls)):
        t = float(drive.stamps_s[k + 1])
        events.append((t, 0, Odometry(t, dt, float(u_meas[k, 0]), float(u_meas[k, 1]))))

    # cumulative arc length and unwrapped heading are piecewise linear in time
    def arc_and_heading(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k = np.clip(np.floor(t / dt + 1e-9).astype(np.int64), 0, len(drive.controls) - 1)
        s0 = np.concatenate([[0.0], np.cumsum(drive.controls[:, 0] * dt)])
        th0 = drive.world_xytheta_body[0, 2] + np.concatenate([[0.0], np.cumsum(drive.controls[:, 1] * dt)])
        tau = t - drive.stamps_s[k]
        return s0[k] + drive.controls[k, 0] * tau, th0[k] + drive.controls[k, 1] * tau

    metadata: dict = {
        "generator": "slamkit.sim.grid_world",
        "scenario": _plain(asdict(config)),
        "map": {"name": grid.name, "resolution_m": grid.resolution_m,
                "origin_xy_m": grid.origin_xy_m.tolist(), "shape": list(grid.shape)},
        "motion_model": "diff_drive_arc",
        "odometry_rate_hz": config.control_rate_hz,
        "odometry_sigma": sigma_u.tolist(),
        "odometry_covariance": np.diag(sigma_u**2).tolist(),
        "units": "SI (m, s, rad)",
        "frames": "world fixed; body x forward, y left, z up; lidar and IMU at the body origin",
    }

    if config.encoder is not None and len(drive.controls):
        enc = config.encoder
        t = np.concatenate([[0.0], _stamps(enc.rate_hz, end_s)])
        s, th = arc_and_heading(t)
        r, l = config.robot.wheel_radius_m, config.robot.half_axle_m
        windows = slip_windows(config, end_s, slip_rng)
        angles = wheel_angles_rad(s, th, t, config.robot, config.wheel_radius_error, windows,
                                  config.slip_ratio_lr)  # left, right
        inc = enc.interval_ticks(enc_rng, angles)
        for ti, (dl, dr) in zip(t[1:], inc):
            events.append((float(ti), 1, WheelEncoders(float(ti), int(dl), int(dr))))
        metadata.update(encoder_rate_hz=enc.rate_hz, encoder_ticks_per_rev=enc.ticks_per_rev,
                        encoder_ticks="increments since the previous reading",
                        wheel_radius_m=r, half_axle_m=l)
        if config.wheel_radius_error or len(windows):
            # what the robot does not know: estimators must not read this
            metadata["truth"] = {"wheel_radius_m": r * (1.0 + config.wheel_radius_error),
                                 "slip_windows_s": windows.tolist(),
                                 "slip_ratio_lr": list(config.slip_ratio_lr)}

    if config.imu_rate_hz and len(drive.controls):
        dti = 1.0 / config.imu_rate_hz
        t = _stamps(config.imu_rate_hz, end_s)
        vw = drive.body_velocity_at(t - 0.5 * dti)  # command in force over each sample interval
        v_prev = drive.body_velocity_at(np.maximum(t - dti, 0.0) - 1e-9)[:, 0]
        v_prev[t - dti < 1e-12] = 0.0  # the robot starts at rest
        v_now = drive.body_velocity_at(t - 1e-9)[:, 0]
        gyro_true = np.column_stack([np.zeros(len(t)), np.zeros(len(t)), vw[:, 1]])
        accel_true = np.column_stack([(v_now - v_prev) / dti, vw[:, 0] * vw[:, 1],
                                      np.full(len(t), GRAVITY_MPS2)])
        samples = simulate_imu(imu_rng, gyro_true, accel_true, dti, config.imu_noise)
        for i, ti in enumerate(t):
            events.append((float(ti), 1, Imu(float(ti), samples.gyro_radps[i], samples.accel_mps2[i])))
        metadata.update(imu_rate_hz=config.imu_rate_hz, imu_noise=_plain(asdict(config.imu_noise)),
                        imu_initial_gyro_bias_radps=samples.gyro_bias_radps[0].tolist(),
                        imu_initial_accel_bias_mps2=samples.accel_bias_mps2[0].tolist(),
                        gravity_mps2=GRAVITY_MPS2)

    if config.lidar is not None:
        lid = config.lidar
        t = np.concatenate([[0.0], _stamps(lid.rate_hz, end_s)])
        poses = drive.pose_at(t)
        beams = lid.angles_rad()
        expected = RayCaster(grid).scan(poses, beams, lid.max_range_m)
        if len(obstacles):
            for i, ti in enumerate(t):
                dyn = cast_circles(np.repeat(poses[i:i + 1, :2], len(beams), axis=0),
                                   poses[i, 2] + beams, obstacles.position_at(float(ti)),
                                   obstacles.radius_m, lid.max_range_m)
                expected[i] = np.fmin(expected[i], dyn)
        no_return = np.isnan(expected)
        noisy = lid.beam_model.sample(lidar_rng, np.where(no_return, lid.max_range_m, expected),
                                      lid.max_range_m)
        noisy = np.where(no_return | (noisy >= lid.max_range_m), np.nan, noisy)
        beams_ro = beams.copy()
        beams_ro.setflags(write=False)
        for i, ti in enumerate(t):
            events.append((float(ti), 1, Scan(float(ti), beams_ro, noisy[i], lid.max_range_m)))
        metadata.update(lidar_rate_hz=lid.rate_hz, lidar_num_beams=lid.num_beams,
                        lidar_fov_rad=lid.fov_rad, lidar_max_range_m=lid.max_range_m,
                        lidar_beam_model=_plain(asdict(lid.beam_model)))

    if config.gps is not None:
        g = config.gps
        t = _stamps(g.rate_hz, end_s)
        if len(t):
            fixes = g.simulate_fixes(gps_rng, drive.pose_at(t), t)
            for ti, fix in zip(t, fixes):
                events.append((float(ti), 1, Gps(float(ti), fix, g.sigma_m)))
        metadata.update(gps_rate_hz=g.rate_hz, gps_sigma_m=g.sigma_m,
                        gps_body_p_antenna=list(g.body_p_antenna),
                        gps_correlation_time_s=g.correlation_time_s)

    if len(obstacles):
        metadata["moving_obstacles"] = {
            "a_xy_m": obstacles.a_xy_m.tolist(), "b_xy_m": obstacles.b_xy_m.tolist(),
            "speed_mps": obstacles.speed_mps.tolist(), "radius_m": obstacles.radius_m.tolist(),
            "phase": obstacles.phase.tolist()}

    # stable order: by stamp, motion (odometry) before the sensors read at the same stamp, then
    # by kind in insertion order
    events.sort(key=lambda e: (e[0], e[1]))
    gt = Trajectory.from_se2(drive.stamps_s, drive.world_xytheta_body)
    seq = Sequence(name=config.name, events=tuple(e for _, _, e in events), ground_truth=gt,
                   world_p_landmarks=None, initial_world_xytheta_body=drive.world_xytheta_body[0].copy(),
                   metadata=metadata, occupancy_grid=grid)
    return seq, grid


def mapping_tour(truth: OccupancyGrid, num_goals: int, clearance_m: float, duration_s: float, speed_mps: float,
                 rng: np.random.Generator, name: str = "mapping_tour") -> Sequence:
    """A seeded mapping tour of ``truth`` (the sequence a robot's map is built from by SLAM,
    :func:`slamkit.systems.slam_map.slam_map`): ``num_goals`` goals spread over the free space
    (farthest-point sampling along the routes, :func:`route` with ``goal_choice="spread"``),
    joined by shortest routes ``clearance_m`` from walls, driven by pure pursuit for at most
    ``duration_s`` at ``speed_mps``; lidar and noisy wheel odometry only (no encoder ticks, IMU
    or GPS)."""
    tour = GridScenario(name=name, num_goals=num_goals, goal_choice="spread", clearance_m=clearance_m,
                        duration_s=duration_s, speed_mps=speed_mps, encoder=None, imu_rate_hz=None, gps=None)
    return simulate_grid_sequence(tour, rng, grid=truth)[0]
