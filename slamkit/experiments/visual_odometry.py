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
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from slamkit.config import build
from slamkit.data.formats.image import read_image
from slamkit.data.formats.image_sequence import ImageSequence, load_image_sequence
from slamkit.data.formats.tum import write_tum
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.experiments.config_models import VisualOdometryPipeline
from slamkit.experiments.observers import PipelineObserver
from slamkit.experiments.pipeline import Pipeline, PipelineOutput, StepProgress
from slamkit.experiments.results import ResultsFolder, RunRecord, markdown_table
from slamkit.metrics.ate import ate
from slamkit.metrics.trajectory_score import score_trajectory
from slamkit.paths import file_in
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
        "frontend_ms_median": float(np.median([f.frontend_ms for f in frames])),
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


def run(config: VisualOdometryPipeline, folder: ResultsFolder, progress: StepProgress,
        observer: PipelineObserver) -> PipelineOutput[VoPayload]:
    """Pipeline ``visual_odometry`` on its validated, resolved model: every sequence with bundle
    adjustment (and without, when ``compare_without_ba``), scored against its ground truth."""
    vo_config = build(VisualOdometryConfig, config.vo, "visual_odometry.vo")
    variants = [("mono_vo_ba", vo_config)]
    if config.compare_without_ba and vo_config.window:
        variants.append(("mono_vo", replace(vo_config, window=0)))
    sequences = [load_image_sequence(s if isinstance(s, str) else s.model_dump(exclude_none=True), config.max_frames)
                 for s in config.sequences]
    runs: list[VoRun] = []
    records: list[RunRecord] = []
    for seq in sequences:
        for label, cfg in variants:
            advance = progress.task(f"{seq.name} {label}", len(seq.images))
            result = run_vo(seq, cfg, label, on_frame=lambda _f: advance())
            runs.append(result)
            records.append(RunRecord(seq.name, label, result.metrics, params={"window": cfg.window}))
            stem = seq.name if label == "mono_vo_ba" else f"{seq.name}_no_ba"
            write_tum(file_in(folder.trajectories, stem, ".tum", "sequence name"), result.trajectory())
    _plot(folder.plots, runs)
    return PipelineOutput(records, _report(config, runs), payload=VoPayload(tuple(runs)))


_REPORT_METRICS = ("ate_rmse_m", "ate_percent_of_distance", "ate_se3_rmse_m", "rpe_rmse_m", "rpe_rot_rmse_deg",
                   "inlier_ratio", "keypoints_mean", "matches_mean", "inliers_mean", "tracked_points_mean",
                   "time_per_frame_ms")


def _report(config: VisualOdometryPipeline, runs: list[VoRun]) -> str:
    text = f"# Monocular visual odometry: {config.name or 'visual_odometry'}\n\n"
    text += ("Monocular scale is unobservable: the trajectory is in the unit of the first baseline, so "
             "ATE is reported after a Sim(3) alignment (`ate_rmse_m`); `ate_se3_rmse_m` (no scale) is only "
             "meaningful where the scale is known. `mono_vo_ba` runs the sliding-window bundle adjustment, "
             "`mono_vo` the same front-end without it.\n\n")
    header = ["sequence", "run", *_REPORT_METRICS]
    rows = [[r.sequence.name, r.label, *[r.metrics.get(m) for m in _REPORT_METRICS]] for r in runs]
    text += markdown_table(header, rows) + "\n\n## Per frame (first run)\n\n"
    if runs:
        first = runs[0]
        frame_rows = [[f.index, f.method, f.num_keypoints, f.num_matches, f.num_inliers, f.tracked_points,
                       f.new_points, f.frontend_ms, f.ba_ms] for f in first.frames]
        text += markdown_table(["frame", "method", "keypoints", "matches", "inliers", "tracked (PnP)", "new points",
                                "front-end ms", "BA ms"], frame_rows) + "\n"
    return text


def _plot(plots: Path, runs: list[VoRun]) -> None:
    if not runs:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for name in dict.fromkeys(r.sequence.name for r in runs):
        mine = [r for r in runs if r.sequence.name == name]
        gt = mine[0].sequence.ground_truth
        # a car's path is long and nearly straight: an equal-aspect top view shows one line, so
        # the lateral offset is drawn on its own scale beside the per-frame error
        fig, (top, err) = plt.subplots(1, 2, figsize=(11, 4.5))
        if gt is not None:
            top.plot(gt.world_t_body[:, 2], gt.world_t_body[:, 0], color="tab:green", lw=2.5, label="ground truth")
        for r in mine:
            est = r.trajectory()
            if gt is None:
                top.plot(est.world_t_body[:, 2], est.world_t_body[:, 0], label=r.label)
                continue
            result = ate(gt, est, "sim3")
            aligned = result.alignment.aligned
            top.plot(aligned.world_t_body[:, 2], aligned.world_t_body[:, 0],
                     label=f"{r.label} (Sim(3) aligned)")
            err.plot(result.errors_m, label=f"{r.label}: RMSE {result.translation_m.rmse:.3f} m")
        top.set_xlabel("z (m, forward)")
        top.set_ylabel("x (m, lateral; not to scale)")
        top.set_title(f"{name}: top view")
        top.legend(fontsize=8)
        err.set_xlabel("frame")
        err.set_ylabel("position error after Sim(3) alignment (m)")
        err.set_title("ATE per frame")
        if gt is not None:
            err.legend(fontsize=8)
        for ax in (top, err):
            ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(file_in(plots, f"trajectory_{name}", ".png", "sequence name"), dpi=110)
        plt.close(fig)

PIPELINE: Pipeline[VisualOdometryPipeline, VoPayload] = Pipeline(
    "visual_odometry", run, VisualOdometryPipeline, VoPayload,
    "monocular visual odometry with sliding-window bundle adjustment on image sequences")
