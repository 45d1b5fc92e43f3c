"""Stereo visual odometry by bundle adjustment over recorded stereo features: an initial pose
per frame and stereo observations (left column, right column, row) of tracked landmarks in,
refined camera poses out.

The back-end is :func:`slamkit.backend.bundle_adjustment.stereo_bundle_adjust` (GTSAM's
``GenericStereoFactor3D``; the first frame fixed, so the world frame is the first camera's).
This module maps a recording's pose ids onto the solver's rows and times the solve. It knows
nothing of ground truth or files: the tests score it on the gtsam wheel's real KITTI 00 features
beside ORB-SLAM (``tests/systems/peer_comparison.py``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from slamkit.backend.bundle_adjustment import BundleAdjustmentConfig, BundleAdjustmentResult, stereo_bundle_adjust
from slamkit.data.formats.gtsam_vo import StereoVoData

__all__ = ["StereoVoResult", "stereo_vo"]


@dataclass(frozen=True)
class StereoVoResult:
    pose_ids: np.ndarray            #: (F,) the recording's pose ids, in the order of the poses
    initial_T_camera: np.ndarray    #: (F, 4, 4) the recording's own (initial) estimate
    world_T_camera: np.ndarray      #: (F, 4, 4) after bundle adjustment
    solve: BundleAdjustmentResult
    run_s: float                    #: wall time of the solve


def stereo_vo(data: StereoVoData, config: BundleAdjustmentConfig = BundleAdjustmentConfig(max_iterations=30)
              ) -> StereoVoResult:
    """Refine every pose of ``data`` from its stereo observations (the first pose fixed)."""
    row = {int(p): k for k, p in enumerate(data.pose_ids)}
    t0 = time.perf_counter()
    res = stereo_bundle_adjust(data.world_T_camera, np.array([row[int(p)] for p in data.obs_pose]),
                               data.obs_landmark, data.obs_uL_uR_v, data.obs_camera_p,
                               (data.fx, data.fy, data.skew, data.cx, data.cy, data.baseline_m), fixed=(0,),
                               config=config)
    return StereoVoResult(data.pose_ids, data.world_T_camera, res.world_T_camera, res, time.perf_counter() - t0)
