"""Obstacle inflation and Nav2-style costmaps.

``inflate`` marks every cell whose centre lies within ``radius_m`` of an occupied cell centre as
occupied, which turns a disc-shaped robot into a point for collision checks (configuration-space
obstacles, Lozano-Perez 1983).

``costmap`` reproduces the inflation layer of ROS 2 Nav2 (``nav2_costmap_2d::InflationLayer``,
``computeCost``): lethal cells cost 254, cells within the inscribed radius 253, and beyond it the
cost decays as ``252 * exp(-cost_scaling * (d - inscribed_radius))`` out to the inflation radius,
0 further away. Values are floats on Nav2's 0..254 scale so planners can use them as traversal
penalties directly or divide by ``LETHAL_COST`` for a 0..1 scale.
"""

from __future__ import annotations

import numpy as np

from slamkit.errors import DataError
from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.occupancy_grid import OccupancyGrid

LETHAL_COST = 254.0
INSCRIBED_COST = 253.0
FREE_COST = 0.0


def inflate(grid: OccupancyGrid, radius_m: float) -> OccupancyGrid:
    """A new grid in which every cell within ``radius_m`` (centre to centre) of an obstacle is
    occupied. ``radius_m = 0`` returns an identical grid."""
    if not (radius_m >= 0 and np.isfinite(radius_m)):
        raise DataError(f"inflation radius_m must be finite and >= 0, got {radius_m}")
    dist = distance_field_m(grid)
    # A small tolerance keeps cells at exactly radius_m inside despite float rounding of the
    # square root in the distance transform.
    occupied = dist <= radius_m + 1e-9 * grid.resolution_m
    return OccupancyGrid(occupied, grid.resolution_m, grid.origin_xy_m, name=f"{grid.name}_inflated")


def costmap(grid: OccupancyGrid, inscribed_radius_m: float, inflation_radius_m: float,
            cost_scaling: float = 3.0) -> np.ndarray:
    """(H, W) Nav2 inflation-layer cost (0..254) of every cell.

    ``cost_scaling`` is Nav2's ``cost_scaling_factor`` (1/m): larger values make the cost fall
    off faster away from obstacles."""
    if not (0 <= inscribed_radius_m <= inflation_radius_m):
        raise DataError("costmap needs 0 <= inscribed_radius_m <= inflation_radius_m, got "
                        f"{inscribed_radius_m} and {inflation_radius_m}")
    if cost_scaling < 0:
        raise DataError(f"cost_scaling must be >= 0, got {cost_scaling}")
    dist = distance_field_m(grid)
    eps = 1e-9 * grid.resolution_m
    cost = np.zeros(dist.shape)
    decay = (dist > inscribed_radius_m + eps) & (dist <= inflation_radius_m + eps)
    cost[decay] = (INSCRIBED_COST - 1.0) * np.exp(-cost_scaling * (dist[decay] - inscribed_radius_m))
    cost[dist <= inscribed_radius_m + eps] = INSCRIBED_COST
    cost[grid.occupied] = LETHAL_COST
    return cost
