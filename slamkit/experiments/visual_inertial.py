"""Visual-inertial odometry on 30 s of real EuRoC V1_01_easy (the gtsam wheel's
``eqvio_processed_30s.csv``, registry ``euroc-v101-eqvio``), scored against the EuRoC ground truth
(``v101-gt``) beside OpenVINS' estimate (``v101-openvins``) on the same stamps, in the same run.

The system (:class:`slamkit.systems.visual_inertial.VisualInertialOdometry`) is fed the file's
IMU readings and feature frames in time order. Inputs it uses:

* camera-IMU extrinsics: the file's ``T_ci_*`` metadata, imu_T_camera, which is EuRoC cam0's
  ``T_BS`` (translation (-0.0216, -0.0647, 0.0098) m, camera z along IMU x to 1.5 deg); both
  trajectories and the ground truth are IMU (body) poses;
* time alignment: none (offset 0). EuRoC's camera and IMU are hardware-synchronised on one clock
  and the file's frame stamps fall on IMU stamps; the ground truth is given at the camera stamps,
  so poses are associated by stamp (10 ms tolerance);
* IMU noise: EuRoC's ADIS16448 ``imu0/sensor.yaml`` densities (``EUROC_IMU_NOISE``).

VIO observes metric scale and, through gravity, roll and pitch; the yaw and the position of its
world frame are free, so both estimates are scored with an SE(3) Umeyama alignment (``ate_rmse_m``,
``ate_rot_rmse_deg``; ``ate_sim3_rmse_m`` beside it) and over 1 m of path (``rpe_rmse_m``,
``rpe_rot_rmse_deg``, where the path is longer than 2 m).
OpenVINS starts 5.6 s into the file (it waits for motion to initialise), so the window is the
stamps all three trajectories share: from OpenVINS' first pose to the end of the file.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from slamkit.data import registry
from slamkit.data.formats.eqvio_csv import EqvioData, read_eqvio_csv
from slamkit.data.formats.tum import read_tum
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError
from slamkit.metrics.alignment import matching_time_indices
from slamkit.metrics.trajectory_score import score_trajectory
from slamkit.systems.visual_inertial import VioConfig, VioEstimate, VisualInertialOdometry

__all__ = ["VioReport", "load_euroc_v101", "run_vio", "vio_euroc_v101"]

MATCH_TOLERANCE_S = 0.01


@dataclass(frozen=True)
class VioReport:
    window_s: tuple[float, float]           #: the scored stamps' first and last
    num_poses: int                          #: poses scored (the same for every estimator)
    metrics: dict[str, dict[str, float]]    #: "vio", "openvins" -> metrics
    estimate: VioEstimate
    run_s: float


def load_euroc_v101() -> EqvioData:
    return read_eqvio_csv(registry.path_of("euroc-v101-eqvio"))


def run_vio(data: EqvioData, config: VioConfig = VioConfig(), until_s: float | None = None) -> VioEstimate:
    """Feed the IMU readings and frames (up to ``until_s`` seconds after the first) in time order."""
    vio = VisualInertialOdometry(data.imu_T_camera, config)
    end = np.inf if until_s is None else data.imu_stamps_s[0] + until_s + 1e-9
    i = 0
    for t, (ids, xy) in zip(data.frame_stamps_s, data.frame_features):
        if t > end:
            break
        while i < len(data.imu_stamps_s) and data.imu_stamps_s[i] <= t + 1e-9:
            vio.step_imu(data.imu_stamps_s[i], data.accel_mps2[i], data.gyro_radps[i])
            i += 1
        vio.step_frame(t, ids, xy)
    return vio.estimate()


def _scores(gt: Trajectory, est: Trajectory) -> dict[str, float]:
    return score_trajectory(gt, est, "se3", extra_aligns=("sim3",), rotation_unit="deg", rpe_delta=1.0,
                            rpe_delta_unit="m", rpe_min_path_m=2.0)


def vio_euroc_v101(config: VioConfig = VioConfig(), until_s: float | None = None) -> VioReport:
    """Run the VIO on the file (its first ``until_s`` seconds) and score it beside OpenVINS."""
    data = load_euroc_v101()
    t0 = time.perf_counter()
    est = run_vio(data, config, until_s)
    run_s = time.perf_counter() - t0
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
    metrics = {"vio": _scores(ref, mine), "openvins": _scores(ref, theirs)}
    metrics["vio"]["time_per_frame_ms"] = float(np.median(est.step_ms))
    return VioReport((float(stamps[0]), float(stamps[-1])), len(stamps), metrics, est, run_s)
