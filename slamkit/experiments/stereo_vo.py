"""Stereo bundle adjustment on real KITTI 00 stereo features (the gtsam wheel's
``VO_*00s.txt``, registry ``kitti00-stereo-features``), scored against the KITTI 00 ground truth
(``kitti00-gt``) beside ORB-SLAM's estimate (``kitti00-orbslam``) on the same frames, in the same
run, with the same metrics.

Pose id i of the feature files is KITTI 00 frame i (id 0 is the origin; id 1 is 0.68 m ahead, as
ORB-SLAM's second pose is), so frames 0..76 are compared. Stereo has
metric scale: the headline ``ate_rmse_m`` is after an SE(3) Umeyama alignment (no scale);
``ate_sim3_rmse_m`` is given too; ``rpe_rmse_m`` / ``rpe_rot_rmse_deg`` frame to frame.
KITTI's drift metric needs 100-800 m segments; 77 frames cover ~70 m, so the drift is computed
over 10-50 m segments (``drift_percent_10_50m``, ``drift_deg_per_100m_10_50m``). ``initial`` is
the feature file's own VO estimate (the starting point), ``stereo_ba`` the GTSAM result.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from slamkit.backend.bundle_adjustment import BundleAdjustmentConfig, stereo_bundle_adjust
from slamkit.data import registry
from slamkit.data.formats.gtsam_vo import StereoVoData, read_stereo_vo
from slamkit.data.formats.kitti import read_kitti
from slamkit.data.trajectory import Trajectory
from slamkit.metrics.trajectory_score import score_trajectory

SHORT_SEGMENTS_M = (10.0, 20.0, 30.0, 40.0, 50.0)


@dataclass(frozen=True)
class StereoVoReport:
    frames: np.ndarray                   #: KITTI 00 frame numbers compared
    metrics: dict[str, dict[str, float]]  #: estimator ("initial", "stereo_ba", "orb_slam") -> metrics
    stereo_ba_s: float
    initial_error: float
    final_error: float


def load_kitti00_stereo() -> StereoVoData:
    return read_stereo_vo(registry.path_of("kitti00-stereo-features", "VO_calibration00s.txt"),
                          registry.path_of("kitti00-stereo-features", "VO_camera_poses00s.txt"),
                          registry.path_of("kitti00-stereo-features", "VO_stereo_factors00s.txt"))


def _scores(gt: Trajectory, est: Trajectory) -> dict[str, float]:
    return score_trajectory(gt, est, "se3", extra_aligns=("sim3",), rotation_unit="deg", rpe_delta=1,
                            rpe_delta_unit="frames", drift_lengths_m=SHORT_SEGMENTS_M, drift_step_frames=1,
                            drift_suffix="_10_50m")


def stereo_ba_kitti00(config: BundleAdjustmentConfig = BundleAdjustmentConfig(max_iterations=30)) -> StereoVoReport:
    data = load_kitti00_stereo()
    row = {int(p): k for k, p in enumerate(data.pose_ids)}
    t0 = time.perf_counter()
    res = stereo_bundle_adjust(data.world_T_camera, np.array([row[int(p)] for p in data.obs_pose]),
                               data.obs_landmark, data.obs_uL_uR_v, data.obs_camera_p,
                               (data.fx, data.fy, data.skew, data.cx, data.cy, data.baseline_m), fixed=(0,),
                               config=config)
    elapsed = time.perf_counter() - t0
    frames = data.pose_ids
    times = registry.path_of("kitti00-gt", "KITTI_00_gt_times.txt")
    gt_all = read_kitti(registry.path_of("kitti00-gt", "KITTI_00_gt.txt"), times)
    orb_all = read_kitti(registry.path_of("kitti00-orbslam"), times)
    gt = gt_all.subset(frames)
    stamps = gt.stamps_s
    estimates = {"initial": Trajectory.from_matrices(stamps, data.world_T_camera),
                 "stereo_ba": Trajectory.from_matrices(stamps, res.world_T_camera),
                 "orb_slam": orb_all.subset(frames)}
    metrics = {name: _scores(gt, est) for name, est in estimates.items()}
    return StereoVoReport(frames, metrics, elapsed, res.initial_error, res.final_error)
