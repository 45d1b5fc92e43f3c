"""One navigation episode: the seeded scenario (:func:`make_navigation_scenario`: a world of
:mod:`slamkit.sim.navigation_world`, start and goal with the A* route they are drawn along,
crossing traffic), the closed loop between the plant and the stack (:func:`run_episode`) and the
episode's metrics, scored against the truth the stack never sees."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from slamkit.errors import ConfigError
from slamkit.experiments.navigation.benchmark import episode_benchmark_metrics, scenario_difficulty
from slamkit.experiments.navigation.map_source import RobotMap, robot_map
from slamkit.experiments.navigation.perception import PERCEPTION, TruePerception
from slamkit.geometry.angles import wrap_angle
from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.inflation import costmap
from slamkit.planning.astar import AStarPlanner
from slamkit.planning.grid_search import costmap_to_cell_cost
from slamkit.planning.protocols import PlanningProblem
from slamkit.sim.navigation_world import (NavigationPlant, NavigationScenario, passage_draws, start_goal_draws,
                                         world_map)
from slamkit.sim.social_force import crossing_traffic
from slamkit.systems.navigation import NavigationCommand, NavigationConfig, NavigationStack, layer_timing_summary


def make_navigation_scenario(seed: int, kind: str, willow_yaml: str | None = None,
                             robot_radius_m: float = 0.2, distance_m: tuple[float, float] = (6.0, 14.0),
                             n_obstacles: int = 2, obstacle_speed_mps: tuple[float, float] = (0.2, 0.6),
                             obstacle_radius_m: tuple[float, float] = (0.25, 0.45),
                             nominal_speed_mps: float = 0.4, path_margin_m: float = 0.15,
                             agents: str = "constant_velocity") -> NavigationScenario:
    """A seeded scenario: start and goal poses in free space ``distance_m`` apart with an A*
    path on the costmap (inscribed radius robot + ``path_margin_m``), and ``n_obstacles`` discs
    (people of radius ~0.25 m, a forklift up to ~0.45 m) crossing the path, timed to meet a
    robot driving it at ``nominal_speed_mps``: shuttles at constant speed, or with ``agents:
    social_force`` people and forklifts drawn from the same crossings
    (:func:`slamkit.sim.social_force.crossing_traffic`)."""
    rng = np.random.default_rng(seed)
    grid = world_map(kind, rng, willow_yaml)
    field_m = distance_field_m(grid)
    inscribed = robot_radius_m + path_margin_m
    cell_cost = costmap_to_cell_cost(costmap(grid, inscribed, max(1.0, inscribed), distance_m=field_m))
    planner = AStarPlanner()

    def route(start_xy: np.ndarray, goal_xy: np.ndarray):
        return planner.plan(PlanningProblem(grid, start_xy, goal_xy, cell_cost=cell_cost))

    draws = (passage_draws(grid, rng, route, 300) if kind == "passage"
             else start_goal_draws(grid, rng, route, robot_radius_m, distance_m, 300))
    for poses, res in draws:
        path = res.path
        start = poses[0].copy()
        lead = path[min(10, len(path) - 1)] - path[0]
        start[2] = math.atan2(lead[1], lead[0]) + rng.uniform(-0.5, 0.5)
        obstacles = crossing_traffic(agents, path, n_obstacles, rng, grid=grid, speed_mps=obstacle_speed_mps,
                                     radius_m=obstacle_radius_m, nominal_speed_mps=nominal_speed_mps,
                                     min_side_m=1.0)
        return NavigationScenario(f"{kind}_{seed}", seed, grid, start, poses[1].copy(), path, obstacles)
    raise ConfigError(f"could not draw a start/goal pair with a path in the {kind} map (seed {seed})")


@dataclass(frozen=True)
class EpisodeConfig:
    dt_s: float = 0.1
    max_time_s: float = 90.0
    goal_tolerance_m: float = 0.03
    heading_tolerance_rad: float = 0.1
    #: the stack's start belief: the true start plus an error of this sigma, believed with it
    initial_sigma_xy_m: float = 0.05
    initial_sigma_theta_rad: float = 0.05
    #: the odometry the plant reports (the stack assumes NavigationConfig.odometry_sigma_*)
    odometry_sigma_v_mps: float = 0.02
    odometry_sigma_omega_radps: float = float(np.deg2rad(1.0))
    #: a kidnapping: at this time the true robot is shifted by ``kidnap_xy_m`` in its body frame
    #: (or the opposite way if that is in a wall; retried every cycle until one is free) (None: none)
    kidnap_at_s: float | None = None
    kidnap_xy_m: tuple[float, float] = (0.3, 0.0)
    #: boxes (x_min, y_min, x_max, y_max) in the world where the lidar returns nothing, so the
    #: stack runs on odometry alone there (:class:`NavigationPlant`)
    lidar_blind_boxes_m: tuple[tuple[float, float, float, float], ...] = ()
    #: how the stack perceives the moving discs: ``lidar`` (its own detector and tracker, the
    #: benchmark), or privileged, an ablation (:mod:`slamkit.experiments.navigation.perception`):
    #: ``true_detections`` (the true discs each scan saw, tracked by its tracker) or
    #: ``true_tracks`` (its tracks hold the true discs' states)
    perception: str = "lidar"

    def __post_init__(self) -> None:
        for name in ("dt_s", "max_time_s", "goal_tolerance_m", "heading_tolerance_rad"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"EpisodeConfig.{name} must be a finite number > 0, got {v!r}")
        for name in ("initial_sigma_xy_m", "initial_sigma_theta_rad", "odometry_sigma_v_mps",
                     "odometry_sigma_omega_radps"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"EpisodeConfig.{name} must be a finite number >= 0, got {v!r}")
        if self.max_time_s / self.dt_s > 1e6:
            raise ConfigError("EpisodeConfig: max_time_s / dt_s above a million cycles")
        if self.kidnap_at_s is not None and not (isinstance(self.kidnap_at_s, (int, float))
                                                 and math.isfinite(self.kidnap_at_s)):
            raise ConfigError(f"EpisodeConfig.kidnap_at_s must be finite or None, got {self.kidnap_at_s!r}")
        if len(self.kidnap_xy_m) != 2 or not all(isinstance(v, (int, float)) and math.isfinite(v)
                                                 for v in self.kidnap_xy_m):
            raise ConfigError(f"EpisodeConfig.kidnap_xy_m must be two finite numbers, got {self.kidnap_xy_m!r}")
        if self.perception not in PERCEPTION:
            raise ConfigError(f"EpisodeConfig.perception must be one of {', '.join(PERCEPTION)}, got {self.perception!r}")
        for box in self.lidar_blind_boxes_m:
            if not (len(box) == 4 and all(isinstance(v, (int, float)) and math.isfinite(v) for v in box)
                    and box[0] < box[2] and box[1] < box[3]):
                raise ConfigError("EpisodeConfig.lidar_blind_boxes_m: each box is [x_min, y_min, x_max, y_max] "
                                  f"with min < max, got {box!r}")


@dataclass(frozen=True)
class Episode:
    scenario: str
    world: str
    seed: int
    variant: str
    t_s: np.ndarray
    true_xytheta: np.ndarray
    #: in the robot's map frame (the world's, unless the map is a SLAM map: ``RobotMap``)
    estimated_xytheta: np.ndarray
    metrics: Mapping[str, float] = field(default_factory=dict)
    #: (T,) the estimate's position error against the true pose seen in the map's frame;
    #: None: |estimate - truth| (the map is the world's)
    localisation_error_m: np.ndarray | None = None

    def position_error_m(self) -> np.ndarray:
        if self.localisation_error_m is not None:
            return self.localisation_error_m
        return np.linalg.norm(self.estimated_xytheta[:, :2] - self.true_xytheta[:, :2], axis=1)


def run_episode(scenario: NavigationScenario, nav_config: NavigationConfig = NavigationConfig(),
                config: EpisodeConfig = EpisodeConfig(), variant: str = "",
                on_step: Callable[[NavigationStack, NavigationPlant, float, NavigationCommand], None] | None = None,
                robot_map: RobotMap | None = None) -> Episode:
    """One closed-loop episode (see the module docstring); ``on_step(stack, plant, t, decision)``
    is called after every cycle (the recorder). The stack localises and plans on ``robot_map``
    (default: the world's grid) and gets its start and goal in that map's frame
    (``RobotMap.to_map``); the plant and the scoring always use the world's grid and the true goal;
    the localisation error is the estimate's against the true pose seen in the map's frame."""
    rng = np.random.default_rng([scenario.seed, 1])
    robot = RobotMap(scenario.grid, "truth") if robot_map is None else robot_map
    plant = NavigationPlant(scenario, rng, odometry_sigma_v_mps=config.odometry_sigma_v_mps,
                            odometry_sigma_omega_radps=config.odometry_sigma_omega_radps,
                            lidar_blind_boxes_m=np.asarray(config.lidar_blind_boxes_m, float).reshape(-1, 4))
    tracker = None if config.perception == "lidar" else \
        TruePerception(plant, robot, nav_config.tracker, config.perception == "true_tracks")
    stack = NavigationStack(robot.grid, nav_config, np.random.default_rng([scenario.seed, 2]), tracker)
    sig = np.array([config.initial_sigma_xy_m, config.initial_sigma_xy_m, config.initial_sigma_theta_rad])
    belief = robot.to_map(scenario.start_xytheta) + sig * rng.standard_normal(3)
    stack.reset(belief, np.diag(sig**2))
    stack.set_goal(robot.to_map(scenario.goal_xytheta))
    stack.step(plant.scan(0.0))
    field_m = distance_field_m(scenario.grid)
    r = nav_config.robot_radius_m
    ts, xs, es = [0.0], [plant.world_xytheta_body.copy()], [stack.current_pose()[0]]
    c_static, c_moving = plant.clearance_m(0.0, r, field_m)
    min_static, min_moving = c_static, c_moving
    clear_static, clear_moving = [c_static], [c_moving]  # the benchmark's percentiles
    hit_static = hit_moving = False
    kidnapped = False
    steps = int(round(config.max_time_s / config.dt_s))
    for k in range(steps):
        t = k * config.dt_s
        decision = stack.command(t)
        cmd = decision.command
        if stack.reached:
            break
        if config.kidnap_at_s is not None and not kidnapped and t >= config.kidnap_at_s:
            kidnapped = plant.kidnap(np.asarray(config.kidnap_xy_m, float), t, r, field_m)
        t_next = t + config.dt_s
        stack.step(plant.advance(cmd, config.dt_s, t_next))
        stack.step(plant.scan(t_next))
        ts.append(t_next)
        xs.append(plant.world_xytheta_body.copy())
        es.append(stack.current_pose()[0])
        c_static, c_moving = plant.clearance_m(t_next, r, field_m)
        min_static, min_moving = min(min_static, c_static), min(min_moving, c_moving)
        clear_static.append(c_static)
        clear_moving.append(c_moving)
        if on_step is not None:
            on_step(stack, plant, t_next, decision)
        if c_static < 0.0 or c_moving < 0.0:
            hit_static, hit_moving = c_static < 0.0, c_moving < 0.0
            break
    difficulty = scenario_difficulty(scenario, r, field_m, nav_config.cruise_speed_mps, config.max_time_s)
    true = np.array(xs)
    est = np.array(es)
    final_err = float(np.linalg.norm(true[-1, :2] - scenario.goal_xytheta[:2]))
    final_head = float(abs(wrap_angle(true[-1, 2] - scenario.goal_xytheta[2])))
    collided = hit_static or hit_moving
    success = (stack.reached and not collided and final_err <= config.goal_tolerance_m
               and final_head <= config.heading_tolerance_rad)
    true_in_map = true if robot.anchors_world_xytheta is None else np.array([robot.to_map(x) for x in true])
    loc_err = np.linalg.norm(true_in_map[:, :2] - est[:, :2], axis=1)
    compute_s = sum(sum(v) for v in stack.timings_s.values())
    path_length_m = float(np.linalg.norm(np.diff(true[:, :2], axis=0), axis=1).sum())
    time_s = float(ts[-1]) if success else float("nan")
    metrics = {
        "success": float(success),
        "reached_by_belief": float(stack.reached),
        "final_position_error_m": final_err,
        "final_heading_error_rad": final_head,
        "collision_static": float(hit_static),
        "collision_moving": float(hit_moving),
        "min_clearance_static_m": float(min_static),
        "min_clearance_moving_m": float(min_moving) if math.isfinite(min_moving) else float("nan"),
        "time_s": time_s,
        "path_length_m": path_length_m,
        "localisation_error_mean_m": float(loc_err.mean()),
        "localisation_error_max_m": float(loc_err.max()),
        "kidnapped": float(kidnapped),
        "replans": float(stack.replans),
        "plan_expansions_median": float(np.median(stack.plan_expansions)) if stack.plan_expansions else 0.0,
        "recoveries": float(stack.recoveries),
        "no_safe_stop_cycles": float(stack.no_safe_stop_cycles),
        # covariance-aware inflation only (nan with fixed): the largest collision probability
        # a plan settled for, and how many plans lowered k to find a path
        "chance_probability_max": stack.planned_collision_probability_max,
        "chance_fallback_plans": float(stack.chance_fallbacks),
        # plans through a passage narrower than the path margin, and plans on the bare map
        "narrowed_plans": float(stack.narrowed_plans),
        "bare_map_plans": float(stack.bare_map_plans),
        #: MCL updates that injected particles (augmented MCL; 0 when it is off)
        "localisation_injections": float(stack.mcl.injections),
        **layer_timing_summary(stack.timings_s),
        "real_time_factor": float(ts[-1] / max(compute_s, 1e-9)),
        **episode_benchmark_metrics(
            success=success, collision_static=hit_static, collision_moving=hit_moving,
            reached_by_belief=stack.reached, clearance_static_m=clear_static, clearance_moving_m=clear_moving,
            time_s=time_s, path_length_m=path_length_m, difficulty=difficulty,
            max_speed_mps=nav_config.cruise_speed_mps),
    }
    return Episode(scenario.name, scenario.name.rsplit("_", 1)[0], scenario.seed, variant,
                   np.array(ts), true, est, metrics, loc_err)
