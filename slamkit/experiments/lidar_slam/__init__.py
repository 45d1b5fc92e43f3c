"""The ``lidar_slam`` pipeline: :class:`slamkit.systems.lidar_slam.LidarSlam` fed simulated grid
worlds and recorded laser logs, scored and reported. The SLAM system itself (scan matching,
keyframes, loop closure, pose graph, map) lives in ``slamkit.systems.lidar_slam``; this module
only feeds it a Sequence, times it and scores what it returns.

Simulated worlds (``worlds``): the world's ground truth scores the keyframes -- ``ate_odometry_m``
(wheel odometry), ``ate_frontend_m`` (chained scan matches, before loop closure), ``ate_rmse_m``
(after loop closure), all RMSE over the keyframes after SE(2) alignment; ``ate_reduction`` =
before / after -- and the world's grid scores the map: ``map_iou``, ``map_precision``,
``map_recall`` (``map_frontend_iou`` of the front-end map) with IoU as defined in
``slamkit.maps.log_odds`` (occupied cells, p > 0.5, against the truth max-pooled to the map
resolution, on the cells the map observed), the maps built after the SE(2) alignment ATE uses.
Optionally ``false_loop_closures`` wrong edges (keyframes more than 10 m apart claimed to
coincide) are injected before the final solve to show what the robust kernel is for, and
``mcl`` runs global localization on each built map.

Laser logs (``logs``: a registry name such as ``intel-log`` or ``{name, path, relations}``):
the relation error of Kuemmerle et al. 2009 (``slamkit.metrics.relations``) of the trajectory of
every scan, stamped with the scans' ipc timestamps, and of the raw odometry; ``real_time_factor``
(log duration / processing time), ``time_total_s``, time per scan, the process's peak memory,
loop-closure counts. The report sets them beside the published numbers (:data:`PUBLISHED`);
``plots/`` holds each map at the configured resolution with the trajectory over it and the time
per scan along the log.

``run(config, folder, progress, observer=None)`` is the pipeline kind; the observer (the Rerun
recorder, ``slamkit.viz.lidar_slam``) gets ``on_step`` per keyframe (when it ``wants_steps``)
with a :class:`LidarSlamSnapshot` as the state and, from the runner, ``on_output`` with the
``PipelineOutput`` whose ``payload`` is the list of :class:`LidarSlamResult` of every run.

Where things live (issue 30; a pipeline is a small package): :mod:`.config` (the config model
:class:`LidarSlamPipeline`; ``slam``, ``mcl`` and ``logs`` entries become LidarSlamConfig,
:class:`MclCheckConfig` and :class:`LogEntry` through :func:`slamkit.config.build`), :mod:`.slam`
(:func:`run_slam`: one sequence through the system, timed and scored, and the published figures),
:mod:`.mcl_check` (global localization on a built map), :mod:`.run` (the pipeline's worlds x seeds
and logs; worlds are grid scenarios, :func:`slamkit.sim.scenario.scenario_from_dict`) and
:mod:`.report` (Markdown and plots); keyframe ATE is
:func:`slamkit.metrics.trajectory_score.ate_at_stamps_m` (through ``score_trajectory``). This
module composes them into ``PIPELINE`` and re-exports the names callers use.
"""

from __future__ import annotations

from slamkit.experiments.lidar_slam.config import (LidarSlamPipeline, LogEntry, LogEntryModel, MclCheckConfig,
                                                   log_entry, slam_section_for)
from slamkit.experiments.lidar_slam.mcl_check import localize_on_map
from slamkit.experiments.lidar_slam.report import _scale_bar_m, log_map_figure, log_map_title, report_markdown
from slamkit.experiments.lidar_slam.run import _sim_parts, _simulate, first_seconds, trim_to_free_space
from slamkit.experiments.lidar_slam.run import run as _run
from slamkit.experiments.lidar_slam.slam import (BAD_RELATION_M, CARTOGRAPHER_REALTIME_FACTOR, PUBLISHED,
                                                 LidarSlamResult, LidarSlamSnapshot, align_se2, false_loop_edges,
                                                 run_slam)
from slamkit.experiments.pipeline import Pipeline

__all__ = ["BAD_RELATION_M", "CARTOGRAPHER_REALTIME_FACTOR", "LidarSlamPipeline", "LidarSlamResult",
           "LidarSlamSnapshot", "LogEntry", "LogEntryModel", "MclCheckConfig", "PIPELINE", "PUBLISHED",
           "_scale_bar_m", "_sim_parts", "_simulate", "align_se2", "false_loop_edges", "first_seconds",
           "localize_on_map", "log_entry", "log_map_figure", "log_map_title", "report_markdown", "run_slam",
           "slam_section_for", "trim_to_free_space"]


PIPELINE: Pipeline[LidarSlamPipeline, list[LidarSlamResult]] = Pipeline(
    "lidar_slam", _run, LidarSlamPipeline, list[LidarSlamResult],
    "lidar SLAM on simulated grid worlds x seeds and on recorded laser logs, x robust kernels x motion priors")
