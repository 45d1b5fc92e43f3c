"""A world for closed-loop navigation: a seeded map (generated office or warehouse, or a ROS map
such as the real Willow Garage office), a start and a goal pose with a path between them, people
and a forklift crossing that path, and the plant: a differential drive that executes velocity
commands exactly (``slamkit.models.diff_drive.motion``) while its wheel odometry reports them with
Gaussian noise and its lidar sees the map and the moving discs (ray cast, then corrupted by the
beam-model mixture as in :mod:`slamkit.sim.grid_world`).

Start and goal draws (:func:`start_goal_draws`, :func:`passage_draws`) live here; they take the
route between the two poses from the caller's planner (``route``: this layer may not plan), and
:mod:`slamkit.experiments.navigation` (and local planning's scenarios) compose map, costmap,
planner and crossing traffic into a scenario. :meth:`NavigationPlant.kidnap` shifts the true
robot (the kidnapped-robot test).

``NavigationPlant.advance(command, dt)`` moves the truth and returns the odometry event of that
period; ``scan(t)`` the lidar event at the current pose. The truth is ``plant.world_xytheta_body``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import numpy as np

from slamkit.data.sequence import Odometry, Scan
from slamkit.errors import ConfigError
from slamkit.maps.generators import (OfficeConfig, PassageHallConfig, WarehouseConfig, office, passage_hall,
                                     random_free_poses, warehouse)
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.maps.raycast import RayCaster, cast_circles
from slamkit.models.diff_drive import motion
from slamkit.sim.grid_world import Lidar
from slamkit.sim.moving_obstacles import MovingObstacles
from slamkit.sim.ros_map import load_ros_map

WORLDS = ("office", "warehouse", "willow", "passage")


@dataclass(frozen=True)
class NavigationScenario:
    name: str
    seed: int
    grid: OccupancyGrid
    start_xytheta: np.ndarray
    goal_xytheta: np.ndarray
    #: the A* path the scenario was drawn with (the obstacles are timed to meet a robot on it)
    path_xy_m: np.ndarray
    #: shuttles, or people and forklifts of the social-force model
    #: (:class:`slamkit.sim.social_force.SocialForceAgents`): the same moving-disc interface
    obstacles: MovingObstacles


_MAP_CACHE: dict[tuple[str, str], OccupancyGrid] = {}


def world_map(kind: str, rng: np.random.Generator, willow_yaml: str | None = None,
              resolution_m: float = 0.05, size_m: float = 20.0) -> OccupancyGrid:
    """The map of a world kind: generated (drawn from ``rng``) or the Willow ROS map. ``passage``
    is a 12 m x 6 m hall whose partition has a narrow gap and a wide door (``size_m`` unused)."""
    if kind == "office":
        return office(rng, OfficeConfig(width_m=size_m, height_m=size_m, resolution_m=resolution_m), name="office")
    if kind == "warehouse":
        return warehouse(rng, WarehouseConfig(width_m=size_m, height_m=size_m, resolution_m=resolution_m,
                                              shelf_length_m=6.0, dock_depth_m=5.0, num_pallets=4),
                         name="warehouse")
    if kind == "passage":
        return passage_hall(rng, PassageHallConfig(resolution_m=resolution_m))
    if kind == "willow":
        if willow_yaml is None:
            raise ConfigError("world 'willow' needs the path of the Willow map YAML (maps_ros)")
        key = (kind, str(willow_yaml))
        if key not in _MAP_CACHE:
            _MAP_CACHE[key] = load_ros_map(willow_yaml).grid
        return _MAP_CACHE[key]
    raise ConfigError(f"unknown world {kind!r}; choose from {WORLDS}")


class NavigationPlant:
    """The robot and its sensors in ``scenario`` (see the module docstring)."""

    def __init__(self, scenario: NavigationScenario, rng: np.random.Generator, lidar: Lidar = Lidar(),
                 odometry_sigma_v_mps: float = 0.02, odometry_sigma_omega_radps: float = float(np.deg2rad(1.0)),
                 lidar_blind_boxes_m: np.ndarray | None = None, robot_radius_m: float = 0.2):
        self.scenario = scenario
        #: (B, 4) boxes (x_min, y_min, x_max, y_max): with the robot inside one the lidar returns
        #: nothing (glass, a featureless hall, a dropout): an odometry-only stretch
        self.blind_boxes_m = np.zeros((0, 4)) if lidar_blind_boxes_m is None else \
            np.asarray(lidar_blind_boxes_m, float).reshape(-1, 4)
        self.rng = rng
        self.lidar = lidar
        self.sigma = np.array([odometry_sigma_v_mps, odometry_sigma_omega_radps])
        self.caster = RayCaster(scenario.grid)
        self.beams = lidar.angles_rad()
        self.beams.setflags(write=False)
        self.world_xytheta_body = np.asarray(scenario.start_xytheta, float).copy()
        #: this episode's moving discs (people of the social-force model react to the robot, so
        #: each plant runs its own copy; shuttles are shared)
        self.obstacles = scenario.obstacles.episode()
        self._robot_radius_m = float(robot_radius_m)
        self.obstacles.observe_robot(0.0, self.world_xytheta_body[:2], self._robot_radius_m)
        #: the last scan's time, pose and noise-free ranges to the map alone (:meth:`discs_seen`)
        self._last_scan: tuple[float, np.ndarray, np.ndarray] | None = None

    def advance(self, command: np.ndarray, dt_s: float, t_end_s: float) -> Odometry:
        """Execute ``command`` (v, omega) for ``dt_s``; the odometry of that period ends at ``t_end_s``."""
        u = np.asarray(command, float).reshape(2)
        self.world_xytheta_body = motion(self.world_xytheta_body, u, dt_s)
        self.obstacles.observe_robot(float(t_end_s), self.world_xytheta_body[:2], self._robot_radius_m)
        noisy = u + self.sigma * self.rng.standard_normal(2)
        return Odometry(float(t_end_s), float(dt_s), float(noisy[0]), float(noisy[1]))

    def lidar_blind(self) -> bool:
        """Whether the robot is in a lidar blind box now."""
        x, y = self.world_xytheta_body[:2]
        b = self.blind_boxes_m
        return bool(np.any((b[:, 0] <= x) & (x <= b[:, 2]) & (b[:, 1] <= y) & (y <= b[:, 3])))

    def scan(self, t_s: float) -> Scan:
        lid, pose = self.lidar, self.world_xytheta_body
        if self.lidar_blind():
            self._last_scan = (float(t_s), pose.copy(), np.zeros(len(self.beams)))  # it sees nothing
            return Scan(float(t_s), self.beams, np.full(len(self.beams), np.nan), lid.max_range_m)
        expected = self.caster.scan(pose, self.beams, lid.max_range_m)[0]
        self._last_scan = (float(t_s), pose.copy(), expected)
        obs = self.obstacles
        if len(obs):
            dyn = cast_circles(np.repeat(pose[None, :2], len(self.beams), axis=0), pose[2] + self.beams,
                               obs.position_at(t_s), obs.radius_m, lid.max_range_m)
            expected = np.fmin(expected, dyn)
        no_return = np.isnan(expected)
        noisy = lid.beam_model.sample(self.rng, np.where(no_return, lid.max_range_m, expected), lid.max_range_m)
        noisy = np.where(no_return | (noisy >= lid.max_range_m), np.nan, noisy)
        return Scan(float(t_s), self.beams, noisy, lid.max_range_m)

    def discs_seen(self) -> tuple[float, np.ndarray]:
        """What the last scan saw of the moving discs, for privileged perception (an ablation,
        :mod:`slamkit.experiments.navigation.perception`): its time and (K,) how many of its
        noise-free beams end on each disc -- nearer than the map and than every other disc (0
        each when there was no scan yet or the lidar was blind)."""
        obs = self.obstacles
        if self._last_scan is None or not len(obs):
            return (math.nan if self._last_scan is None else self._last_scan[0]), np.zeros(len(obs), dtype=int)
        t_s, pose, expected = self._last_scan
        origins = np.repeat(pose[None, :2], len(self.beams), axis=0)
        ranges = np.column_stack([cast_circles(origins, pose[2] + self.beams, c[None], [r], self.lidar.max_range_m,
                                               no_hit=np.inf)
                                  for c, r in zip(obs.position_at(t_s), obs.radius_m)])  # (N, K)
        nearest = np.argmin(ranges, axis=1)
        hit = ranges[np.arange(len(ranges)), nearest] < np.fmin(expected, np.inf)  # no static return: NaN -> inf
        return t_s, np.bincount(nearest[hit], minlength=len(obs))

    def clearance_m(self, t_s: float, robot_radius_m: float, distance_m: np.ndarray) -> tuple[float, float]:
        """(static, moving) distance from the robot's disc to the nearest wall and to the nearest
        moving disc (+inf without any). The wall distance is exact: from the robot's centre to the
        nearest occupied cell *square* (looked up among the cells whose centres the distance field
        puts within reach; outside the map counts as a wall)."""
        g = self.scenario.grid
        xy = self.world_xytheta_body[:2]
        cell = g.world_to_cell(xy[None, :])
        if not bool(g.in_bounds(cell)[0]):
            d_static = -robot_radius_m
        else:
            reach = float(distance_m[cell[0, 1], cell[0, 0]]) + g.resolution_m
            k = int(math.ceil(reach / g.resolution_m)) + 1
            ix0, iy0 = max(cell[0, 0] - k, 0), max(cell[0, 1] - k, 0)
            iy, ix = np.nonzero(g.occupied[iy0:cell[0, 1] + k + 1, ix0:cell[0, 0] + k + 1])
            if len(ix) == 0:
                d_static = reach - robot_radius_m
            else:
                lo = g.origin_xy_m + np.column_stack([ix + ix0, iy + iy0]) * g.resolution_m
                gap = np.maximum(np.maximum(lo - xy, xy - (lo + g.resolution_m)), 0.0)
                d_static = float(np.linalg.norm(gap, axis=1).min()) - robot_radius_m
        obs = self.obstacles
        d_moving = math.inf
        if len(obs):
            centres = obs.position_at(t_s)
            d_moving = float((np.linalg.norm(centres - xy, axis=1) - obs.radius_m).min())
            d_moving -= robot_radius_m
        return d_static, d_moving

    def kidnap(self, shift_xy_m: np.ndarray, t_s: float, robot_radius_m: float, distance_m: np.ndarray) -> bool:
        """Shift the true robot by ``shift_xy_m`` (in its body frame), or by the opposite shift if
        that lands in a wall; True when one of them was free (>= 0.05 m clearance, ``distance_m``
        the map's distance field as in :meth:`clearance_m`) and applied."""
        x = self.world_xytheta_body
        c, s = math.cos(x[2]), math.sin(x[2])
        world_shift = np.array([c * shift_xy_m[0] - s * shift_xy_m[1], s * shift_xy_m[0] + c * shift_xy_m[1]])
        for sign in (1.0, -1.0):
            before = x[:2].copy()
            x[:2] = before + sign * world_shift
            if min(self.clearance_m(t_s, robot_radius_m, distance_m)) >= 0.05:
                return True
            x[:2] = before
        return False


#: the caller's planner between two points: ``route(start_xy, goal_xy)`` -> a result with
#: ``solved``, ``length_m`` and ``path`` (slamkit.planning's PlanResult)
Route = Callable[[np.ndarray, np.ndarray], Any]


def start_goal_draws(grid: OccupancyGrid, rng: np.random.Generator, route: Route, robot_radius_m: float,
                     distance_m: tuple[float, float], attempts: int) -> Iterator[tuple[np.ndarray, Any]]:
    """Yield (poses (2, 3), route result) for start/goal pairs drawn in free space at least 0.5 m
    beyond the robot's radius from walls, ``distance_m`` apart, with a route at most twice the
    longest distance (up to ``attempts`` draws)."""
    for _attempt in range(attempts):
        poses = random_free_poses(grid, rng, 2, clearance_m=robot_radius_m + 0.5)
        d = float(np.linalg.norm(poses[0, :2] - poses[1, :2]))
        if not distance_m[0] <= d <= distance_m[1]:
            continue
        res = route(poses[0, :2], poses[1, :2])
        if res.solved and res.length_m <= 2.0 * distance_m[1]:
            yield poses, res


def passage_draws(grid: OccupancyGrid, rng: np.random.Generator, route: Route, attempts: int
                  ) -> Iterator[tuple[np.ndarray, Any]]:
    """Start and goal on either side of the passage hall's partition (1-2.5 m from the end
    walls, 1.2 m from the side walls), with the route between them."""
    w, h = grid.width * grid.resolution_m, grid.height * grid.resolution_m
    for _attempt in range(attempts):
        x = rng.uniform(1.0, 2.5, 2)
        y = rng.uniform(1.2, h - 1.2, 2)
        poses = np.array([[x[0], y[0], 0.0], [w - x[1], y[1], rng.uniform(-np.pi, np.pi)]])
        res = route(poses[0, :2], poses[1, :2])
        if res.solved:
            yield poses, res
