"""The navigation stack's orchestration (:class:`NavigationStack`): sensor events and a goal in,
velocity commands out. It owns localisation, perception and the local planner, the state they
share (the goal, the global path, the last command, the stack's clock) and the one prediction of
the tracks (:meth:`NavigationStack.local_world`), and hands each decision to the part
responsible for it (see the package docstring for which module holds what):

* :meth:`NavigationStack.step` -- Odometry: MCL prediction; Scan: MCL update, then obstacle
  detection (end points the map does not explain) and tracking;
* :meth:`NavigationStack.command` -- within the goal's approach radius the goal regulator
  (:mod:`.goal`), unless the safety guard (:mod:`.safety`) sees the robot about to be run into;
  otherwise replan when due, blocked or stuck (:mod:`.global_planning`, :mod:`.recovery`),
  recover while a recovery lasts, else the local planner's command on the (chance-tightened)
  local world, capped by yielding (:mod:`.yielding`) and the cruise speed, evaded, kept
  escapable and checked for a safe stop by the safety guard.

Each layer is timed per call (``timings_s``: ``localisation``, ``perception``,
``global_planner``, ``local_planner``).
"""

from __future__ import annotations

import math
import time
from typing import Mapping

import numpy as np

from slamkit.control.protocols import ControlOutput, ControlStatus, DistanceGrid, LocalWorld, Reference, RobotState
from slamkit.control.registry import make_controller
from slamkit.data.estimate import Estimate, Prior
from slamkit.data.noise import NoiseParams
from slamkit.data.sequence import Event, Odometry, Scan
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError
from slamkit.estimation.lidar_mcl import LidarMCL
from slamkit.estimation.obstacle_tracker import (ConstantVelocityTracker, ObstacleTracker, Tracks, cluster_points,
                                                 unexplained_points)
from slamkit.maps.distance_field import surface_distance_field_m
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.systems.navigation.command import CommandStatus, NavigationCommand, speed_capped
from slamkit.systems.navigation.config import NavigationConfig, default_controller_params
from slamkit.systems.navigation.global_planning import GlobalPlanning
from slamkit.systems.navigation.goal import GoalRegulator
from slamkit.systems.navigation.recovery import Recovery
from slamkit.systems.navigation.safety import SafetyGuard
from slamkit.systems.navigation.yielding import YieldDecision, Yielding

LAYERS = ("localisation", "perception", "global_planner", "local_planner")


class NavigationStack:
    """See the module docstring. ``grid`` is the static map the robot has (a map SLAM built or
    a ROS map); the lidar sits at the body origin. Its parts (``planning``, ``yielding``,
    ``safety``, ``regulator``, ``recovery``) read their sections of ``config`` through the stack,
    so a new ``config`` applies to all of them."""

    name = "navigation"

    def __init__(self, grid: OccupancyGrid, config: NavigationConfig = NavigationConfig(),
                 rng: np.random.Generator | None = None, tracker: ObstacleTracker | None = None):
        """``tracker``: the moving obstacles' tracker (default the constant-velocity one of
        ``config.tracker``; an ablation passes a privileged one)."""
        self.grid = grid
        self.config = config
        self.rng = rng if rng is not None else np.random.default_rng(0)
        c = config
        noise = NoiseParams(sigma_v_mps=c.odometry_sigma_v_mps, sigma_omega_radps=c.odometry_sigma_omega_radps)
        self.mcl = LidarMCL(grid, noise, c.mcl, self.rng)
        # what the local planner sees: the distance to the walls' surface (half a cell less than
        # to the occupied cells' centres), so its margins are real on a 10 cm map too
        self.distance = DistanceGrid(surface_distance_field_m(grid),
                                     grid.resolution_m, grid.origin_xy_m)
        self.tracker: ObstacleTracker = ConstantVelocityTracker(c.tracker) if tracker is None else tracker
        params = default_controller_params(c) if c.controller_params is None else c.controller_params
        self.controller = make_controller(c.controller, dict(params))
        self.planning = GlobalPlanning(self)
        self.yielding = Yielding(self)
        self.safety = SafetyGuard(self)
        self.regulator = GoalRegulator(self)
        self.recovery = Recovery(self)
        self._ready = False

    # ------------------------------------------------------------------ belief and goal
    def reset(self, world_xytheta_body: np.ndarray, covariance: np.ndarray) -> None:
        """Start from a Gaussian belief (the robot was put down at a known place)."""
        self.mcl.reset(Prior(np.asarray(world_xytheta_body, float), np.asarray(covariance, float)))
        self.tracker.reset()
        self.controller.reset()
        self.goal: np.ndarray | None = None
        self.path: np.ndarray | None = None
        self._last_cmd = np.zeros(2)
        self._t_s = 0.0
        self.timings_s: dict[str, list[float]] = {k: [] for k in LAYERS}
        self.last_scan_points = np.zeros((0, 2))
        for part in (self.planning, self.yielding, self.safety, self.regulator, self.recovery):
            part.reset()
        self._ready = True

    def set_goal(self, goal_xytheta: np.ndarray) -> None:
        self.goal = np.asarray(goal_xytheta, float).reshape(3).copy()
        self.path = None
        self.planning.last_plan_s = -math.inf
        self.regulator.phase = CommandStatus.DRIVING
        self.planning.searched_cost = None
        self.yielding.progress_reference_m = math.inf  # progress is towards this goal

    def current_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """(3,) estimated world_xytheta_body and its (3, 3) covariance."""
        return self.mcl._pose_and_covariance()

    def latest_estimate(self) -> Estimate:
        mean, cov = self.current_pose()
        return Estimate(trajectory=Trajectory.from_se2(np.array([self._t_s]), mean.reshape(1, 3)),
                        pose_covariances=cov.reshape(1, 3, 3))

    @property
    def particles(self) -> np.ndarray:
        return self.mcl.particles

    def tracks(self) -> Tracks:
        return self.tracker.tracks()

    # ------------------------------------------------------------------ what the parts share
    @property
    def now_s(self) -> float:
        """The stack's clock: the latest event or command time seen."""
        return self._t_s

    @property
    def last_command(self) -> np.ndarray:
        """(2,) the command sent last (v, omega): the yielding back-off and the safe stop start from it."""
        return self._last_cmd

    # ------------------------------------------------------------------ the parts' counters
    @property
    def reached(self) -> bool:
        """The stack believes it is at the goal pose (and sends zero)."""
        return self.regulator.reached

    @property
    def replans(self) -> int:
        return self.planning.replans

    @property
    def plan_expansions(self) -> list[int]:
        return self.planning.plan_expansions

    @property
    def chance_k(self) -> float:
        return self.planning.chance_k

    @property
    def chance_k_min(self) -> float:
        return self.planning.chance_k_min

    @property
    def chance_fallbacks(self) -> int:
        return self.planning.chance_fallbacks

    @property
    def planned_collision_probability_max(self) -> float:
        return self.planning.planned_collision_probability_max

    @property
    def narrowed_plans(self) -> int:
        return self.planning.narrowed_plans

    @property
    def bare_map_plans(self) -> int:
        return self.planning.bare_map_plans

    @property
    def recoveries(self) -> int:
        return self.recovery.recoveries

    @property
    def no_safe_stop_cycles(self) -> int:
        return self.safety.no_safe_stop_cycles

    def cell_cost(self, margin_cm: int) -> np.ndarray:
        """The global planner's cell costs (:meth:`GlobalPlanning.cell_cost`)."""
        return self.planning.cell_cost(margin_cm)

    def yield_decision(self, pose: np.ndarray, tracks: Tracks) -> YieldDecision:
        """Yielding's decision (:meth:`Yielding.decision`)."""
        return self.yielding.decision(pose, tracks)

    def safe_stop_exists(self, pose: np.ndarray, command: np.ndarray, world: LocalWorld,
                         dt_s: float = 0.1) -> bool:
        """The safe-stop check (:meth:`SafetyGuard.safe_stop_exists`)."""
        return self.safety.safe_stop_exists(pose, command, world, dt_s)

    # ------------------------------------------------------------------ events
    def step(self, event: Event) -> None:
        """Odometry -> MCL prediction; Scan -> MCL update, then obstacle detection and tracking.
        Other events are ignored."""
        if not self._ready:
            raise ConfigError("NavigationStack: reset() before step()")
        self._t_s = max(self._t_s, float(event.stamp_s))
        if isinstance(event, Odometry):
            t0 = time.perf_counter()
            self.mcl.step(event)
            self.timings_s["localisation"].append(time.perf_counter() - t0)
        elif isinstance(event, Scan):
            t0 = time.perf_counter()
            self.mcl.step(event)
            t1 = time.perf_counter()
            self.timings_s["localisation"].append(t1 - t0)
            pose, _ = self.current_pose()
            # a return from inside the robot's own disc is sensor noise (a short reading), not an
            # obstacle: nothing can be there without touching the robot (measured: such ghost
            # tracks made the robot evade backwards into a wall, Willow seed 4)
            ranges = np.where(np.asarray(event.ranges_m, float) < self.config.robot_radius_m, np.nan, event.ranges_m)
            pts = unexplained_points(pose, event.angles_rad, ranges, event.max_range_m,
                                     lambda p: self.distance.query(p)[0], self.config.detector.unexplained_m)
            self.last_scan_points = pts
            self.tracker.update(float(event.stamp_s), cluster_points(pts, pose[:2], self.config.detector))
            self.timings_s["perception"].append(time.perf_counter() - t1)

    # ------------------------------------------------------------------ control
    def command(self, t_s: float | None = None) -> NavigationCommand:
        """The velocity command for now (call at the control rate)."""
        if not self._ready:
            raise ConfigError("NavigationStack: reset() before command()")
        t = self._t_s if t_s is None else float(t_s)
        self._t_s = max(self._t_s, t)
        if self.goal is None:
            return self._send(np.zeros(2), CommandStatus.NO_GOAL)
        c = self.config
        pose, cov = self.current_pose()
        tracks = self.tracker.tracks()
        d_goal = float(np.linalg.norm(self.goal[:2] - pose[:2]))
        if self.regulator.engaged(d_goal):
            if not self.safety.threatened(pose, tracks, t):
                return self.regulator.regulate(pose, d_goal, tracks)
            return self.safety.escape(pose, tracks, t)
        block = self.planning.blocking_tracks(tracks)
        stuck = self.recovery.stuck(t)
        if self.path is None or t - self.planning.last_plan_s >= c.planning.replan_period_s or len(block) or stuck:
            if not self.planning.plan(pose, cov, tracks, block) and self.path is None:
                return self._send(np.zeros(2), CommandStatus.NO_PATH)
            if stuck:
                self.recovery.start(t)
        if self.recovery.active(t):
            return self.recovery.recover(pose, tracks)
        t0 = time.perf_counter()
        yielding = self.yielding.decision(pose, tracks)
        self.yielding.record_trail(pose, yielding.back_off_xy_m)
        world = self.local_world(tracks, t)
        if c.uncertainty != "fixed":
            world = self.planning.chance_world(world, pose, cov, tracks)
        v_yield = yielding.v_max_mps
        out = None
        if yielding.back_off_xy_m is not None:
            cmd = self.yielding.drive_to(pose, yielding.back_off_xy_m,
                                         self.yielding.back_off_aim(pose, yielding.back_off_xy_m))
        else:
            state = RobotState(pose, self._last_cmd, t)
            out = self.controller.compute(state, Reference(self.path, speed_mps=c.cruise_speed_mps), world)
            cmd = out.command
            if c.safety.evade and (out.status is ControlStatus.FALLBACK_BRAKE or self.safety.chosen_hits(world, out)):
                cmd = self.safety.evade(state, self.safety.turned_back_world(world, tracks)
                                        if c.safety.escape_reaction_s > 0 else world, out)
            cmd = speed_capped(cmd, min(c.cruise_speed_mps, v_yield))
            cmd, braked = self.safety.keep_escapable(pose, cmd, world, tracks)
            if braked:
                v_yield = min(v_yield, abs(float(cmd[0])))  # waiting for traffic, not stuck
        cmd, safe = self.safety.keep_safe_stop(pose, cmd, world)
        self.timings_s["local_planner"].append(time.perf_counter() - t0)
        self.recovery.watch(t, v_yield, out, cmd)
        if v_yield < c.cruise_speed_mps:
            status = CommandStatus.YIELDING
        else:
            status = CommandStatus.DRIVING if out.status is ControlStatus.OK else CommandStatus(out.status.value)
        return self._send(cmd, status, out, safe)

    def moving(self, tracks: Tracks, typical: bool = False) -> np.ndarray:
        """(K,) tracks moving faster than ``blocking_speed_mps`` (``typical``: now or typically --
        a track slowed down to turn is still traffic)."""
        speed = np.linalg.norm(tracks.velocity_mps, axis=1)
        if typical:
            speed = np.maximum(speed, tracks.speed_typical_mps)
        return speed >= self.config.blocking_speed_mps

    def local_world(self, tracks: Tracks, t_s: float = 0.0, hedges: tuple[float, float] | None = None,
                    turning: bool = False, wall_turn_horizon_s: float | None = None) -> LocalWorld:
        """What the local planner, the evasion, yielding and the safe-stop check see: the walls
        and every track, moving ones grown by ``moving_margin_m``, predicted with the hedge of
        ``prediction_hedge`` (``reversed_prediction_hedge`` for a track that has reversed
        before; ``hedges``: other values for the two) -- the stack's only prediction of the tracks.
        ``turning``: a track slower than its typical speed is turning or stopping, so its way on
        is unknown: the missing fraction of its typical speed, 1 - |v| / typical, is the least
        hedge it gets (a shuttler at its turn, |v| ~ 0, is predicted by its reachable set).
        A standing track may set off: its disc grows at ``standing_growth_mps`` up to
        ``standing_growth_max_m`` (unless its hedge grows it faster).
        A moving track whose prediction runs into a wall within ``wall_turn_horizon_s`` is also
        predicted turning back there (:meth:`wall_turns`; ``wall_turn_horizon_s``: another
        horizon than the config's): one more disc per such track, after the tracks' own
        (:meth:`moving_discs`)."""
        c = self.config
        moving = self.moving(tracks)
        plain, reversed_ = (c.prediction_hedge, c.reversed_prediction_hedge) if hedges is None else hedges
        lam = np.where(tracks.reversals > 0, reversed_, plain)
        speed_now = np.linalg.norm(tracks.velocity_mps, axis=1)
        speed = np.maximum(speed_now, tracks.speed_typical_mps)
        if turning:
            lam = np.maximum(lam, np.clip(1.0 - speed_now / np.maximum(speed, 1e-9), 0.0, 1.0))
        xy, radius = tracks.xy_m, tracks.radius_m + c.moving_margin_m * moving
        velocity, growth = (1.0 - lam)[:, None] * tracks.velocity_mps, lam * speed
        # a standing track grows at the larger of its hedge's rate (unlimited) and the standing rate
        # (limited): a shuttler slowed at its turn keeps yielding's reachable set
        standing = ~moving & (growth < c.standing_growth_mps)
        growth = np.where(standing, c.standing_growth_mps, growth)
        growth_max = np.where(standing, c.standing_growth_max_m, math.inf)
        world = LocalWorld(xy, radius, velocity, self.distance, t_s, growth, growth_max)
        k, t_wall = self.wall_turns(xy, velocity, tracks.radius_m, moving, wall_turn_horizon_s)
        # the turn back is the predicted path mirrored where it turns: a disc that starts as far
        # beyond that point as the track is before it and comes back at the same speed
        return world.with_copies(k, xy[k] + 2.0 * t_wall[:, None] * velocity[k], -velocity[k]) if len(k) else world

    def wall_turns(self, xy_m: np.ndarray, velocity_mps: np.ndarray, radius_m: np.ndarray,
                   moving: np.ndarray, horizon_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Which moving tracks' predicted paths run into a wall within ``horizon_s`` (default the
        config's ``wall_turn_horizon_s``) and when they turn: (indices (J,), times (J,) s).
        Running into a wall means the predicted centre gets within half the track's radius of it
        (a track walking along a wall does not count); it turns ``wall_turn_clearance_m`` short of
        touching it, measured along its way (exact for a wall across it; 0 for one that close
        already)."""
        c = self.config
        horizon_s = c.wall_turn_horizon_s if horizon_s is None else horizon_s
        k = np.flatnonzero(moving)
        if horizon_s <= 0 or len(k) == 0:
            return np.zeros(0, int), np.zeros(0)
        tau = np.arange(0.0, horizon_s + 1e-9, 0.05)
        path = xy_m[k][:, None, :] + tau[None, :, None] * velocity_mps[k][:, None, :]  # (J, T, 2)
        into = self.distance.query(path)[0] <= 0.5 * radius_m[k][:, None]
        hits = into.any(axis=1)
        speed = np.maximum(np.linalg.norm(velocity_mps[k], axis=1), 1e-9)
        t_turn = tau[np.argmax(into, axis=1)] - (0.5 * radius_m[k] + c.wall_turn_clearance_m) / speed
        return k[hits], np.maximum(t_turn[hits], 0.0)

    def moving_discs(self, tracks: Tracks, world: LocalWorld, typical: bool = False) -> np.ndarray:
        """(D,) which discs of ``world`` (:meth:`local_world` of ``tracks``) are moving traffic:
        the moving tracks' discs and every wall turn's (only moving tracks turn at walls)."""
        moving = self.moving(tracks, typical)
        return np.concatenate([moving, np.ones(world.num_circles - len(moving), bool)])

    def _send(self, cmd: np.ndarray, status: CommandStatus, output: ControlOutput | None = None,
              safe: bool = True) -> NavigationCommand:
        cmd = np.asarray(cmd, float).reshape(2).copy()
        self._last_cmd = cmd
        return NavigationCommand(cmd, status, output, safe)


def layer_timing_summary(timings_s: Mapping[str, list[float]]) -> dict[str, float]:
    """Median and p99 per layer in milliseconds: ``<layer>_median_ms``, ``<layer>_p99_ms``."""
    out = {}
    for layer, values in timings_s.items():
        v = np.asarray(values, float) * 1e3
        out[f"{layer}_median_ms"] = float(np.median(v)) if len(v) else 0.0
        out[f"{layer}_p99_ms"] = float(np.percentile(v, 99)) if len(v) else 0.0
    return out
