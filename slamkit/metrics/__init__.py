"""Trajectory metrics with evo's definitions: alignment (Umeyama none/origin/SE2/SE3/Sim3),
timestamp association, ATE, RPE, summary statistics, KITTI segment drift, NEES/NIS bands, and
``evaluate_files`` behind ``slamkit eval``.

One scorer, :func:`score_trajectory` (:mod:`slamkit.metrics.trajectory_score`), turns an estimate
and its reference into the trajectory figures of every results.json, with the alignment, RPE
delta and drift segments as parameters. The vocabulary (one quantity, one name, in every
pipeline; the unit is the suffix):

| name | quantity |
|---|---|
| ``ate_rmse_m`` | ATE, translation RMSE after the pipeline's alignment: the one that removes what its sensors cannot observe (SE(2) planar, SE(3) metric 3D, Sim(3) monocular) |
| ``ate_rot_rmse_rad`` / ``_deg`` | ATE, rotation RMSE after the same alignment |
| ``ate_<align>_rmse_m`` | ATE after a second alignment reported beside the headline (``ate_se3_rmse_m``, ``ate_sim3_rmse_m``) |
| ``sim3_scale`` | the scale of a Sim(3) headline alignment |
| ``rpe_rmse_m`` | RPE, translation RMSE over the pipeline's delta (1 m of path for the estimator runner and VIO, one frame for camera odometry) |
| ``rpe_rot_rmse_rad`` / ``_deg`` | RPE, rotation RMSE over the same delta |
| ``drift_percent<_segments>``, ``drift_deg_per_100m<_segments>`` | KITTI segment drift (``_10_50m``: over 10-50 m segments instead of KITTI's 100-800 m) |
| ``ate_<trajectory>_m`` | ATE RMSE of another trajectory of the same run (lidar SLAM's ``ate_odometry_m``, ``ate_frontend_m``) |
| ``nees_mean``, ``nis_mean`` | mean normalised estimation / innovation error squared (unitless) |
| ``relation_trans_mean_m`` / ``_std_m``, ``relation_rot_mean_deg`` / ``_std_deg`` | the relation error of Kuemmerle et al. 2009 against a log's relations (:mod:`slamkit.metrics.relations`) |
| ``map_consistency_mean_m`` / ``_p95_m`` | mean / 95th percentile distance of the scans' end points to the surface other visits of the same place drew (no ground truth needed; :mod:`slamkit.metrics.map_consistency`) |
| ``map_consistency_same_pass_mean_m`` | the same mean between scans of one pass (within 5 m of travel): the floor the surfaces and the scan matcher set |
| ``map_consistency_overlap`` | share of the scored end points seen on more than one visit |
| ``real_time_factor`` / ``_cpu`` | time the data spans over the wall-clock / process CPU time it took (larger is faster) |

docs/reference/metrics.md renders this table; a results.json field not in it is a bug.
"""

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
from slamkit.metrics.trajectory_score import ate_paired_by_stamp, score_trajectory

__all__ = [
    "ALIGN_MODES", "AlignmentResult", "Association", "AteResult", "Chi2Band", "ConsistencyResult",
    "ErrorStats", "EvaluationResult", "KittiDriftResult", "RpeResult", "align", "associate", "ate",
    "ate_paired_by_stamp", "ate_rmse_m", "chi2_band", "consistency", "evaluate_files", "evaluate_trajectories",
    "kitti_drift", "load_trajectory", "nees", "nis", "rpe", "score_trajectory", "trajectory_from_pose_graph",
    "transform_trajectory", "umeyama",
]
