"""The ``visual_odometry`` pipeline's report: the metrics table and each sequence's trajectory plot."""

from __future__ import annotations

from pathlib import Path


from slamkit.experiments.results import markdown_table
from slamkit.experiments.visual_odometry.config import VisualOdometryPipeline
from slamkit.experiments.visual_odometry.vo import VoRun
from slamkit.metrics.ate import ate
from slamkit.paths import file_in


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
