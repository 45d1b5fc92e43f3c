"""The one trajectory scorer: ATE, RPE and (optionally) segment drift of an estimate against a
reference, named in the vocabulary of :mod:`slamkit.metrics` (``ate_rmse_m``, ``rpe_rmse_m`` ...).

Every pipeline that scores a trajectory calls :func:`score_trajectory` with its own alignment,
RPE delta and drift segments (the runner behind filter_vs_smoother, visual odometry, stereo
bundle adjustment, visual-inertial odometry), so one quantity has one name and one definition in
every results.json. The definitions are evo's (:func:`slamkit.metrics.ate.ate`,
:func:`slamkit.metrics.rpe.rpe`) and KITTI's (:func:`slamkit.metrics.kitti_drift.kitti_drift`).
"""

from __future__ import annotations

import numpy as np

from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.metrics.alignment import AlignMode, associate
from slamkit.metrics.ate import ate
from slamkit.metrics.kitti_drift import kitti_drift
from slamkit.metrics.rpe import DeltaUnit, rpe

ROTATION_UNITS = ("rad", "deg")


def score_trajectory(ref: Trajectory, est: Trajectory, align: AlignMode = "se3", *,
                     extra_aligns: tuple[AlignMode, ...] = (), rotation_unit: str = "rad",
                     rpe_delta: float | None = 1.0, rpe_delta_unit: DeltaUnit = "m", rpe_align: AlignMode = "none",
                     rpe_pairs_from_reference: bool = False, rpe_min_path_m: float = 0.0,
                     drift_lengths_m: tuple[float, ...] | None = None, drift_step_frames: int = 10,
                     drift_suffix: str = "") -> dict[str, float]:
    """Score ``est`` against ``ref`` (associated: same length, pose i with pose i).

    * ``ate_rmse_m``, ``ate_rot_rmse_<unit>``: ATE after aligning with ``align`` (the alignment
      that removes what the sensors cannot observe: ``se2`` planar, ``se3`` metric 3D, ``sim3``
      monocular); ``sim3_scale`` too when ``align`` is ``sim3``;
    * ``ate_<mode>_rmse_m`` for every mode in ``extra_aligns`` (a second alignment reported
      beside the headline, e.g. ``ate_sim3_rmse_m``);
    * ``rpe_rmse_m``, ``rpe_rot_rmse_<unit>``: RPE over ``rpe_delta`` ``rpe_delta_unit`` after
      ``rpe_align``; left out where the reference path is not longer than ``rpe_min_path_m`` or
      the delta gives no pose pair, and not computed when ``rpe_delta`` is None (a scorer that
      reports ATE only, such as lidar SLAM's keyframe ATE);
    * ``drift_percent<suffix>``, ``drift_deg_per_100m<suffix>``: KITTI segment drift over
      ``drift_lengths_m`` (starting every ``drift_step_frames``), when lengths are given.

    ``rotation_unit`` is ``rad`` (the default, SI) or ``deg``.
    """
    if rotation_unit not in ROTATION_UNITS:
        raise DataError(f"rotation_unit must be one of {ROTATION_UNITS}, got {rotation_unit!r}")
    out: dict[str, float] = {}
    headline = ate(ref, est, align)
    out["ate_rmse_m"] = float(headline.translation_m.rmse)
    out[f"ate_rot_rmse_{rotation_unit}"] = float(
        (headline.rotation_rad if rotation_unit == "rad" else headline.rotation_deg).rmse)
    if align == "sim3":
        out["sim3_scale"] = float(headline.alignment.scale)
    for mode in extra_aligns:
        out[f"ate_{mode}_rmse_m"] = float(ate(ref, est, mode).translation_m.rmse)
    if rpe_delta is not None and (rpe_min_path_m <= 0.0 or ref.path_length_m() > rpe_min_path_m):
        try:
            rel = rpe(ref, est, rpe_delta, rpe_delta_unit, align_mode=rpe_align,
                      pairs_from_reference=rpe_pairs_from_reference)
        except DataError:
            rel = None
        if rel is not None:
            out["rpe_rmse_m"] = float(rel.translation_m.rmse)
            out[f"rpe_rot_rmse_{rotation_unit}"] = float(
                (rel.rotation_rad if rotation_unit == "rad" else rel.rotation_deg).rmse)
    if drift_lengths_m is not None:
        drift = kitti_drift(ref, est, lengths_m=drift_lengths_m, step_frames=drift_step_frames)
        out[f"drift_percent{drift_suffix}"] = float(drift.translation_percent)
        out[f"drift_deg_per_100m{drift_suffix}"] = float(drift.rotation_deg_per_100m)
    return out


def ate_paired_by_stamp(reference: Trajectory, estimate: Trajectory, max_diff_s: float = 0.1) -> tuple[float, str]:
    """``ate_rmse_m`` of :func:`score_trajectory` (no RPE) with the poses paired by stamp
    (within ``max_diff_s``; a pose graph's vertex ids) and the alignment that removes what a
    pose graph cannot observe: SE(2) when both trajectories are planar, SE(3) otherwise; returns
    (ATE RMSE in m, the alignment)."""
    pairs = associate(reference, estimate, max_diff_s=max_diff_s)
    mode: AlignMode = "se2" if reference.planar and estimate.planar else "se3"
    return score_trajectory(pairs.ref, pairs.est, mode, rpe_delta=None)["ate_rmse_m"], mode


def poses_at_stamps(trajectory: Trajectory, stamps_s: np.ndarray, tol_s: float = 1e-6) -> np.ndarray:
    """(K, 3) planar poses of ``trajectory`` at ``stamps_s`` (K,), each within ``tol_s`` of one of
    its stamps (a simulator's ground truth at the stamps of the scans it produced)."""
    idx = np.clip(np.searchsorted(trajectory.stamps_s, stamps_s - 1e-9), 0, len(trajectory) - 1)
    if np.max(np.abs(trajectory.stamps_s[idx] - stamps_s)) > tol_s:
        raise DataError("ground truth has no pose at some keyframe stamps")
    return trajectory.xytheta()[idx]


def ate_at_stamps_m(ground_truth: Trajectory, stamps_s: np.ndarray, poses: np.ndarray) -> float:
    """``ate_rmse_m`` of :func:`score_trajectory` (SE(2) alignment, no RPE) of planar ``poses``
    (K, 3) at ``stamps_s`` against ``ground_truth`` looked up at those stamps
    (:func:`poses_at_stamps`): lidar SLAM's keyframe ATE."""
    gt = poses_at_stamps(ground_truth, stamps_s)
    return score_trajectory(Trajectory.from_se2(stamps_s, gt), Trajectory.from_se2(stamps_s, poses), "se2",
                            rpe_delta=None)["ate_rmse_m"]
