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
supplies the A* route they are drawn with. The robot's map (``map: {source: ...}``, :mod:`.map_source`) is
the world's grid (``truth``) or built offline by slamkit's lidar SLAM on a mapping tour of the
world (``slam_tour``, 5 cm); the simulator keeps the true world either way.

Metrics per episode (units in the names): ``success`` (the stack stopped within
``goal_tolerance_m`` of the goal position and ``heading_tolerance_rad`` of its heading, by the
truth, without a collision), ``final_position_error_m``, ``final_heading_error_rad``,
``collision_static`` / ``collision_moving`` (0/1), ``min_clearance_static_m`` /
``min_clearance_moving_m``, ``time_s``, ``path_length_m``, ``localisation_error_mean_m`` /
``_max_m`` (estimate vs truth over the run), ``replans``, ``no_safe_stop_cycles``, and per layer
``<layer>_median_ms`` / ``<layer>_p99_ms`` with ``real_time_factor`` (simulated time over the
stack's compute time), and the benchmark's (:mod:`.benchmark`):
``timeout``, ``off_goal``, ``clearance_static_p5_m`` / ``clearance_moving_p5_m``,
``optimal_path_length_m``, ``optimal_time_s``, ``time_over_optimal``, ``path_over_optimal``,
``crossing_agents``, ``agent_speed_max_mps``, ``narrowest_passage_m``, ``oracle_delay_s`` /
``oracle_feasible`` (shuttle traffic: how much later a robot that knows the traffic's future
reaches the end of the path).

Seeds: ``scenarios.seeds`` are the development seeds, ``scenarios.evaluation`` the blocks a claim
is measured on; every run records its ``block`` (:mod:`.benchmark`).

Modules (a pipeline is a small package, issue 30): :mod:`.episode` (the scenario, the loop, the
episode's metrics), :mod:`.config` (the config model and the variants' configs), :mod:`.map_source`
(the robot's map: the truth, or the map the system :mod:`slamkit.systems.slam_map` builds on a
simulated mapping tour, scored against the truth and cached in the results folder),
:mod:`.benchmark` (the protocol and its tables), :mod:`.snapshot` (what the viewer gets),
:mod:`.run` and :mod:`.report`; this module composes them into ``PIPELINE`` and re-exports the
names callers use (``run_episode``, ``make_navigation_scenario``, ``_variants`` ...).
"""

from __future__ import annotations

from slamkit.experiments.navigation.config import (NavigationEvaluation, NavigationPipeline, NavigationScenarios,
                                                   NavigationVariant, _variants, variants_of)
from slamkit.experiments.navigation.episode import Episode, EpisodeConfig, make_navigation_scenario, run_episode
from slamkit.experiments.navigation.map_source import MapSourceConfig, RobotMap, robot_map
from slamkit.experiments.navigation.report import (PAIRED_METRICS, map_source_markdown, paired_variants_markdown,
                                                   plot, report_markdown)
from slamkit.experiments.navigation.run import runs_of, scenarios_of, seed_blocks_of, willow_yaml
from slamkit.experiments.navigation.run import run as _run
from slamkit.experiments.navigation.snapshot import (SNAPSHOT_MAX_PARTICLES, NavigationScene, NavigationSnapshot,
                                                     _snapshots, navigation_scene, navigation_snapshot)
from slamkit.experiments.pipeline import Pipeline
from slamkit.sim.navigation_world import NavigationScenario  # where callers of the former module found it

__all__ = ["Episode", "EpisodeConfig", "MapSourceConfig", "NavigationEvaluation", "NavigationPipeline",
           "NavigationScenario", "NavigationScenarios", "NavigationScene", "NavigationSnapshot",
           "NavigationVariant", "PAIRED_METRICS", "PIPELINE", "RobotMap", "SNAPSHOT_MAX_PARTICLES",
           "_snapshots", "_variants", "make_navigation_scenario", "map_source_markdown", "navigation_scene",
           "navigation_snapshot", "paired_variants_markdown", "plot", "report_markdown", "robot_map",
           "run_episode", "runs_of", "scenarios_of", "seed_blocks_of", "variants_of", "willow_yaml"]


PIPELINE: Pipeline[NavigationPipeline, list[Episode]] = Pipeline(
    "navigation", _run, NavigationPipeline, list[Episode],
    "MCL + A* + a local planner on the estimated pose, closed through the simulator")
