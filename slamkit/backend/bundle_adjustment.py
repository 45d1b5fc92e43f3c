"""Bundle adjustment with GTSAM: camera poses and 3D points refined jointly by minimising the
robustified reprojection error (Triggs, McLauchlan, Hartley & Fitzgibbon, "Bundle adjustment -
a modern synthesis", Vision Algorithms 1999; GTSAM's ``SFMExample.py``).

One ``GenericProjectionFactorCal3_S2`` per observation (pixel noise ``pixel_sigma``, a Huber or
Cauchy kernel in whitened units), keys ``X(frame)`` for ``world_T_camera`` (camera: z forward,
x right, y down, as :class:`slamkit.models.camera.PinholeCamera`) and ``L(point)``; the poses
listed in ``fixed`` get a prior of ``fixed_sigma`` (two fixed poses fix the gauge of a monocular
window, scale included). Points with fewer than two observations carry no information on their
depth and are left out (returned unchanged). ``stereo_bundle_adjust`` does the same with
``GenericStereoFactor3D`` (left and right column and the row of a rectified stereo pair), where
one observation fixes a point. Build -> initialise -> optimise (LM), the GTSAM
order; observations behind a camera during the iterations are not fatal (no cheirality throw).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from slamkit.backend.graph import ROBUST_KINDS, RobustKind, isotropic, robust
from slamkit.errors import ConfigError

__all__ = ["BundleAdjustmentConfig", "BundleAdjustmentResult", "bundle_adjust", "stereo_bundle_adjust"]


@dataclass(frozen=True)
class BundleAdjustmentConfig:
    pixel_sigma: float = 1.0
    robust: RobustKind = "huber"
    robust_k: float | None = None
    max_iterations: int = 15
    fixed_sigma: float = 1e-6

    def __post_init__(self) -> None:
        if not self.pixel_sigma > 0 or not self.fixed_sigma > 0:
            raise ConfigError("BundleAdjustmentConfig sigmas must be positive")
        if self.robust not in ROBUST_KINDS:
            raise ConfigError(f"BundleAdjustmentConfig.robust must be one of {ROBUST_KINDS}, got {self.robust!r}")
        if self.max_iterations < 1:
            raise ConfigError("BundleAdjustmentConfig.max_iterations must be >= 1")


@dataclass(frozen=True)
class BundleAdjustmentResult:
    world_T_camera: np.ndarray   #: (F, 4, 4)
    world_p: np.ndarray          #: (P, 3)
    initial_error: float         #: GTSAM's error (1/2 sum of robust whitened squares)
    final_error: float
    iterations: int
    num_factors: int
    used_points: np.ndarray      #: (P,) bool: points that were optimised


def _solve(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, config: BundleAdjustmentConfig
           ) -> tuple[float, gtsam.Values, int]:
    """Levenberg-Marquardt: (initial error, result, iterations)."""
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(config.max_iterations)
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
    initial_error = float(graph.error(values))
    return initial_error, optimizer.optimize(), int(optimizer.iterations())


def bundle_adjust(world_T_camera: np.ndarray, world_p: np.ndarray, frame_index: np.ndarray,
                  point_index: np.ndarray, uv: np.ndarray, intrinsics: tuple[float, float, float, float],
                  fixed=(), config: BundleAdjustmentConfig = BundleAdjustmentConfig()) -> BundleAdjustmentResult:
    """Refine (F, 4, 4) poses and (P, 3) points from observations ``uv`` (M, 2) of point
    ``point_index[m]`` in frame ``frame_index[m]``; ``intrinsics`` = (fx, fy, cx, cy) pixels."""
    poses = np.asarray(world_T_camera, dtype=float)
    points = np.asarray(world_p, dtype=float)
    fi = np.asarray(frame_index, dtype=int)
    pi = np.asarray(point_index, dtype=int)
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    if not (len(fi) == len(pi) == len(uv)):
        raise ConfigError("bundle_adjust: frame_index, point_index and uv need equal lengths")
    if len(fi) and (fi.min() < 0 or fi.max() >= len(poses) or pi.min() < 0 or pi.max() >= len(points)):
        raise ConfigError("bundle_adjust: an observation refers to a frame or point that does not exist")
    counts = np.bincount(pi, minlength=len(points))
    used = counts >= 2
    keep = used[pi]
    fx, fy, cx, cy = (float(v) for v in intrinsics)
    K = gtsam.Cal3_S2(fx, fy, 0.0, cx, cy)
    noise = robust(isotropic(2, config.pixel_sigma), config.robust, config.robust_k)
    graph = gtsam.NonlinearFactorGraph()
    for f, p, m in zip(fi[keep], pi[keep], uv[keep]):
        graph.add(gtsam.GenericProjectionFactorCal3_S2(m, noise, X(int(f)), L(int(p)), K, False, False))
    prior = isotropic(6, config.fixed_sigma)
    seen_frames = np.unique(fi[keep])
    fixed = sorted(set(int(f) for f in fixed))
    for f in fixed:
        graph.add(gtsam.PriorFactorPose3(X(f), gtsam.Pose3(poses[f]), prior))
    values = gtsam.Values()
    for f in sorted(set(seen_frames.tolist()) | set(fixed)):
        values.insert(X(int(f)), gtsam.Pose3(poses[f]))
    for p in np.flatnonzero(used):
        values.insert(L(int(p)), points[p])
    initial_error, result, iterations = _solve(graph, values, config)
    out_poses = poses.copy()
    out_points = points.copy()
    for f in sorted(set(seen_frames.tolist()) | set(fixed)):
        out_poses[f] = result.atPose3(X(int(f))).matrix()
    for p in np.flatnonzero(used):
        out_points[p] = result.atPoint3(L(int(p)))
    return BundleAdjustmentResult(out_poses, out_points, initial_error, float(graph.error(result)),
                                  iterations, int(graph.size()), used)


def stereo_bundle_adjust(world_T_camera: np.ndarray, obs_frame: np.ndarray, obs_landmark: np.ndarray,
                         uL_uR_v: np.ndarray, camera_p: np.ndarray,
                         intrinsics: tuple[float, float, float, float, float, float],
                         fixed=(0,), config: BundleAdjustmentConfig = BundleAdjustmentConfig()
                         ) -> BundleAdjustmentResult:
    """Stereo bundle adjustment (``GenericStereoFactor3D``: left column, right column, row, each
    with ``pixel_sigma``, robust kernel as ``config``): (F, 4, 4) poses refined from
    observations of landmark ``obs_landmark[m]`` in frame ``obs_frame[m]`` (0-based rows of
    ``world_T_camera``); a landmark starts at ``camera_p`` of its first observation;
    ``intrinsics`` = (fx, fy, skew, cx, cy, baseline_m). Returns the points in the order of
    ``np.unique(obs_landmark)``."""
    poses = np.asarray(world_T_camera, dtype=float)
    fi = np.asarray(obs_frame, dtype=int)
    landmarks, li = np.unique(np.asarray(obs_landmark, dtype=int), return_inverse=True)
    z = np.asarray(uL_uR_v, dtype=float).reshape(-1, 3)
    cp = np.asarray(camera_p, dtype=float).reshape(-1, 3)
    if not (len(fi) == len(li) == len(z) == len(cp)):
        raise ConfigError("stereo_bundle_adjust: observation arrays need equal lengths")
    K = gtsam.Cal3_S2Stereo(*(float(v) for v in intrinsics))
    noise = robust(isotropic(3, config.pixel_sigma), config.robust, config.robust_k)
    graph = gtsam.NonlinearFactorGraph()
    for f, p, m in zip(fi, li, z):
        graph.add(gtsam.GenericStereoFactor3D(gtsam.StereoPoint2(*m), noise, X(int(f)), L(int(p)), K))
    prior = isotropic(6, config.fixed_sigma)
    for f in sorted(set(int(f) for f in fixed)):
        graph.add(gtsam.PriorFactorPose3(X(f), gtsam.Pose3(poses[f]), prior))
    values = gtsam.Values()
    for f in range(len(poses)):
        values.insert(X(f), gtsam.Pose3(poses[f]))
    first = np.unique(li, return_index=True)[1]
    world_p = np.einsum("mij,mj->mi", poses[fi[first], :3, :3], cp[first]) + poses[fi[first], :3, 3]
    for p in range(len(landmarks)):
        values.insert(L(p), world_p[p])
    initial_error, result, iterations = _solve(graph, values, config)
    out_poses = np.stack([result.atPose3(X(f)).matrix() for f in range(len(poses))])
    out_points = np.stack([result.atPoint3(L(p)) for p in range(len(landmarks))])
    return BundleAdjustmentResult(out_poses, out_points, initial_error, float(graph.error(result)),
                                  iterations, int(graph.size()), np.ones(len(landmarks), bool))
