"""Trajectory metrics with evo's definitions: alignment (Umeyama none/origin/SE2/SE3/Sim3),
timestamp association, ATE, RPE, summary statistics, KITTI segment drift, NEES/NIS bands, and
``evaluate_files`` behind ``slamkit eval``."""

from slamkit.metrics.alignment import (
    ALIGN_MODES,
    AlignmentResult,
    Association,
    align,
    associate,
    transform_trajectory,
    umeyama,
)
from slamkit.metrics.ate import AteResult, ate, ate_rmse_m
from slamkit.metrics.consistency import Chi2Band, ConsistencyResult, chi2_band, consistency, nees, nis
from slamkit.metrics.evaluate import (
    EvaluationResult,
    evaluate_files,
    evaluate_trajectories,
    load_trajectory,
    trajectory_from_pose_graph,
)
from slamkit.metrics.kitti_drift import KittiDriftResult, kitti_drift
from slamkit.metrics.rpe import RpeResult, rpe
from slamkit.metrics.stats import ErrorStats

__all__ = [
    "ALIGN_MODES", "AlignmentResult", "Association", "AteResult", "Chi2Band", "ConsistencyResult",
    "ErrorStats", "EvaluationResult", "KittiDriftResult", "RpeResult", "align", "associate", "ate",
    "ate_rmse_m", "chi2_band", "consistency", "evaluate_files", "evaluate_trajectories",
    "kitti_drift", "load_trajectory", "nees", "nis", "rpe", "trajectory_from_pose_graph",
    "transform_trajectory", "umeyama",
]
