"""End-to-end navigation on an estimated pose (``pipelines/navigation.yaml``, pipeline kind
``navigation``): the experiment closes the loop between the simulator
(:mod:`slamkit.sim.navigation_world`) and the navigation stack
(:class:`slamkit.systems.navigation.NavigationStack`), and scores it against the ground truth the
stack never sees.

One control cycle (``dt_s`` = 0.1 s): the stack answers a velocity command from its belief; the
plant executes it exactly for dt; the odometry of that period (the command plus Gaussian noise)
and a lidar scan at the new pose go to the stack. An episode ends when the stack says it has
reached the goal pose, on a collision, or after ``max_time_s``.

Scenarios (:func:`make_navigation_scenario`): a seeded map (generated 20 m office or warehouse at
5 cm, or the real Willow Garage map at 10 cm), start and goal poses 6-14 m apart with an A* path
on the costmap, and ``n_obstacles`` discs (people, a forklift) crossing that path timed to meet
the robot; the start/goal draws and the kidnapping (``kidnap_at_s``) are the simulator's
(:func:`slamkit.sim.navigation_world.start_goal_draws`, ``NavigationPlant.kidnap``), this module
supplies the A* route they are drawn with. The robot's map (``map: {source: ...}``, :mod:`slamkit.experiments.navigation_map`) is
the world's grid (``truth``) or built offline by slamkit's lidar SLAM on a mapping tour of the
world (``slam_tour``, 5 cm); the simulator keeps the true world either way.

Metrics per episode (units in the names): ``success`` (the stack stopped within
``goal_tolerance_m`` of the goal position and ``heading_tolerance_rad`` of its heading, by the
truth, without a collision), ``final_position_error_m``, ``final_heading_error_rad``,
``collision_static`` / ``collision_moving`` (0/1), ``min_clearance_static_m`` /
``min_clearance_moving_m``, ``time_s``, ``path_length_m``, ``localisation_error_mean_m`` /
``_max_m`` (estimate vs truth over the run), ``replans``, ``no_safe_stop_cycles``, and per layer
``<layer>_median_ms`` / ``<layer>_p99_ms`` with ``real_time_factor`` (simulated time over the
stack's compute time), and the benchmark's (:mod:`slamkit.experiments.navigation_benchmark`):
``timeout``, ``off_goal``, ``clearance_static_p5_m`` / ``clearance_moving_p5_m``,
``optimal_path_length_m``, ``optimal_time_s``, ``time_over_optimal``, ``path_over_optimal``,
``crossing_agents``, ``agent_speed_max_mps``, ``narrowest_passage_m``.

Seeds: ``scenarios.seeds`` are the development seeds, ``scenarios.evaluation`` the blocks a claim
is measured on; every run records its ``block`` (:mod:`slamkit.experiments.navigation_benchmark`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Callable, Literal, Mapping, Sequence

import numpy as np
import pydantic
from pydantic import BaseModel, Field

from slamkit.config import STRICT, YamlDocument, build, model_of, resolved
from slamkit.data.registry import path_of
from slamkit.errors import ConfigError
from slamkit.experiments.config_models import (PipelineConfig, PlainName, Seed, Seeds, _nested, _refuse_moved_keys,
                                               seed_list)
from slamkit.experiments.navigation_benchmark import (DEV_BLOCK, benchmark_markdown, block_of, benchmark_rows, difficulty_rows,
                                                     episode_benchmark_metrics, plot_benchmark, scenario_difficulty,
                                                     seed_blocks)
from slamkit.experiments.navigation_map import MapSourceConfig, RobotMap, robot_map
from slamkit.experiments.observers import PipelineObserver, StepSnapshot
from slamkit.experiments.pipeline import Pipeline, PipelineOutput, StepProgress
from slamkit.experiments.results import (ResultsFolder, RunRecord, markdown_table, paired_difference, summarise,
                                         summary_markdown)
from slamkit.geometry.angles import wrap_angle
from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.inflation import costmap
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.planning.astar import AStarPlanner
from slamkit.planning.grid_search import costmap_to_cell_cost
from slamkit.planning.protocols import PlanningProblem
from slamkit.sim.navigation_world import (NavigationPlant, NavigationScenario, passage_draws, start_goal_draws,
                                         world_map)
from slamkit.sim.social_force import crossing_traffic
from slamkit.systems.lidar_slam import LidarSlamConfig
from slamkit.systems.navigation import (MOVED_FIELDS, CommandStatus, NavigationCommand, NavigationConfig,
                                        NavigationStack, layer_timing_summary)


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
    stack = NavigationStack(robot.grid, nav_config, np.random.default_rng([scenario.seed, 2]))
    plant = NavigationPlant(scenario, rng, odometry_sigma_v_mps=config.odometry_sigma_v_mps,
                            odometry_sigma_omega_radps=config.odometry_sigma_omega_radps,
                            lidar_blind_boxes_m=np.asarray(config.lidar_blind_boxes_m, float).reshape(-1, 4))
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
        #: MCL updates that injected particles (augmented MCL; 0 when it is off)
        "localisation_injections": float(stack.mcl.injections),
        **layer_timing_summary(stack.timings_s),
        "real_time_factor": float(ts[-1] / max(compute_s, 1e-9)),
        **episode_benchmark_metrics(
            success=success, collision_static=hit_static, collision_moving=hit_moving,
            reached_by_belief=stack.reached, clearance_static_m=clear_static, clearance_moving_m=clear_moving,
            time_s=time_s, path_length_m=path_length_m, difficulty=scenario_difficulty(scenario, r, field_m),
            max_speed_mps=nav_config.cruise_speed_mps),
    }
    return Episode(scenario.name, scenario.name.rsplit("_", 1)[0], scenario.seed, variant,
                   np.array(ts), true, est, metrics, loc_err)


# --------------------------------------------------------------------------- the pipeline


def _section(value: Any, where: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ConfigError(f"{where}: expected a mapping, got {type(value).__name__}")
    return dict(value)


def _variants(config: Mapping[str, Any]) -> list[tuple[str, NavigationConfig, EpisodeConfig]]:
    """:func:`variants_of` of a plain config mapping (the model's check of its sections, a
    notebook's or a test's mapping): its ``navigation``, ``episode`` and ``variants`` sections
    (no ``variants``: one called ``nominal``)."""
    variants = config.get("variants", [{"name": "nominal"}])
    if not isinstance(variants, list):
        raise ConfigError("variants: expected a list of {name, navigation, episode}")
    return variants_of(config.get("navigation"), config.get("episode"), variants)


def variants_of(navigation: Mapping[str, Any] | None, episode: Mapping[str, Any] | None,
                variants: "Sequence[NavigationVariant | Mapping[str, Any]]"
                ) -> list[tuple[str, NavigationConfig, EpisodeConfig]]:
    """(name, stack config, episode config) per variant: the base ``navigation``/``episode``
    sections with each variant's keys on top -- a key the variant names replaces the base's
    value as a whole (a nested section too: ``planning: {...}`` in a variant replaces the base's
    ``planning`` mapping, over the section's defaults) -- built by :func:`slamkit.config.build`."""
    base_nav = _section(navigation, "navigation")
    base_ep = _section(episode, "episode")
    plain = [v.model_dump(exclude_none=True) if isinstance(v, BaseModel) else v for v in variants]
    out = []
    for i, v in enumerate(plain):
        v = _section(v, f"variants.{i}")
        name = str(v.get("name", f"variant_{i}"))
        nav = build(NavigationConfig, {**base_nav, **_section(v.get("navigation"), f"variants.{name}.navigation")},
                    f"variants.{name}.navigation", moved=MOVED_FIELDS)
        ep = build(EpisodeConfig, {**base_ep, **_section(v.get("episode"), f"variants.{name}.episode")},
                   f"variants.{name}.episode")
        out.append((name, nav, ep))
    names = [n for n, _, _ in out]
    for v in plain:
        other = v.get("paired_with") if isinstance(v, Mapping) else None
        if other is not None and (other not in names or other == v.get("name")):
            raise ConfigError(f"variants.{v.get('name')}.paired_with: {other!r} is not another variant ({names})")
    return out


def willow_yaml(spec: str | None) -> str:
    """The Willow map YAML: a path, or the dataset registry's ``willow`` entry (None)."""
    if spec is None or spec == "willow":
        return str(path_of("willow", "maps_ros/willow-2010-02-18-0.10.yaml"))
    return str(spec)


def scenarios_of(scenarios: "NavigationScenarios") -> list[NavigationScenario]:
    """Every world x seed (development, then evaluation blocks) of a config's ``scenarios``."""
    seeds = [seed for _block, seed in seed_blocks_of(scenarios)]
    willow = willow_yaml(scenarios.willow_map) if "willow" in scenarios.worlds else None
    return [make_navigation_scenario(seed, w, willow, n_obstacles=scenarios.n_obstacles, agents=scenarios.agents)
            for w in scenarios.worlds for seed in seeds]


def seed_blocks_of(scenarios: "NavigationScenarios") -> list[tuple[str, int]]:
    """(block, seed) of every episode seed: ``scenarios.seeds`` as the development block, then
    the ``scenarios.evaluation`` blocks (:mod:`slamkit.experiments.navigation_benchmark`)."""
    evaluation = None if scenarios.evaluation is None else scenarios.evaluation.model_dump()
    return seed_blocks(seed_list(scenarios.seeds), evaluation)


#: what the paired table of :func:`paired_variants_markdown` compares
PAIRED_METRICS = ("success", "collision_static", "collision_moving", "min_clearance_static_m", "time_s",
                  "path_length_m", "localisation_error_max_m")


def paired_variants_markdown(variants: "Sequence[NavigationVariant | Mapping[str, Any]]",
                             episodes: list[Episode]) -> str:
    """Per world, every variant (of a config's ``variants``) with ``paired_with`` minus that
    variant, paired by seed (both saw the same scenario and noise seed): mean difference, its 95%
    CI and the Wilcoxon p-value of :func:`slamkit.experiments.results.paired_difference`; time
    over the seeds both reached."""
    plain = [v.model_dump(exclude_none=True) if isinstance(v, BaseModel) else v for v in variants]
    pairs = [(str(v["name"]), str(v["paired_with"])) for v in plain
             if isinstance(v, Mapping) and v.get("paired_with")]
    by = {(e.world, e.variant, e.seed): e.metrics for e in episodes}
    rows = []
    for world in dict.fromkeys(e.world for e in episodes):
        for a, b in pairs:
            seeds = sorted(s for (w, v, s) in by if w == world and v == a and (w, b, s) in by)
            for m in PAIRED_METRICS if seeds else ():
                d = paired_difference([by[world, a, s][m] for s in seeds], [by[world, b, s][m] for s in seeds])
                lo, hi = d["ci95"]
                rows.append([world, f"{a} - {b}", m, d["pairs"], d["mean_difference"],
                             f"[{lo:.3g}, {hi:.3g}]", d["wilcoxon_p"]])
    if not rows:
        return ""
    return "## Paired by seed\n\n" + markdown_table(
        ["world", "variants", "metric", "pairs", "mean difference", "95% CI", "Wilcoxon p"], rows) + "\n"


def runs_of(episodes: list[Episode], blocks: Mapping[int, str] | None = None) -> list[RunRecord]:
    """The episodes as run records; ``params.block`` says which seed block each came from."""
    blocks = blocks or {}
    return [RunRecord(e.world, e.variant, dict(e.metrics), seed=e.seed,
                      params={"scenario": e.scenario, "block": blocks.get(e.seed, DEV_BLOCK)})
            for e in episodes]


def report_markdown(config: "NavigationPipeline", episodes: list[Episode], summary: list[dict],
                    maps: Mapping[str, RobotMap] | None = None, benchmark: str = "") -> str:
    text = f"# Navigation: {config.name or 'navigation'}\n\n" + benchmark
    text += "## Every metric\n\n"
    text += ("MCL (likelihood field, 500 particles) on simulated lidar and wheel odometry, each "
             "variant's global planner (A* by default) and local planner on the estimated pose among "
             "lidar-tracked obstacles. "
             "Success: stopped within the goal tolerance (position and heading, by the truth) "
             "without a collision. Mean ± half the 95% CI over seeds, per world, variant and seed set "
             "(development or evaluation).\n\n")
    text += map_source_markdown(maps or {})
    lead = ["dataset", "estimator"] + (["seeds"] if summary and "seeds" in summary[0] else [])
    text += summary_markdown(summary, lead) + "\n\n" + paired_variants_markdown(config.variants, episodes) + "\n## Runs\n\n"
    rows = [[e.scenario, e.variant, e.metrics["success"], e.metrics["final_position_error_m"],
             e.metrics["collision_static"], e.metrics["collision_moving"], e.metrics["time_s"],
             e.metrics["localisation_error_max_m"], e.metrics["replans"]] for e in episodes]
    text += markdown_table(["scenario", "variant", "success", "final error (m)", "static hit", "moving hit",
                            "time (s)", "max loc. error (m)", "replans"], rows) + "\n"
    return text


def map_source_markdown(maps: Mapping[str, RobotMap]) -> str:
    """The robot's map: its source and, for a built map, its scores per scenario."""
    sources = sorted({m.source for m in maps.values()})
    if not maps or sources == ["truth"]:
        return "Robot's map: the world's own grid (the ground truth; Willow: the ROS map).\n\n"
    text = (f"Robot's map: {', '.join(sources)} (slamkit.experiments.navigation_map): lidar SLAM on a "
            "seeded mapping tour of each world, rasterised at 5 cm in SLAM's own frame; the simulator "
            "keeps the true world. Occupied cells matched within one cell on the observed cells:\n\n")
    keys = ("map_precision_1cell", "map_recall_1cell", "map_free_coverage", "map_tour_ate_m",
            "map_tour_error_max_m", "map_tour_length_m", "map_build_s")
    rows = [[name] + [m.metrics.get(k, float("nan")) for k in keys] for name, m in maps.items()]
    return markdown_table(["scenario", "precision", "recall", "free coverage", "tour ATE (m)",
                           "tour max error (m)", "tour length (m)", "build (s)"], rows) + "\n\n"


def plot(plots: Path, episodes: list[Episode], scenarios: Mapping[str, NavigationScenario]) -> None:
    """``trajectory.png``: per world, its first scenario on the whole map (truth and estimate of
    every variant, the crossing obstacles' lines, start and goal) above the localisation error
    along the run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    firsts = list({e.world: e.scenario for e in reversed(episodes)}.items())[::-1]
    fig, axes = plt.subplots(2, len(firsts), figsize=(5.5 * len(firsts), 8.5), squeeze=False,
                             gridspec_kw={"height_ratios": [3, 1]})
    for col, (world, name) in enumerate(firsts):
        sc, ax, err = scenarios[name], axes[0, col], axes[1, col]
        g = sc.grid
        extent = (g.origin_xy_m[0], g.origin_xy_m[0] + g.width * g.resolution_m,
                  g.origin_xy_m[1], g.origin_xy_m[1] + g.height * g.resolution_m)
        ax.imshow(g.occupied, origin="lower", extent=extent, cmap="Greys", alpha=0.8)
        for ep in (e for e in episodes if e.scenario == name):
            ax.plot(ep.true_xytheta[:, 0], ep.true_xytheta[:, 1], lw=1.5, label=f"{ep.variant} truth")
            ax.plot(ep.estimated_xytheta[:, 0], ep.estimated_xytheta[:, 1], "--", lw=1,
                    label=f"{ep.variant} estimate")
            err.plot(ep.t_s, 100.0 * ep.position_error_m(), lw=1, label=ep.variant)
        for route in sc.obstacles.routes_xy_m():
            ax.plot(route[:, 0], route[:, 1], color="tab:red", lw=3, alpha=0.4)
        ax.plot(*sc.start_xytheta[:2], "bo", ms=7)
        ax.plot(*sc.goal_xytheta[:2], "g*", ms=12)
        ax.set_title(f"{name}: truth and estimate (red: crossing obstacles)", fontsize=9)
        ax.set_aspect("equal")
        ax.legend(loc="best", fontsize=7)
        err.set_xlabel("time (s)")
        err.set_ylabel("position error (cm)")
        err.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(plots / "trajectory.png", dpi=100)
    plt.close(fig)


#: the most particles a snapshot carries (the viewer draws them all)
SNAPSHOT_MAX_PARTICLES = 500


def _frozen(a: Any, dtype: type = float) -> np.ndarray:
    """A read-only copy (a snapshot shares no array with the stack or the plant)."""
    out = np.array(a, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class NavigationScene:
    """What a recording of one episode draws once: the robot's map, the world's own grid (the
    same object when the robot's map is the world's), ``costmap_blocked`` (H, W) the free cells of
    the robot's map the inflated robot may not enter (the global planner's costmap without a
    chance margin), the goal pose and the robot's radius."""

    robot_map: OccupancyGrid
    true_map: OccupancyGrid
    costmap_blocked: np.ndarray
    goal_xytheta: np.ndarray
    robot_radius_m: float


@dataclass(frozen=True)
class NavigationSnapshot:
    """One control cycle of a navigation episode as the viewer draws it (issue 30, item 4): copied,
    read-only arrays, never the live stack or plant. The truth (``true_xytheta``, the crossing
    obstacles ``obstacles_xy_m`` / ``obstacles_radius_m`` of the episode's traffic at the stamp) beside the
    stack's belief (``estimate_xytheta``, ``covariance`` (3, 3), at most
    :data:`SNAPSHOT_MAX_PARTICLES` ``particles_xytheta``), its global ``path_xy_m`` (None before
    the first plan), the scan end points the map does not explain, the lidar tracks (ids,
    centres, radii, velocities), the decision (``command``, ``status``) and the local planner's
    candidates with their scores and ``chosen`` index, or the MPC's predicted horizon."""

    scene: NavigationScene
    true_xytheta: np.ndarray
    estimate_xytheta: np.ndarray
    covariance: np.ndarray
    particles_xytheta: np.ndarray
    path_xy_m: np.ndarray | None
    scan_unexplained_xy_m: np.ndarray
    track_ids: np.ndarray
    track_xy_m: np.ndarray
    track_radius_m: np.ndarray
    track_velocity_mps: np.ndarray
    obstacles_xy_m: np.ndarray
    obstacles_radius_m: np.ndarray
    command: np.ndarray
    status: CommandStatus
    candidates_xytheta: np.ndarray | None = None
    candidate_scores: np.ndarray | None = None
    chosen: int = -1
    mpc_horizon_xytheta: np.ndarray | None = None


def navigation_scene(scenario: NavigationScenario, stack: NavigationStack) -> NavigationScene:
    g = stack.grid
    return NavigationScene(g, scenario.grid, _frozen(~np.isfinite(stack.cell_cost(0)) & ~g.occupied, bool),
                           _frozen(scenario.goal_xytheta), float(stack.config.robot_radius_m))


def navigation_snapshot(scene: NavigationScene, scenario: NavigationScenario, stack: NavigationStack,
                        plant: NavigationPlant, t_s: float, decision: NavigationCommand) -> NavigationSnapshot:
    """The snapshot of the cycle that has just ended (read at once: the stack and plant move on)."""
    mean, cov = stack.current_pose()
    tracks = stack.tracks()
    # the plant's own traffic: social-force people react to this episode's robot, so the
    # scenario's template would draw them walking as if it were not there
    obs = plant.obstacles
    out = decision.output
    has_candidates = out is not None and out.candidates_xytheta is not None and len(out.candidates_xytheta) > 0
    return NavigationSnapshot(
        scene, _frozen(plant.world_xytheta_body), _frozen(mean), _frozen(cov),
        _frozen(stack.particles[:SNAPSHOT_MAX_PARTICLES]),
        None if stack.path is None else _frozen(stack.path), _frozen(stack.last_scan_points),
        _frozen(tracks.ids, int), _frozen(tracks.xy_m), _frozen(tracks.radius_m), _frozen(tracks.velocity_mps),
        _frozen(obs.position_at(t_s) if len(obs) else np.zeros((0, 2))),
        _frozen(obs.radius_m if len(obs) else np.zeros(0)),
        _frozen(decision.command), CommandStatus(decision.status),
        candidates_xytheta=_frozen(out.candidates_xytheta) if has_candidates else None,
        candidate_scores=_frozen(out.scores) if has_candidates and out.scores is not None else None,
        chosen=int(out.chosen) if has_candidates else -1,
        mpc_horizon_xytheta=(_frozen(out.predicted_xytheta) if out is not None and out.predicted_xytheta is not None
                             else None))


def _snapshots(observer: PipelineObserver, run_name: str, scenario: NavigationScenario):
    """An ``on_step`` that hands each cycle to a pipeline observer as a ``StepSnapshot`` whose
    state is a :class:`NavigationSnapshot` (its :class:`NavigationScene` built at the first cycle)."""
    counter = iter(range(10**9))
    scene: list[NavigationScene] = []

    def on_step(stack, plant, t_s, decision) -> None:
        if not scene:
            scene.append(navigation_scene(scenario, stack))
        observer.on_step(StepSnapshot("navigation", run_name, next(counter), t_s,
                                      navigation_snapshot(scene[0], scenario, stack, plant, t_s, decision)))
    return on_step


def run(config: NavigationPipeline, folder: ResultsFolder, progress: StepProgress,
        observer: PipelineObserver | None = None) -> PipelineOutput[list[Episode]]:
    """Pipeline ``navigation`` on its validated, resolved model: worlds x seeds x variants ->
    runs, summary, report, plots."""
    variants = variants_of(config.navigation, config.episode, config.variants)
    map_config = build(MapSourceConfig, config.map, "map")
    scenarios = scenarios_of(config.scenarios)
    advance = progress.task("navigation episodes", len(scenarios) * len(variants))
    watch = observer is not None and observer.wants_steps
    episodes = []
    maps: dict[str, RobotMap] = {}
    for i, sc in enumerate(scenarios):
        maps[sc.name] = robot = robot_map(sc, map_config, folder.path / "maps")
        for name, nav, ep in variants:
            hook = _snapshots(observer, f"{name}/{sc.name}", sc) if watch and i < config.record_scenarios else None
            episode = run_episode(sc, nav, ep, name, hook, robot)
            episodes.append(dataclasses.replace(episode, metrics={**episode.metrics, **robot.metrics}))
            advance(1)
    blocks = seed_blocks_of(config.scenarios)
    runs = runs_of(episodes, {seed: block for block, seed in blocks})
    # development and evaluation seeds never share a mean (the protocol of navigation_benchmark)
    summary = summarise(runs, lambda r: {"dataset": r.dataset, "estimator": r.estimator,
                                         "seeds": "development" if block_of(r) == DEV_BLOCK else "evaluation"})
    plot(folder.plots, episodes, {s.name: s for s in scenarios})
    rows, by_difficulty = benchmark_rows(runs), difficulty_rows(runs)
    plot_benchmark(folder.plots / "benchmark.png", rows, by_difficulty)
    evaluation = config.scenarios.evaluation
    protocol = {"dev_seeds": [s for b, s in blocks if b == DEV_BLOCK],
                "evaluation": None if evaluation is None else evaluation.model_dump()}
    text = benchmark_markdown(rows, by_difficulty, protocol)
    return PipelineOutput(runs, report_markdown(config, episodes, summary, maps, text), summary,
                          extra={"benchmark": {"protocol": protocol, "rows": rows, "by_difficulty": by_difficulty}},
                          payload=episodes)


# --- the config model (slamkit.experiments.config_models): checked before anything runs ---------

class NavigationEvaluation(BaseModel):
    """``blocks`` disjoint blocks of ``block_size`` consecutive seeds from ``start`` on: the
    seeds a claimed rate is measured on (slamkit.experiments.navigation_benchmark)."""

    model_config = STRICT
    start: Seed
    blocks: Annotated[int, Field(ge=1, le=100)] = 3
    block_size: Annotated[int, Field(ge=1, le=10_000)] = 30


class NavigationScenarios(BaseModel):
    model_config = STRICT
    worlds: Annotated[list[Literal["office", "warehouse", "willow", "passage"]], Field(min_length=1)] = ["office"]
    #: the development seeds (the ones failures are looked at and fixed on)
    seeds: Seeds = 3
    #: the evaluation blocks, disjoint from ``seeds`` (None: development seeds only)
    evaluation: NavigationEvaluation | None = None
    n_obstacles: Annotated[int, Field(ge=0, le=20)] = 2
    #: the crossing traffic: constant-velocity shuttles or social-force people and forklifts
    #: (slamkit.sim.social_force.crossing_traffic)
    agents: Literal["constant_velocity", "social_force"] = "constant_velocity"
    #: world 'willow': the dataset registry's ``willow`` (default) or a map_server YAML path
    willow_map: str | None = None

    @pydantic.model_validator(mode="after")
    def _evaluation_is_fresh(self) -> "NavigationScenarios":
        if self.evaluation is not None:
            try:
                seed_blocks(seed_list(self.seeds), self.evaluation.model_dump())
            except ConfigError as exc:
                raise ValueError(str(exc)) from None
        return self


class NavigationVariant(BaseModel):
    model_config = STRICT
    name: PlainName
    #: another variant's name: the report adds this one's differences to it, paired by seed
    paired_with: PlainName | None = None
    navigation: dict[str, Any] = {}
    episode: dict[str, Any] = {}


class NavigationPipeline(PipelineConfig):
    pipeline: Literal["navigation"]
    scenarios: NavigationScenarios = NavigationScenarios()
    #: NavigationConfig fields (slamkit.systems.navigation) shared by every variant
    navigation: dict[str, Any] = {}
    #: EpisodeConfig fields (slamkit.experiments.navigation) shared by every variant
    episode: dict[str, Any] = {}
    variants: Annotated[list[NavigationVariant], Field(min_length=1)] = [NavigationVariant(name="nominal")]
    record_scenarios: Annotated[int, Field(ge=0, le=1000)] = 1
    #: the robot's map: MapSourceConfig fields (slamkit.experiments.navigation_map)
    map: dict[str, Any] = {}

    def check_options(self, config: dict[str, Any], doc: YamlDocument | None, source: str) -> None:
        # the base sections and every variant's overrides against the models of NavigationConfig
        # (its nested sections included) and EpisodeConfig, each error with its YAML line; a key
        # of the former flat NavigationConfig names the section it moved into (MOVED_FIELDS)
        sections: list[tuple[tuple, dict[str, Any], type]] = [
            (("navigation",), self.navigation, NavigationConfig), (("episode",), self.episode, EpisodeConfig)]
        for i, variant in enumerate(self.variants):
            sections += [(("variants", i, "navigation"), variant.navigation, NavigationConfig),
                         (("variants", i, "episode"), variant.episode, EpisodeConfig)]
        for prefix, values, cls in sections:
            if cls is NavigationConfig:
                _refuse_moved_keys(values, prefix, MOVED_FIELDS, doc, source)
            _nested(model_of(cls), values, doc, source, prefix)
        _variants(config)  # builds every variant's configs: the dataclasses' own checks
        # the map section's fields checked with their YAML line, then the config built (its
        # own checks: source, unknown, the nested lidar-SLAM config)
        _nested(model_of(MapSourceConfig), self.map, doc, source, ("map",))
        build(MapSourceConfig, config.get("map"), "map")

    def resolve(self, config: dict[str, Any]) -> dict[str, Any]:
        # the shared sections spelt out with NavigationConfig's, EpisodeConfig's and
        # MapSourceConfig's defaults (the map's lidar-SLAM mapping with LidarSlamConfig's); a
        # variant's sections stay overrides: each of its keys replaces the base's as a whole, over
        # base values that equal what build filled in before, so every variant builds the same
        robot_map = resolved(MapSourceConfig, config.get("map"), "map")
        robot_map["slam"] = resolved(LidarSlamConfig, robot_map["slam"], "map.slam")
        return {**config,
                "navigation": resolved(NavigationConfig, config.get("navigation"), "navigation", moved=MOVED_FIELDS),
                "episode": resolved(EpisodeConfig, config.get("episode"), "episode"),
                "map": robot_map}


PIPELINE: Pipeline[NavigationPipeline, list[Episode]] = Pipeline(
    "navigation", run, NavigationPipeline, list[Episode],
    "MCL + A* + a local planner on the estimated pose, closed through the simulator")
