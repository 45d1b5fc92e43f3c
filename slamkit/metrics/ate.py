"""Absolute trajectory error (APE/ATE) with evo's semantics.

Sturm et al., "A Benchmark for the Evaluation of RGB-D SLAM Systems", IROS 2012, sec. V-B (ATE);
Kuemmerle et al., "On measuring the accuracy of SLAM algorithms", Autonomous Robots 2009, and
``evo.core.metrics.APE``:

* translation error of pose i: ||t_est,i - t_ref,i|| (evo ``PoseRelation.translation_part``);
* rotation error of pose i: the angle of est_i^-1 ref_i in [0, pi] (evo ``rotation_angle_rad`` /
  ``rotation_angle_deg``).

``est`` is first aligned to ``ref`` with :func:`slamkit.metrics.alignment.align`. The two
trajectories must already be associated (same length; use ``associate`` for stamps).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.data.trajectory import Trajectory
from slamkit.geometry import so3
from slamkit.metrics.alignment import AlignMode, AlignmentResult, align
from slamkit.metrics.stats import ErrorStats


@dataclass(frozen=True)
class AteResult:
    """Per-pose errors and their statistics (translation in m, rotation in rad and deg)."""

    translation_m: ErrorStats
    rotation_rad: ErrorStats
    rotation_deg: ErrorStats
    errors_m: np.ndarray
    errors_rad: np.ndarray
    stamps_s: np.ndarray
    alignment: AlignmentResult

    @property
    def num_pairs(self) -> int:
        return len(self.errors_m)


def translation_errors_m(ref: Trajectory, est: Trajectory) -> np.ndarray:
    return np.linalg.norm(est.world_t_body - ref.world_t_body, axis=1)


def rotation_errors_rad(ref: Trajectory, est: Trajectory) -> np.ndarray:
    """Angle of est_i^-1 ref_i for every i (the angle does not depend on the order)."""
    R_ref = so3.from_quat_wxyz(ref.world_q_body_wxyz)
    R_est = so3.from_quat_wxyz(est.world_q_body_wxyz)
    return so3.angle(so3.between(R_est, R_ref))


def ate(ref: Trajectory, est: Trajectory, align_mode: AlignMode = "none",
        n_first: int | None = None) -> AteResult:
    """ATE of ``est`` against ``ref`` after aligning with ``align_mode`` (first ``n_first`` poses)."""
    alignment = align(est, ref, align_mode, n_first)
    aligned = alignment.aligned
    e_m = translation_errors_m(ref, aligned)
    e_rad = rotation_errors_rad(ref, aligned)
    e_deg = np.rad2deg(e_rad)
    return AteResult(
        translation_m=ErrorStats.from_errors(e_m),
        rotation_rad=ErrorStats.from_errors(e_rad),
        rotation_deg=ErrorStats.from_errors(e_deg),
        errors_m=e_m, errors_rad=e_rad, stamps_s=ref.stamps_s, alignment=alignment,
    )


def ate_rmse_m(ref: Trajectory, est: Trajectory, align_mode: AlignMode = "se3") -> float:
    """Shortcut for the headline number ``ate_rmse_m`` of results.json."""
    return ate(ref, est, align_mode).translation_m.rmse
