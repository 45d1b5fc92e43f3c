"""Monocular visual odometry as an experiment: the ``visual_odometry`` pipeline.

A sequence is a registry name (``kitti-vo-a``) or ``{name, images: DIR, calib: FILE, poses:
FILE, times: FILE}`` in the KITTI odometry layout (``calib.txt`` P0 = the left camera's 3x4
projection, ``poses.txt`` camera-to-world ground truth, stamps = frame index x 0.1 s unless
``times`` are given), read by :mod:`slamkit.data.formats.image_sequence`. The system
(:class:`slamkit.systems.visual_odometry.VisualOdometry`) is fed the frames; this module scores it and writes ``trajectories/<name>.tum`` (the BA run;
``<name>_no_ba.tum`` for the run without bundle adjustment when ``compare_without_ba``).

Metrics per run (the vocabulary of :mod:`slamkit.metrics`): ``ate_rmse_m`` after a Sim(3)
Umeyama alignment (monocular scale is unobservable, so this is the figure that means something;
``sim3_scale`` its scale, ``ate_rot_rmse_deg``), ``ate_se3_rmse_m`` (without scale: only
meaningful where the scale is known, reported for completeness), ``rpe_rmse_m`` and
``rpe_rot_rmse_deg`` (frame to frame after the Sim(3) alignment), ``ate_percent_of_distance``,
``inlier_ratio`` (essential-matrix inliers / putative matches, mean over frames), ``time_per_frame_ms`` (front-end + BA, median) and the course's per-frame numbers
as means (``keypoints_mean``, ``matches_mean``, ``inliers_mean``, ``tracked_points_mean``).

Modules (a pipeline is a small package, issue 30): :mod:`.config` (the config model), :mod:`.vo`
(:func:`run_vo` and :func:`score`: one sequence through the system, scored), :mod:`.run` (the
pipeline's sequences) and :mod:`.report` (Markdown and plots); this module composes them into
``PIPELINE``.
"""

from __future__ import annotations

from slamkit.experiments.pipeline import Pipeline
from slamkit.experiments.visual_odometry.config import ImageSequenceModel, VisualOdometryPipeline
from slamkit.experiments.visual_odometry.vo import VoPayload, VoRun, run_vo, score
from slamkit.experiments.visual_odometry.run import run as _run

__all__ = ["ImageSequenceModel", "PIPELINE", "VisualOdometryPipeline", "VoPayload", "VoRun", "run_vo", "score"]


PIPELINE: Pipeline[VisualOdometryPipeline, VoPayload] = Pipeline(
    "visual_odometry", _run, VisualOdometryPipeline, VoPayload,
    "monocular visual odometry with sliding-window bundle adjustment on image sequences")
