"""KITTI odometry drift: translational error in % and rotational error in deg/m, averaged over
all sub-sequences of 100, 200, ..., 800 m (Geiger et al., "Are we ready for Autonomous Driving?
The KITTI Vision Benchmark Suite", CVPR 2012, sec. 3.1; ``evaluate_odometry.cpp`` of the KITTI
odometry devkit).

As in the devkit: path lengths are accumulated on the ground truth; a segment starts every
``step_frames`` (10) frames; it ends at the first frame whose distance from the start exceeds the
length (segments that run past the end are skipped); the error pose is
(est_first^-1 est_last)^-1 (gt_first^-1 gt_last); its translation norm and rotation angle
(arccos((trace - 1)/2), clipped) are divided by the segment length. The headline numbers average
over all segments of all lengths with equal weight.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.geometry import se3

KITTI_LENGTHS_M: tuple[float, ...] = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)


@dataclass(frozen=True)
class KittiDriftResult:
    """``translation_percent`` (100 * m/m) and ``rotation_deg_per_m``, averaged over segments;
    ``per_length`` maps each length to (translation %, rotation deg/m, number of segments)."""

    translation_percent: float
    rotation_deg_per_m: float
    num_segments: int
    per_length: dict[float, tuple[float, float, int]]
    lengths_m: tuple[float, ...]

    @property
    def rotation_deg_per_100m(self) -> float:
        return 100.0 * self.rotation_deg_per_m


def kitti_drift(ref: Trajectory, est: Trajectory, lengths_m: tuple[float, ...] = KITTI_LENGTHS_M,
                step_frames: int = 10) -> KittiDriftResult:
    """KITTI segment drift of ``est`` against ground truth ``ref`` (associated, same length)."""
    if len(ref) != len(est):
        raise DataError(f"{len(ref)} reference poses but {len(est)} estimated: associate first")
    gt, res = ref.matrices(), est.matrices()
    dist = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(gt[:, :3, 3], axis=0), axis=1))])
    first = np.arange(0, len(gt), step_frames)
    t_all, r_all = [], []
    per_length: dict[float, tuple[float, float, int]] = {}
    for length in lengths_m:
        # first frame whose distance exceeds dist[first] + length (devkit: strictly greater)
        last = np.searchsorted(dist, dist[first] + length, side="right")
        ok = last < len(gt)
        f, l_ = first[ok], last[ok]
        if len(f) == 0:
            continue
        E = se3.between(se3.between(res[f], res[l_]), se3.between(gt[f], gt[l_]))
        t_err = np.linalg.norm(E[:, :3, 3], axis=1) / length
        d = 0.5 * (np.trace(E[:, :3, :3], axis1=1, axis2=2) - 1.0)
        r_err = np.arccos(np.clip(d, -1.0, 1.0)) / length
        t_all.append(t_err)
        r_all.append(r_err)
        per_length[float(length)] = (float(100.0 * t_err.mean()), float(np.rad2deg(r_err.mean())), len(f))
    if not t_all:
        raise DataError(f"trajectory ({dist[-1]:.1f} m) is shorter than the shortest segment "
                        f"({min(lengths_m)} m)")
    t = np.concatenate(t_all)
    r = np.concatenate(r_all)
    return KittiDriftResult(
        translation_percent=float(100.0 * t.mean()), rotation_deg_per_m=float(np.rad2deg(r.mean())),
        num_segments=len(t), per_length=per_length, lengths_m=tuple(float(x) for x in lengths_m),
    )
