"""Real-data checks of the camera systems beside a peer's estimate on the same frames, with the
same metrics (slamkit.metrics.score_trajectory). Only the tests use these, so they live here
(issue 30: they were slamkit.experiments.stereo_vo / visual_inertial, modules no pipeline used).

* stereo VO (:func:`slamkit.systems.stereo_vo.stereo_vo`) on the gtsam wheel's real KITTI 00
  stereo features (registry ``kitti00-stereo-features``) against the KITTI 00 ground truth
  (``kitti00-gt``) beside ORB-SLAM (``kitti00-orbslam``). Pose id i is KITTI 00 frame i, so frames
  0..76 are compared. Stereo has metric scale: ``ate_rmse_m`` is after an SE(3) alignment,
  ``ate_sim3_rmse_m`` beside it; KITTI's drift needs 100-800 m segments and 77 frames cover ~70 m,
  so the drift is over 10-50 m segments (``drift_percent_10_50m``, ``drift_deg_per_100m_10_50m``).
  ``initial`` is the feature file's own VO estimate, ``stereo_ba`` the GTSAM result.
* VIO (:func:`slamkit.systems.visual_inertial.run_vio`) on 30 s of real EuRoC V1_01_easy (the
  gtsam wheel's ``eqvio_processed_30s.csv``, ``euroc-v101-eqvio``) against the EuRoC ground truth
  (``v101-gt``) beside OpenVINS (``v101-openvins``). Camera-IMU extrinsics: the file's ``T_ci_*``
  (imu_T_camera, EuRoC cam0's T_BS); no time offset (hardware-synchronised; the ground truth is at
  the camera stamps, associated within 10 ms); IMU noise: EuRoC's ADIS16448 densities. VIO
  observes scale and, through gravity, roll and pitch; yaw and position are free, so both are
  scored after an SE(3) alignment (``ate_rmse_m``, ``ate_rot_rmse_deg``), RPE over 1 m where the
  path is longer than 2 m. OpenVINS starts 5.6 s into the file (it waits for motion), so the
  window is the stamps all three share.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.backend.bundle_adjustment import BundleAdjustmentConfig
from slamkit.data import registry
from slamkit.data.formats.eqvio_csv import EqvioData, read_eqvio_csv
from slamkit.data.formats.gtsam_vo import StereoVoData, read_stereo_vo
from slamkit.data.formats.kitti import read_kitti
from slamkit.data.formats.tum import read_tum
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError
from slamkit.metrics.alignment import matching_time_indices
from slamkit.metrics.trajectory_score import score_trajectory
from slamkit.systems.stereo_vo import stereo_vo
from slamkit.systems.visual_inertial import VioConfig, VioEstimate, run_vio

SHORT_SEGMENTS_M = (10.0, 20.0, 30.0, 40.0, 50.0)
MATCH_TOLERANCE_S = 0.01


# --- stereo VO on KITTI 00 ---------------------------------------------------------------------

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


def stereo_scores(gt: Trajectory, est: Trajectory) -> dict[str, float]:
    return score_trajectory(gt, est, "se3", extra_aligns=("sim3",), rotation_unit="deg", rpe_delta=1,
                            rpe_delta_unit="frames", drift_lengths_m=SHORT_SEGMENTS_M, drift_step_frames=1,
                            drift_suffix="_10_50m")


def stereo_ba_kitti00(config: BundleAdjustmentConfig = BundleAdjustmentConfig(max_iterations=30)) -> StereoVoReport:
    res = stereo_vo(load_kitti00_stereo(), config)
    frames = res.pose_ids
    times = registry.path_of("kitti00-gt", "KITTI_00_gt_times.txt")
    gt_all = read_kitti(registry.path_of("kitti00-gt", "KITTI_00_gt.txt"), times)
    orb_all = read_kitti(registry.path_of("kitti00-orbslam"), times)
    gt = gt_all.subset(frames)
    stamps = gt.stamps_s
    estimates = {"initial": Trajectory.from_matrices(stamps, res.initial_T_camera),
                 "stereo_ba": Trajectory.from_matrices(stamps, res.world_T_camera),
                 "orb_slam": orb_all.subset(frames)}
    metrics = {name: stereo_scores(gt, est) for name, est in estimates.items()}
    return StereoVoReport(frames, metrics, res.run_s, res.solve.initial_error, res.solve.final_error)


# --- VIO on EuRoC V1_01 ------------------------------------------------------------------------

@dataclass(frozen=True)
class VioReport:
    window_s: tuple[float, float]           #: the scored stamps' first and last
    num_poses: int                          #: poses scored (the same for every estimator)
    metrics: dict[str, dict[str, float]]    #: "vio", "openvins" -> metrics
    estimate: VioEstimate


def load_euroc_v101() -> EqvioData:
    return read_eqvio_csv(registry.path_of("euroc-v101-eqvio"))


def vio_scores(gt: Trajectory, est: Trajectory) -> dict[str, float]:
    return score_trajectory(gt, est, "se3", extra_aligns=("sim3",), rotation_unit="deg", rpe_delta=1.0,
                            rpe_delta_unit="m", rpe_min_path_m=2.0)


def vio_euroc_v101(config: VioConfig = VioConfig(), until_s: float | None = None) -> VioReport:
    """Run the VIO on the file (its first ``until_s`` seconds) and score it beside OpenVINS."""
    data = load_euroc_v101()
    est = run_vio(data, config, until_s)
    gt = read_tum(registry.path_of("v101-gt"))
    ov = read_tum(registry.path_of("v101-openvins"))
    vio = Trajectory.from_matrices(est.stamps_s, est.world_T_body)
    # the stamps all three share
    stamps = vio.stamps_s[vio.stamps_s >= ov.stamps_s[0] - MATCH_TOLERANCE_S]
    i_gt, j_gt = matching_time_indices(stamps, gt.stamps_s, MATCH_TOLERANCE_S)
    stamps = stamps[i_gt]
    i_ov, j_ov = matching_time_indices(stamps, ov.stamps_s, MATCH_TOLERANCE_S)
    stamps, j_gt = stamps[i_ov], j_gt[i_ov]
    if len(stamps) < 3:
        raise ConfigError(f"fewer than 3 stamps shared with OpenVINS (until_s={until_s}); OpenVINS starts "
                          f"{ov.stamps_s[0] - data.imu_stamps_s[0]:.1f} s into the file")
    ref = gt.subset(j_gt)
    mine = vio.subset(matching_time_indices(stamps, vio.stamps_s, MATCH_TOLERANCE_S)[1])
    theirs = ov.subset(j_ov)
    metrics = {"vio": vio_scores(ref, mine), "openvins": vio_scores(ref, theirs)}
    metrics["vio"]["time_per_frame_ms"] = float(np.median(est.step_ms))
    return VioReport((float(stamps[0]), float(stamps[-1])), len(stamps), metrics, est)
