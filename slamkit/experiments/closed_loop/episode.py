"""One closed-loop episode: the seeded scenario (:func:`make_scenario`: start, goal and the A*
path through a world of :mod:`slamkit.sim.local_planning_world`, moving obstacles timed to meet
the robot), the control cycle (:func:`run_episode`: perceive, decide, move, measure the
clearance) and its metrics (:func:`episode_metrics`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Mapping, Protocol

import numpy as np

from slamkit.control.protocols import (ControlOutput, ControlStatus, Controller, DistanceGrid,
                                       LocalWorld, Reference, RobotState)
from slamkit.errors import ConfigError
from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.inflation import costmap
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.models.diff_drive import motion
from slamkit.planning.astar import AStarPlanner
from slamkit.planning.grid_search import costmap_to_cell_cost
from slamkit.planning.protocols import PlanningProblem
from slamkit.sim.local_planning_world import scenario_map, visible_obstacles
from slamkit.sim.local_planning_world import clearance_m as world_clearance_m
from slamkit.sim.moving_obstacles import MovingObstacles, crossing_obstacles
from slamkit.sim.navigation_world import start_goal_draws


# --------------------------------------------------------------------------- scenarios


@dataclass(frozen=True)
class Scenario:
    name: str
    seed: int
    grid: OccupancyGrid
    start_xytheta: np.ndarray
    goal_xy_m: np.ndarray
    path_xy_m: np.ndarray
    obstacles: MovingObstacles
    distance: DistanceGrid
    #: A* traversal multipliers of the static map (inf = blocked), reused when a controller
    #: hands over to the global planner
    cell_cost: np.ndarray | None = None


def replan(scenario: Scenario, xy_m: np.ndarray, t_s: float, robot_radius_m: float) -> np.ndarray | None:
    """Hand-over to the global planner: A* from ``xy_m`` to the goal on the static costmap with
    the moving obstacles' current discs (inflated by the robot radius) blocked. None if no path."""
    if scenario.cell_cost is None:
        return None
    cost = scenario.cell_cost.copy()
    g = scenario.grid
    if len(scenario.obstacles):
        iy, ix = np.mgrid[0:g.height, 0:g.width]
        centres = g.cell_to_world(np.column_stack([ix.ravel(), iy.ravel()]))
        pos = scenario.obstacles.position_at(t_s)
        d = np.linalg.norm(centres[:, None, :] - pos[None, :, :], axis=2)
        blocked = (d <= scenario.obstacles.radius_m + robot_radius_m).any(axis=1).reshape(g.height, g.width)
        cost[blocked] = np.inf
    res = AStarPlanner().plan(PlanningProblem(g, np.asarray(xy_m, float), scenario.goal_xy_m, cell_cost=cost))
    return _simplify(res.path) if res.solved else None


def _simplify(path: np.ndarray, every: int = 3) -> np.ndarray:
    """Keep every ``every``-th A* cell centre (and the last): the controllers interpolate anyway."""
    if len(path) <= 2:
        return path
    keep = np.unique(np.concatenate([np.arange(0, len(path), every), [len(path) - 1]]))
    return path[keep]


def make_scenario(seed: int, kind: str = "office", n_obstacles: int = 3,
                  robot_radius_m: float = 0.2, distance_m: tuple[float, float] = (6.0, 14.0),
                  nominal_speed_mps: float = 0.5,
                  obstacle_speed_mps: tuple[float, float] = (0.2, 0.5),
                  obstacle_min_side_m: float = 0.5) -> Scenario:
    """A seeded scenario (same seed and kind -> same scenario)."""
    rng = np.random.default_rng(seed)
    grid = scenario_map(kind, rng)
    # the global path keeps the robot's disc plus 0.15 m from walls, more than any controller's
    # safety margin, so a path never leads through a gap the local planner refuses to enter
    cost = costmap(grid, inscribed_radius_m=robot_radius_m + 0.15, inflation_radius_m=1.0)
    cell_cost = costmap_to_cell_cost(cost)
    planner = AStarPlanner()

    def route(start_xy: np.ndarray, goal_xy: np.ndarray):
        return planner.plan(PlanningProblem(grid, start_xy, goal_xy, cell_cost=cell_cost))

    for poses, res in start_goal_draws(grid, rng, route, robot_radius_m, distance_m, 200):
        path = _simplify(res.path)
        start = poses[0].copy()
        # start roughly facing the path, as after a global plan
        lead = path[min(5, len(path) - 1)] - path[0]
        start[2] = math.atan2(lead[1], lead[0]) + rng.uniform(-0.5, 0.5)
        obstacles = crossing_obstacles(path, n_obstacles, rng, grid=grid, speed_mps=obstacle_speed_mps,
                                       nominal_speed_mps=nominal_speed_mps, min_side_m=obstacle_min_side_m)
        distance = DistanceGrid(distance_field_m(grid), grid.resolution_m, grid.origin_xy_m)
        return Scenario(f"{kind}_{seed}", seed, grid, start, poses[1, :2].copy(), path, obstacles,
                        distance, cell_cost)
    raise ConfigError(f"could not draw a start/goal pair with a path in {kind} map (seed {seed})")


# --------------------------------------------------------------------------- the loop


@dataclass(frozen=True)
class ClosedLoopConfig:
    dt_s: float = 0.1
    max_time_s: float = 60.0
    goal_tolerance_m: float = 0.3
    robot_radius_m: float = 0.2
    sensor_range_m: float = 5.0
    reference_speed_mps: float = 0.6


@dataclass(frozen=True)
class ControlStep:
    """One closed-loop cycle as observers (the Rerun recorder, progress bars) see it; pipeline
    observers receive it as the ``step`` of an ``observers.StepSnapshot``'s
    :class:`LocalPlanningSnapshot`."""

    step: int
    t_s: float
    world_xytheta_body: np.ndarray
    output: ControlOutput
    obstacle_xy_m: np.ndarray
    obstacle_radius_m: np.ndarray
    clearance_m: float


class Observer(Protocol):
    def on_episode(self, scenario: Scenario, controller: str) -> None: ...

    def on_step(self, snapshot: ControlStep) -> None: ...


@dataclass(frozen=True)
class Episode:
    scenario: str
    controller: str
    seed: int
    t_s: np.ndarray            # (T,)
    poses_xytheta: np.ndarray  # (T, 3)
    commands: np.ndarray       # (T - 1, 2)
    statuses: tuple[str, ...]  # (T - 1,)
    solve_time_s: np.ndarray   # (T - 1,)
    clearance_m: np.ndarray    # (T,)
    reached_goal: bool
    collided: bool
    metrics: Mapping[str, float] = field(default_factory=dict)


def perceive(scenario: Scenario, world_xytheta_body: np.ndarray, t_s: float,
             config: ClosedLoopConfig) -> LocalWorld:
    """What the controller is told: the static map and the circles the perfect tracker sees
    (:func:`slamkit.sim.local_planning_world.visible_obstacles`)."""
    if len(scenario.obstacles) == 0:
        return LocalWorld(distance=scenario.distance, t_s=t_s)
    xy, radius, velocity = visible_obstacles(scenario.obstacles, world_xytheta_body[:2], t_s, config.sensor_range_m)
    return LocalWorld(xy, radius, velocity, scenario.distance, t_s)


def clearance_m(scenario: Scenario, xy_m: np.ndarray, t_s: float, robot_radius_m: float) -> float:
    """Distance from the robot's disc to the nearest obstacle surface (< 0: collision):
    :func:`slamkit.sim.local_planning_world.clearance_m` on the scenario's map and circles."""
    return world_clearance_m(scenario.grid, scenario.distance.distance_m, scenario.obstacles, xy_m, t_s,
                             robot_radius_m)


def run_episode(scenario: Scenario, controller: Controller, config: ClosedLoopConfig = ClosedLoopConfig(),
                observers: Iterable[Observer] = ()) -> Episode:
    observers = list(observers)
    for ob in observers:
        ob.on_episode(scenario, controller.name)
    controller.reset()
    reference = Reference(scenario.path_xy_m, speed_mps=config.reference_speed_mps)
    x = np.asarray(scenario.start_xytheta, dtype=float).copy()
    u = np.zeros(2)
    ts, xs, us, st, lat = [0.0], [x], [], [], []
    clear = [clearance_m(scenario, x[:2], 0.0, config.robot_radius_m)]
    reached = collided = False
    replans = 0
    steps = int(round(config.max_time_s / config.dt_s))
    for k in range(steps):
        t = k * config.dt_s
        if np.linalg.norm(x[:2] - scenario.goal_xy_m) <= config.goal_tolerance_m:
            reached = True
            break
        world = perceive(scenario, x, t, config)
        out = controller.compute(RobotState(x, u, t), reference, world)
        if out.status is ControlStatus.LOCAL_MINIMUM:
            # the controller asks the global planner for help: replan from here around what it sees
            path = replan(scenario, x[:2], t, config.robot_radius_m)
            if path is not None and len(path) >= 2:
                reference = Reference(path, speed_mps=config.reference_speed_mps)
                replans += 1
        u = out.command
        x = motion(x, u, config.dt_s)
        t_next = t + config.dt_s
        c = clearance_m(scenario, x[:2], t_next, config.robot_radius_m)
        ts.append(t_next); xs.append(x); us.append(u); st.append(out.status.value)  # noqa: E702
        lat.append(out.solve_time_s); clear.append(c)  # noqa: E702
        if observers:
            obs = scenario.obstacles
            snap = ControlStep(k + 1, t_next, x, out,
                                obs.position_at(t_next) if len(obs) else np.zeros((0, 2)),
                                obs.radius_m, c)
            for ob in observers:
                ob.on_step(snap)
        if c < 0.0:
            collided = True
            break
    else:
        reached = bool(np.linalg.norm(x[:2] - scenario.goal_xy_m) <= config.goal_tolerance_m)
    ep = Episode(scenario.name, controller.name, scenario.seed, np.asarray(ts), np.asarray(xs),
                 np.asarray(us).reshape(-1, 2), tuple(st), np.asarray(lat), np.asarray(clear),
                 reached and not collided, collided)
    metrics = {**episode_metrics(ep, config.dt_s), "replans": float(replans)}
    return Episode(**{**ep.__dict__, "metrics": metrics})


def episode_metrics(ep: Episode, dt_s: float) -> dict[str, float]:
    v = ep.commands[:, 0] if len(ep.commands) else np.zeros(0)
    jerk = np.diff(v, n=2) / dt_s**2 if len(v) >= 3 else np.zeros(0)
    fallback = sum(s in (ControlStatus.FALLBACK_BRAKE.value, ControlStatus.LOCAL_MINIMUM.value)
                   for s in ep.statuses)
    return {
        "success": float(ep.reached_goal),
        "time_to_goal_s": float(ep.t_s[-1]) if ep.reached_goal else float("nan"),
        "path_length_m": float(np.linalg.norm(np.diff(ep.poses_xytheta[:, :2], axis=0), axis=1).sum()),
        "min_clearance_m": float(ep.clearance_m.min()),
        "collisions": float(ep.collided),
        "jerk_rms_mps3": float(np.sqrt(np.mean(jerk**2))) if len(jerk) else 0.0,
        "fallback_steps": float(fallback),
        "step_latency_median_ms": float(np.median(ep.solve_time_s) * 1e3) if len(ep.solve_time_s) else 0.0,
    }
