"""One image sequence through :class:`slamkit.systems.visual_odometry.VisualOdometry`, timed and
scored against its ground truth: :func:`run_vo`, :func:`score` (the metric vocabulary of
:mod:`slamkit.metrics`) and the payload the viewer gets."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from slamkit.data.formats.image import read_image
from slamkit.data.formats.image_sequence import ImageSequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.metrics.trajectory_score import score_trajectory
from slamkit.systems.visual_odometry import FrameResult, VisualOdometry, VisualOdometryConfig, VoEstimate


@dataclass(frozen=True)
class VoRun:
    """One VO run on one sequence: the system's output, its per-frame results and its scores."""

    sequence: ImageSequence
    label: str
    config: VisualOdometryConfig
    frames: tuple[FrameResult, ...]
    estimate: VoEstimate
    metrics: dict[str, float] = field(default_factory=dict)

    def trajectory(self) -> Trajectory:
        return Trajectory.from_matrices(self.estimate.stamps_s, self.estimate.world_T_camera)


def run_vo(sequence: ImageSequence, config: VisualOdometryConfig = VisualOdometryConfig(), label: str = "vo",
           on_frame=None) -> VoRun:
    """Feed every frame of ``sequence`` to a fresh system and score it."""
    system = VisualOdometry(sequence.camera, config)
    frames = []
    for stamp, path in zip(sequence.stamps_s, sequence.images):
        try:
            frames.append(system.step(float(stamp), read_image(path)))
        except DataError as exc:  # the system names the frame; the user needs its file
            raise DataError(str(exc), path) from None
        if on_frame is not None:
            on_frame(frames[-1])
    run = VoRun(sequence, label, config, tuple(frames), system.estimate())
    return replace(run, metrics=score(run))


def score(run: VoRun) -> dict[str, float]:
    frames = run.frames
    with_matches = [f for f in frames if f.num_matches]
    metrics: dict[str, float] = {
        "inlier_ratio": float(np.mean([f.num_inliers / f.num_matches for f in with_matches])) if with_matches else 0.0,
        "time_per_frame_ms": float(np.median([f.frontend_ms + f.ba_ms for f in frames])),
        "frontend_median_ms": float(np.median([f.frontend_ms for f in frames])),
        "keypoints_mean": float(np.mean([f.num_keypoints for f in frames])),
        "matches_mean": float(np.mean([f.num_matches for f in with_matches])) if with_matches else 0.0,
        "inliers_mean": float(np.mean([f.num_inliers for f in with_matches])) if with_matches else 0.0,
        "tracked_points_mean": float(np.mean([f.tracked_points for f in frames[2:]])) if len(frames) > 2 else 0.0,
        "num_frames": float(len(frames)),
        "map_points": float(len(run.estimate.world_p)),
    }
    gt = run.sequence.ground_truth
    if gt is not None and len(frames) >= 3:
        metrics.update(score_trajectory(gt, run.trajectory(), "sim3", extra_aligns=("se3",), rotation_unit="deg",
                                        rpe_delta=1, rpe_delta_unit="frames", rpe_align="sim3"))
        metrics["distance_m"] = float(gt.path_length_m())
        metrics["ate_percent_of_distance"] = 100.0 * metrics["ate_rmse_m"] / max(metrics["distance_m"], 1e-9)
    return metrics


@dataclass(frozen=True)
class VoPayload:
    """What the recorder draws: every run (images are read again from ``sequence.images``)."""

    runs: tuple[VoRun, ...]
    max_recorded_frames: int = 60
