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

Modules (a pipeline is a small package, issue 30): :mod:`.episode` (the scenario, the loop, the
metrics), :mod:`.config` (the config model), :mod:`.run` (controllers x scenarios) and
:mod:`.report` (Markdown and plots); this module composes them into ``PIPELINE`` and re-exports
the names callers use.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from slamkit.experiments.closed_loop.config import LocalPlanningPipeline, LocalPlanningScenarios
from slamkit.experiments.closed_loop.episode import (ClosedLoopConfig, ControlStep, Episode, Observer, Scenario,
                                                     clearance_m, episode_metrics, make_scenario, perceive, replan,
                                                     run_episode)
from slamkit.experiments.closed_loop.report import plot, report_markdown
from slamkit.experiments.closed_loop.run import (LocalPlanningSnapshot, compare, episodes_to_runs,
                                                 scenario_list)
from slamkit.experiments.closed_loop.run import run as _run_kind
from slamkit.experiments.pipeline import Pipeline
from slamkit.experiments.pipeline import run_pipeline as _run

__all__ = ["ClosedLoopConfig", "ControlStep", "Episode", "LocalPlanningPipeline", "LocalPlanningScenarios",
           "LocalPlanningSnapshot", "Observer", "PIPELINE", "Scenario", "clearance_m", "compare", "episode_metrics",
           "episodes_to_runs", "make_scenario", "perceive", "plot", "replan", "report_markdown", "run_episode",
           "run_pipeline", "scenario_list"]


def run_pipeline(config: Mapping[str, Any], out_dir: str | Path, observer_factory=None) -> dict[str, Any]:
    """Run the comparison and write the results folder; returns the results.json dict.
    ``observer_factory`` as in ``slamkit.experiments.pipeline.run_pipeline`` (e.g.
    ``slamkit.viz.pipelines.observer_for``) adds ``recording.rrd``."""
    cfg = dict(config)
    cfg.setdefault("pipeline", "local_planning")
    return _run(cfg, out_dir, progress=False, observer_factory=observer_factory).results


PIPELINE: Pipeline[LocalPlanningPipeline, list[Episode]] = Pipeline(
    "local_planning", _run_kind, LocalPlanningPipeline, list[Episode],
    "controllers x seeded closed-loop scenarios")
