"""Euclidean distance field of an occupancy grid.

Each cell holds the Euclidean distance (metres) from its centre to the centre of the nearest
occupied cell, computed exactly with the separable distance transform of Maurer et al.,
"A linear time algorithm for computing exact Euclidean distance transforms of binary images in
arbitrary dimensions", IEEE PAMI 25(2), 2003 (``scipy.ndimage.distance_transform_edt``).
Occupied cells hold 0. A grid without any occupied cell has distance ``inf`` everywhere.

The field feeds the likelihood-field lidar model, inflation/costmaps and obstacle-distance
costs in local planners, which is why :func:`distance_at` looks many world points up at once.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from slamkit.maps.occupancy_grid import OccupancyGrid


def distance_field_m(grid: OccupancyGrid) -> np.ndarray:
    """(H, W) distance in metres from every cell centre to the nearest occupied cell centre."""
    occ = grid.occupied
    if not occ.any():
        return np.full(occ.shape, np.inf)
    # distance_transform_edt measures the distance of every non-zero element to the nearest
    # zero element, so free cells must be the non-zero ones.
    return ndimage.distance_transform_edt(~occ, sampling=grid.resolution_m)


def signed_distance_field_m(grid: OccupancyGrid) -> np.ndarray:
    """(H, W) signed distance: positive in free space (to the nearest occupied cell), negative
    inside obstacles (minus the distance to the nearest free cell), so gradients point out of
    obstacles everywhere (as CHOMP-style obstacle costs need)."""
    occ = grid.occupied
    outside = distance_field_m(grid)
    if occ.all():
        return np.full(occ.shape, -np.inf)
    inside = ndimage.distance_transform_edt(occ, sampling=grid.resolution_m)
    return np.where(occ, -inside, outside)


def surface_distance_field_m(grid: OccupancyGrid, signed: bool = False) -> np.ndarray:
    """(H, W) distance from every cell centre to the *surface* of the nearest occupied cell (the
    distance to its centre less half a cell: a lidar beam ends on a wall's face, not at its
    cell's centre), 0 in occupied cells; ``signed``: inside occupied cells minus the distance to
    the surface of the nearest free cell instead of 0, so the field passes through 0 on the faces
    and bilinear interpolation between a free and an occupied neighbour is exact there.

    A field clipped at 0 inside walls makes the likelihood-field lidar model lopsided: an end
    point that range noise puts behind a wall's face costs nothing, one in front of it costs its
    distance, so the best-fitting pose pulls the end points into the walls. Measured (likelihood
    optimum of 20 summed scans of 90 beams at the goal pose, 2 cm range noise, sigma_hit 5 cm, 30
    seeds per world; mean / max distance from the true position): office 0.74 / 2.06 cm clipped,
    0.02 / 0.25 cm signed; warehouse 0.88 / 1.58 -> 0.05 / 0.35; Willow (10 cm map) 0.80 / 1.46
    -> 0.16 / 0.35."""
    half = 0.5 * grid.resolution_m
    outside = np.maximum(distance_field_m(grid) - half, 0.0)
    if not signed or not grid.occupied.any():
        return outside
    return np.where(grid.occupied, signed_distance_field_m(grid) + half, outside)


def distance_at(grid: OccupancyGrid, field_m: np.ndarray, world_xy_m: np.ndarray,
                outside_m: float = 0.0) -> np.ndarray:
    """(N,) value of ``field_m`` at the cells containing the (N, 2) world points.

    Points outside the grid get ``outside_m`` (0 by default: unknown space is treated as an
    obstacle, the safe choice for collision checks)."""
    cells = grid.world_to_cell(world_xy_m)
    ok = grid.in_bounds(cells)
    out = np.full(len(cells), float(outside_m))
    out[ok] = field_m[cells[ok, 1], cells[ok, 0]]
    return out


def bilinear(field_m: np.ndarray, resolution_m: float, origin_xy_m: np.ndarray, xy_m: np.ndarray,
             outside: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(..., 2) points -> (value (...), gradient (..., 2)) of a field sampled at cell centres,
    interpolated bilinearly between them (vectorised). Points outside the grid get ``outside``
    and a zero gradient; within half a cell of the border the edge values are held."""
    xy = np.asarray(xy_m, dtype=float)
    shape = xy.shape[:-1]
    p = xy.reshape(-1, 2)
    d = np.asarray(field_m, dtype=float)
    h, w = d.shape
    # continuous index whose integer values are cell centres
    g = (p - np.asarray(origin_xy_m, float)) / resolution_m - 0.5
    inside = (g[:, 0] >= -0.5) & (g[:, 0] <= w - 0.5) & (g[:, 1] >= -0.5) & (g[:, 1] <= h - 0.5)
    gx = np.clip(g[:, 0], 0.0, w - 1.0)
    gy = np.clip(g[:, 1], 0.0, h - 1.0)
    x0 = np.minimum(np.floor(gx).astype(np.int64), max(w - 2, 0))
    y0 = np.minimum(np.floor(gy).astype(np.int64), max(h - 2, 0))
    x1 = np.minimum(x0 + 1, w - 1)
    y1 = np.minimum(y0 + 1, h - 1)
    fx = gx - x0
    fy = gy - y0
    d00, d10, d01, d11 = d[y0, x0], d[y0, x1], d[y1, x0], d[y1, x1]
    val = (d00 * (1 - fx) * (1 - fy) + d10 * fx * (1 - fy) + d01 * (1 - fx) * fy + d11 * fx * fy)
    ddx = ((d10 - d00) * (1 - fy) + (d11 - d01) * fy) / resolution_m
    ddy = ((d01 - d00) * (1 - fx) + (d11 - d10) * fx) / resolution_m
    val = np.where(inside, val, outside)
    grad = np.stack([np.where(inside, ddx, 0.0), np.where(inside, ddy, 0.0)], axis=-1)
    return val.reshape(shape), grad.reshape(shape + (2,))
