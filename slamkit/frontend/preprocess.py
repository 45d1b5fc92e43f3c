"""Scan preprocessing: remove isolated returns before matching and mapping.

A lidar's random readings (the z_rand component of the beam model, Probabilistic Robotics
sec. 6.3) are isolated: neither neighbouring beam agrees with them. A reading *longer* than the
true range would carve free space straight through a wall in the log-odds map
(``slamkit.maps.log_odds``), and a short one pulls ICP. The filter is the "speckle"/"outlier"
filter of laser pipelines (e.g. ROS ``laser_filters``' ScanShadowsFilter / speckle filter in
its distance mode): a beam is dropped when its range differs from *both* neighbours by more
than ``jump_m + relative * range`` (the relative part tolerates walls seen at grazing angles,
where neighbouring ranges legitimately grow apart). Vectorised over beams and scans.
"""

from __future__ import annotations

import numpy as np


def despeckle(ranges_m: np.ndarray, jump_m: float = 0.3, relative: float = 0.05,
              circular: bool = True) -> np.ndarray:
    """Ranges (..., B) with isolated returns replaced by NaN (no return).

    ``circular``: the first and last beams are neighbours (a 360 degree scan)."""
    r = np.asarray(ranges_m, dtype=float)
    if circular:
        prev, nxt = np.roll(r, 1, axis=-1), np.roll(r, -1, axis=-1)
    else:
        pad = np.full(r.shape[:-1] + (1,), np.nan)
        prev = np.concatenate([pad, r[..., :-1]], axis=-1)
        nxt = np.concatenate([r[..., 1:], pad], axis=-1)
    tol = jump_m + relative * r
    # comparisons with NaN are False: a beam next to two no-returns is isolated too
    agrees = (np.abs(r - prev) <= tol) | (np.abs(r - nxt) <= tol)
    return np.where(agrees, r, np.nan)


def voxel_downsample(points_xy: np.ndarray, voxel_m: float) -> np.ndarray:
    """The centroid of the points (N, 2) in every occupied ``voxel_m`` grid cell (M, 2), in the
    order of the cells' first points (the voxel filter of PCL / KISS-ICP). A submap stacked from
    scans taken close together samples each wall every few millimetres, well below the range
    noise (~1 cm), so the PCA normals of a point's nearest neighbours point anywhere; one point
    per cell makes the neighbourhood span the wall instead (``slamkit.frontend.icp.IcpTarget``)."""
    p = np.asarray(points_xy, dtype=float)
    if voxel_m <= 0 or len(p) == 0:
        return p
    cells = np.floor(p / voxel_m).astype(np.int64)
    _, first, inverse = np.unique(cells, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    sums = np.zeros((len(first), 2))
    np.add.at(sums, inverse, p)
    centroids = sums / np.bincount(inverse)[:, None]
    return centroids[np.argsort(first, kind="stable")]
