"""Trajectory alignment and timestamp association (the evo conventions).

* ``umeyama`` -- S. Umeyama, "Least-squares estimation of transformation parameters between two
  point patterns", IEEE PAMI 13(4), 1991, eqs. 34-43: the similarity (R, t, s) minimising
  sum ||dst_i - (s R src_i + t)||^2, with the reflection fix of eq. 43.
* ``align`` -- applies one of the modes below to an estimate so it can be compared with a
  reference (Sturm et al., IROS 2012; Zhang & Scaramuzza, "A Tutorial on Quantitative Trajectory
  Evaluation for Visual(-Inertial) Odometry", IROS 2018, sec. III):

  ``none``   identity;
  ``origin`` ref_0 est_0^-1 applied on the left, so the first poses coincide (evo ``align_origin``);
  ``se2``    planar: Umeyama on the x-y positions, yaw-only rotation, (x, y) translation (z kept);
  ``se3``    Umeyama without scale on the 3D positions (evo ``--align``);
  ``sim3``   Umeyama with scale (evo ``--align --correct_scale``): positions become s R p + t.

  As in evo, the fit uses positions only and the first ``n_first`` pairs when given.
* ``associate`` -- pairs poses whose stamps differ by at most ``max_diff_s``: for every pose of
  the shorter trajectory the nearest stamp of the longer one (ties to the earlier), exactly as
  ``evo.core.sync.associate_trajectories`` with ``SyncMethod.nearest_time``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.geometry import se3, so3

AlignMode = Literal["none", "origin", "se2", "se3", "sim3"]
ALIGN_MODES: tuple[str, ...] = ("none", "origin", "se2", "se3", "sim3")


def umeyama(src: np.ndarray, dst: np.ndarray, with_scale: bool = False
            ) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares similarity mapping ``src`` (N, m) onto ``dst`` (N, m): dst ~ s R src + t.

    Returns (R (m, m), t (m,), s); ``s`` is 1.0 without scale. Raises ``DataError`` when the
    points are degenerate (covariance rank below m - 1, e.g. fewer than m points or all
    collinear in 3D)."""
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    if src.shape != dst.shape or src.ndim != 2:
        raise DataError(f"umeyama needs two (N, m) arrays of equal shape, got {src.shape} and {dst.shape}")
    n, m = src.shape
    mean_src, mean_dst = src.mean(axis=0), dst.mean(axis=0)
    src_c, dst_c = src - mean_src, dst - mean_dst
    var_src = np.sum(src_c * src_c) / n  # eq. 36
    cov = dst_c.T @ src_c / n  # eq. 38
    U, d, Vt = np.linalg.svd(cov)
    if np.count_nonzero(d > np.finfo(float).eps) < m - 1:
        raise DataError(f"degenerate point sets ({n} points): Umeyama alignment is not possible")
    S = np.eye(m)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0.0:
        S[m - 1, m - 1] = -1.0  # eq. 43: a rotation, never a reflection
    R = U @ S @ Vt
    s = float(np.trace(np.diag(d) @ S) / var_src) if with_scale else 1.0
    t = mean_dst - s * R @ mean_src
    return R, t, s


@dataclass(frozen=True)
class AlignmentResult:
    """``aligned`` is ``est`` mapped by p -> scale * rotation @ p + translation (orientations are
    rotated by ``rotation``)."""

    aligned: Trajectory
    rotation: np.ndarray
    translation: np.ndarray
    scale: float
    mode: str

    def apply(self, trajectory: Trajectory) -> Trajectory:
        return transform_trajectory(trajectory, self.rotation, self.translation, self.scale)


def transform_trajectory(trajectory: Trajectory, rotation: np.ndarray, translation: np.ndarray,
                         scale: float = 1.0) -> Trajectory:
    """Left-multiply every pose by the similarity (rotation, translation, scale)."""
    R = np.asarray(rotation, dtype=float)
    t = (scale * trajectory.world_t_body) @ R.T + np.asarray(translation, dtype=float)
    q = so3.quat_multiply_wxyz(so3.to_quat_wxyz(R), trajectory.world_q_body_wxyz)
    return Trajectory(trajectory.stamps_s, t, q, planar=trajectory.planar, frame=trajectory.frame)


def align(est: Trajectory, ref: Trajectory, mode: AlignMode = "se3",
          n_first: int | None = None) -> AlignmentResult:
    """Align ``est`` to ``ref`` (already associated: same length, pose i with pose i)."""
    if mode not in ALIGN_MODES:
        raise DataError(f"unknown alignment mode {mode!r}; use one of {ALIGN_MODES}")
    if len(est) != len(ref):
        raise DataError(f"cannot align {len(est)} poses to {len(ref)}: associate the trajectories first")
    if len(est) == 0:
        raise DataError("cannot align empty trajectories")
    n = len(est) if n_first is None or n_first < 0 else min(int(n_first), len(est))
    if n < 1:
        raise DataError(f"n_first must be positive, got {n_first}")
    R, t, s = np.eye(3), np.zeros(3), 1.0
    if mode == "origin":
        ref_T_est = ref.matrices()[0] @ se3.inverse(est.matrices()[0])
        R, t = ref_T_est[:3, :3], ref_T_est[:3, 3]
    elif mode == "se2":
        R2, t2, _ = umeyama(est.world_t_body[:n, :2], ref.world_t_body[:n, :2], with_scale=False)
        R[:2, :2] = R2
        t[:2] = t2
    elif mode in ("se3", "sim3"):
        R, t, s = umeyama(est.world_t_body[:n], ref.world_t_body[:n], with_scale=mode == "sim3")
    aligned = est if mode == "none" else transform_trajectory(est, R, t, s)
    return AlignmentResult(aligned=aligned, rotation=R, translation=t, scale=s, mode=mode)


@dataclass(frozen=True)
class Association:
    """Index pairs (``ref_index[k]``, ``est_index[k]``) and the associated trajectories."""

    ref: Trajectory
    est: Trajectory
    ref_index: np.ndarray
    est_index: np.ndarray

    @property
    def num_pairs(self) -> int:
        return len(self.ref_index)


def matching_time_indices(stamps_1: np.ndarray, stamps_2: np.ndarray, max_diff_s: float
                          ) -> tuple[np.ndarray, np.ndarray]:
    """For every stamp in ``stamps_1`` the nearest in ``stamps_2`` within ``max_diff_s``.

    Ties go to the earlier stamp; unmatched stamps are dropped (evo ``matching_time_indices``)."""
    s1 = np.asarray(stamps_1, dtype=float)
    s2 = np.asarray(stamps_2, dtype=float)
    if len(s1) == 0 or len(s2) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    if np.any(np.diff(s2) < 0):
        # unsorted: nearest by brute force, first minimum wins (as np.argmin in evo)
        best = np.argmin(np.abs(s2[None, :] - s1[:, None]), axis=1)
        ok = np.abs(s2[best] - s1) <= max_diff_s
        return np.flatnonzero(ok), best[ok].astype(np.int64)
    upper = np.searchsorted(s2, s1, side="right")
    has_lower = upper > 0
    upper = np.minimum(upper, len(s2) - 1)
    diff_ub = s2[upper] - s1
    diff_lb = np.where(has_lower, s1 - s2[np.maximum(upper - 1, 0)], np.inf)
    in_range = (s1 >= s2[0] - max_diff_s) & (s1 <= s2[-1] + max_diff_s)
    take_upper = (diff_ub <= max_diff_s) & (diff_ub < diff_lb)
    take_lower = ~take_upper & (diff_lb <= max_diff_s) & (diff_lb <= diff_ub)
    ok = in_range & (take_upper | take_lower)
    best = np.where(take_upper, upper, upper - 1)
    return np.flatnonzero(ok), best[ok].astype(np.int64)


def associate(ref: Trajectory, est: Trajectory, max_diff_s: float = 0.01) -> Association:
    """Associate two trajectories by timestamp (evo ``associate_trajectories``, nearest time).

    Starts from the trajectory with fewer poses so none of its poses is lost (when lengths are
    equal, from ``est``). Raises ``DataError`` when no stamps match."""
    second_longer = len(est) > len(ref)
    short, long_ = (ref, est) if second_longer else (est, ref)
    idx_short, idx_long = matching_time_indices(short.stamps_s, long_.stamps_s, max_diff_s)
    if len(idx_short) == 0:
        raise DataError(f"found no matching timestamps between reference and estimate with max. "
                        f"time difference {max_diff_s} s")
    ref_index, est_index = (idx_short, idx_long) if second_longer else (idx_long, idx_short)
    return Association(ref=ref.subset(ref_index), est=est.subset(est_index),
                       ref_index=ref_index, est_index=est_index)
