"""Closed-loop local planning: a controller tracks a global path to a goal through a static map
while moving obstacles cross the path; the ``local_planning`` pipeline compares controllers over
seeded scenarios.

One control cycle (period ``dt_s``):

1. perception -- the robot knows the static map (as a distance field) and sees the moving
   circles within ``sensor_range_m`` with their true positions and velocities (a perfect tracker;
   the point is to compare the decision makers, not the perception);
2. the controller computes a command from the state, the global path and that local world;
3. the plant -- ``slamkit.models.diff_drive.motion``, the exact-arc unicycle -- applies it for dt;
4. the clearance (distance from the robot's disc to the nearest static or moving obstacle
   surface) is measured; below zero is a collision and ends the episode.

An episode succeeds when the robot's centre gets within ``goal_tolerance_m`` of the goal
without a collision before ``max_time_s``. Metrics (units in the names): ``success``,
``time_to_goal_s`` (NaN when not reached), ``path_length_m``, ``min_clearance_m``,
``collisions`` (0 or 1), ``jerk_rms_mps3`` (RMS of the second difference of the commanded speed
over dt^2), ``fallback_steps`` (cycles whose status was a brake or a local minimum) and
``step_latency_median_ms``.

Scenarios (:func:`make_scenario`): a seeded map (:func:`slamkit.sim.local_planning_world.scenario_map`:
the office and warehouse generators at 20 m x 20 m, or an open room with boxes), start and goal
drawn in free space 6-14 m apart, the global path from A* on the Nav2-style costmap, and moving
circles from :func:`slamkit.sim.moving_obstacles.crossing_obstacles` timed to meet the robot. The
world itself -- map, perfect obstacle sensor, ground-truth clearance -- is
:mod:`slamkit.sim.local_planning_world`; this module draws what needs a planner (start, goal,
path, the hand-over replan) and runs the loop (issue 30).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Callable, Iterable, Literal, Mapping, Protocol

import numpy as np
import pydantic
from pydantic import BaseModel, Field

from slamkit.control.protocols import (ControlOutput, ControlStatus, Controller, DistanceGrid,
                                       LocalWorld, Reference, RobotState)
from slamkit.control.registry import CONTROLLERS, make_controller
from slamkit.config import STRICT, YamlDocument, build, model_of, validate
from slamkit.errors import ConfigError
from slamkit.experiments.config_models import PipelineConfig, Seeds, _nested, seed_list, typed_config
from slamkit.experiments.observers import PipelineObserver, StepSnapshot
from slamkit.experiments.pipeline import Pipeline, PipelineOutput, StepProgress
from slamkit.experiments.pipeline import run_pipeline as _run
from slamkit.experiments.results import ResultsFolder, RunRecord, markdown_table, summarise, summary_markdown
from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.inflation import costmap
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.models.diff_drive import motion
from slamkit.naming import suggestion
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


# --------------------------------------------------------------------------- comparison


def scenario_list(scenarios: "LocalPlanningScenarios") -> list[Scenario]:
    """The seeded scenarios of a config's ``scenarios`` (kinds taken in turn over the seeds).

    ``obstacle_min_side_m``: how far from the path a shuttling obstacle may turn round: measured
    on 30 scenarios, 0.5 m left 17 % collisions for DWA and MPC, nearly all obstacles reversing
    beside the robot (a constant-velocity prediction cannot foresee it); 1 m gave 0-3 % but fits
    fewer obstacles."""
    kinds = scenarios.kinds
    speed = tuple(float(v) for v in scenarios.obstacle_speed_mps)
    return [make_scenario(seed, kinds[i % len(kinds)], scenarios.n_obstacles, obstacle_speed_mps=speed,
                          obstacle_min_side_m=scenarios.obstacle_min_side_m)
            for i, seed in enumerate(seed_list(scenarios.seeds))]


@dataclass(frozen=True)
class LocalPlanningSnapshot:
    """The state of a ``local_planning`` step snapshot (issue 30, item 4: a type, not a dict of
    string keys): the episode's scenario, the controller's name and the cycle's
    :class:`ControlStep` (values only: the pose, the controller's output, the obstacles)."""

    scenario: Scenario
    controller: str
    step: ControlStep


class _PipelineStepAdapter:
    """Forwards closed-loop steps to a pipeline observer (``slamkit.experiments.observers``) as
    ``StepSnapshot(kind="local_planning", run="<controller>/<scenario>", ...)`` whose state is a
    :class:`LocalPlanningSnapshot`."""

    def __init__(self, observer, controller: str, scenario: Scenario):
        self.observer, self.controller, self.scenario = observer, controller, scenario

    def on_episode(self, scenario: Scenario, controller: str) -> None:
        pass

    def on_step(self, snap: ControlStep) -> None:
        self.observer.on_step(StepSnapshot("local_planning", f"{self.controller}/{self.scenario.name}",
                                           snap.step, snap.t_s,
                                           LocalPlanningSnapshot(self.scenario, self.controller, snap)))


def compare(config: "LocalPlanningPipeline | Mapping[str, Any]", observer=None,
            progress: Callable[[int], None] | None = None) -> tuple[list[Episode], list[Scenario]]:
    """Every controller on every scenario of ``config`` (the pipeline's model; a plain mapping
    is made one by :func:`~slamkit.experiments.config_models.typed_config`). A pipeline
    ``observer`` that wants steps sees the episodes of the first ``record_scenarios`` scenarios
    (default 1, to keep recordings small)."""
    config = typed_config(LocalPlanningPipeline, config)
    controllers = config.controllers
    try:  # every name checked before the first episode runs
        names = [CONTROLLERS.canonical(c) for c in controllers]
    except ConfigError as exc:
        raise ConfigError(f"controllers: {exc}") from None
    params = config.controller_params
    loop = build(ClosedLoopConfig, config.closed_loop, "closed_loop")
    watch = observer is not None and observer.wants_steps
    episodes = []
    scenarios = scenario_list(config.scenarios)
    for typed, name in zip(controllers, names):
        ctl = make_controller(name, params.get(typed, params.get(name)))
        for i, sc in enumerate(scenarios):
            obs = [_PipelineStepAdapter(observer, name, sc)] if watch and i < config.record_scenarios else []
            episodes.append(run_episode(sc, ctl, loop, obs))
            if progress is not None:
                progress(1)
    return episodes, scenarios


def episodes_to_runs(episodes: Iterable[Episode]) -> list[RunRecord]:
    """One RunRecord per episode; dataset = "local_planning" so the summary groups by controller
    over all scenarios (the scenario name is kept in params)."""
    return [RunRecord("local_planning", e.controller, dict(e.metrics), seed=e.seed,
                      params={"scenario": e.scenario}) for e in episodes]


def report_markdown(config: "LocalPlanningPipeline", episodes: list[Episode], summary: list[dict]) -> str:
    text = f"# Local planning: {config.name or 'local_planning'}\n\n"
    text += ("Controllers track an A* path through a static map while moving circles cross it "
             "(perfect perception within range). Mean ± half the 95% CI over scenarios; "
             "time to goal over successful runs only.\n\n")
    text += summary_markdown(summary) + "\n\n## Runs\n\n"
    rows = [[e.scenario, e.controller, e.metrics["success"], e.metrics["time_to_goal_s"],
             e.metrics["min_clearance_m"], e.metrics["collisions"], e.metrics["step_latency_median_ms"]]
            for e in episodes]
    text += markdown_table(["scenario", "controller", "success", "time to goal (s)",
                            "min clearance (m)", "collisions", "latency median (ms)"], rows) + "\n"
    return text


def plot(plots: Path, episodes: list[Episode], scenarios: Mapping[str, Scenario]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    first = episodes[0].scenario
    sc = scenarios[first]
    fig, ax = plt.subplots(figsize=(7, 7))
    g = sc.grid
    extent = (g.origin_xy_m[0], g.origin_xy_m[0] + g.width * g.resolution_m,
              g.origin_xy_m[1], g.origin_xy_m[1] + g.height * g.resolution_m)
    ax.imshow(g.occupied, origin="lower", extent=extent, cmap="Greys", alpha=0.8)
    ax.plot(sc.path_xy_m[:, 0], sc.path_xy_m[:, 1], "k--", lw=1, label="global path")
    for e in episodes:
        if e.scenario == first:
            ax.plot(e.poses_xytheta[:, 0], e.poses_xytheta[:, 1], lw=1.5,
                    label=f"{e.controller} ({'ok' if e.reached_goal else 'fail'})")
    for a, b in zip(sc.obstacles.a_xy_m, sc.obstacles.b_xy_m):
        ax.plot([a[0], b[0]], [a[1], b[1]], color="tab:red", lw=3, alpha=0.4)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{first}: trajectories (red: obstacle crossing segments)")
    ax.set_aspect("equal")
    fig.savefig(plots / "trajectories.png", dpi=110, bbox_inches="tight")
    plt.close(fig)

    names = list(dict.fromkeys(e.controller for e in episodes))
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for ax, metric, label in zip(axes, ("success", "time_to_goal_s", "min_clearance_m"),
                                 ("success rate", "time to goal (s)", "min clearance (m)")):
        vals = []
        for n in names:
            v = np.array([e.metrics[metric] for e in episodes if e.controller == n], dtype=float)
            vals.append(float(v[np.isfinite(v)].mean()) if np.isfinite(v).any() else 0.0)
        ax.bar(names, vals, color="tab:blue")
        ax.set_title(label)
    fig.savefig(plots / "metrics.png", dpi=110, bbox_inches="tight")
    plt.close(fig)


def run(config: LocalPlanningPipeline, folder: ResultsFolder, progress: StepProgress,
        observer: PipelineObserver | None = None) -> PipelineOutput[list[Episode]]:
    """Pipeline ``local_planning`` (``PIPELINE`` below) on its validated, resolved model:
    controllers x seeded scenarios -> results.json runs/summary, report.md and plots; the observer
    (the recorder the viz layer registers, ``slamkit.viz.control.LocalPlanningObserver``) records
    the steps."""
    n = len(seed_list(config.scenarios.seeds)) * len(config.controllers)
    advance = progress.task("closed-loop episodes", n)
    episodes, scenarios = compare(config, observer, advance)
    runs = episodes_to_runs(episodes)
    summary = summarise(runs)
    plot(folder.plots, episodes, {s.name: s for s in scenarios})
    return PipelineOutput(runs, report_markdown(config, episodes, summary), summary, payload=episodes)


# --- the config model (slamkit.experiments.config_models): checked before anything runs ---------

class LocalPlanningScenarios(BaseModel):
    model_config = STRICT
    kinds: Annotated[list[Literal["office", "warehouse", "open"]], Field(min_length=1)] = ["office"]
    seeds: Seeds = 5
    n_obstacles: Annotated[int, Field(ge=0, le=100)] = 3
    obstacle_speed_mps: tuple[Annotated[float, Field(ge=0, le=10)], Annotated[float, Field(ge=0, le=10)]] = (0.2, 0.5)
    obstacle_min_side_m: Annotated[float, Field(ge=0, le=100)] = 0.5


class LocalPlanningPipeline(PipelineConfig):
    pipeline: Literal["local_planning"]
    #: names in ``slamkit.control.registry.CONTROLLERS`` (checked in ``check_options``)
    controllers: Annotated[list[str], Field(min_length=1)] = ["dwa", "mpc"]
    scenarios: LocalPlanningScenarios = LocalPlanningScenarios()
    closed_loop: dict[str, Any] = {}
    controller_params: dict[str, dict[str, Any]] = {}
    record_scenarios: Annotated[int, Field(ge=0, le=1000)] = 1

    def check_options(self, config: dict[str, Any], doc: YamlDocument | None, source: str) -> None:
        _nested(model_of(ClosedLoopConfig), self.closed_loop, doc, source, ("closed_loop",))
        for i, name in enumerate(self.controllers):
            if name not in CONTROLLERS:
                where = doc.where(("controllers", i)) if doc is not None else source
                raise ConfigError(f"{where}: controllers.{i}: unknown controller {name!r}"
                                  + suggestion(name, CONTROLLERS) + f"; known: {', '.join(CONTROLLERS)}")
        for name, params in self.controller_params.items():
            if name not in CONTROLLERS:
                validate(pydantic.create_model("ControllerParams", __config__=STRICT,
                                               **{k: (dict, None) for k in CONTROLLERS}),
                         {name: params}, doc, source, ("controller_params",))
            _nested(model_of(CONTROLLERS.get(name).config), params, doc, source, ("controller_params", name))


def run_pipeline(config: Mapping[str, Any], out_dir: str | Path, observer_factory=None) -> dict[str, Any]:
    """Run the comparison and write the results folder; returns the results.json dict.
    ``observer_factory`` as in ``slamkit.experiments.pipeline.run_pipeline`` (e.g.
    ``slamkit.viz.pipelines.observer_for``) adds ``recording.rrd``."""
    cfg = dict(config)
    cfg.setdefault("pipeline", "local_planning")
    return _run(cfg, out_dir, progress=False, observer_factory=observer_factory).results


PIPELINE: Pipeline[LocalPlanningPipeline, list[Episode]] = Pipeline(
    "local_planning", run, LocalPlanningPipeline, list[Episode],
    "controllers x seeded closed-loop scenarios")
