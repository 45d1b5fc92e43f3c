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
            cost_scaling: float = 3.0, distance_m: np.ndarray | None = None) -> np.ndarray:
    """(H, W) Nav2 inflation-layer cost (0..254) of every cell.

    ``cost_scaling`` is Nav2's ``cost_scaling_factor`` (1/m): larger values make the cost fall
    off faster away from obstacles. ``distance_m``: the grid's distance field if the caller
    already has it (a navigation stack re-inflating one map as its pose covariance changes)."""
    if not (0 <= inscribed_radius_m <= inflation_radius_m):
        raise DataError("costmap needs 0 <= inscribed_radius_m <= inflation_radius_m, got "
                        f"{inscribed_radius_m} and {inflation_radius_m}")
    if cost_scaling < 0:
        raise DataError(f"cost_scaling must be >= 0, got {cost_scaling}")
    dist = distance_field_m(grid) if distance_m is None else np.asarray(distance_m, float)
    eps = 1e-9 * grid.resolution_m
    cost = np.zeros(dist.shape)
    decay = (dist > inscribed_radius_m + eps) & (dist <= inflation_radius_m + eps)
    cost[decay] = (INSCRIBED_COST - 1.0) * np.exp(-cost_scaling * (dist[decay] - inscribed_radius_m))
    cost[dist <= inscribed_radius_m + eps] = INSCRIBED_COST
    cost[grid.occupied] = LETHAL_COST
    return cost


def chance_sigma_multiplier(collision_probability: float) -> float:
    """k of a one-sided chance constraint: P(n^T e > k sigma_n) = delta for a Gaussian pose error
    e, i.e. k = Phi^-1(1 - delta) (delta = 0.05 -> 1.645, 0.01 -> 2.326)."""
    from scipy.stats import norm

    if not 0.0 < collision_probability < 0.5:
        raise DataError(f"collision_probability must lie in (0, 0.5), got {collision_probability}")
    return float(norm.ppf(1.0 - collision_probability))


def chance_inflation_m(robot_radius_m: float, covariance_xy: np.ndarray, collision_probability: float,
                       direction_xy: np.ndarray | None = None) -> float:
    """Inflation radius that keeps a robot of ``robot_radius_m`` off an obstacle with probability
    1 - delta under a Gaussian position error of ``covariance_xy`` (2, 2): the radius plus k sigma
    of the covariance projected on the obstacle direction n, sigma_n = sqrt(n^T Sigma n) (Blackmore,
    Ono & Williams 2011, chance-constraint tightening). Without a direction the worst one is used
    (sigma = sqrt of the largest eigenvalue), which is what a costmap needs for every obstacle."""
    cov = np.asarray(covariance_xy, float)[:2, :2]
    if direction_xy is None:
        var = float(np.linalg.eigvalsh(0.5 * (cov + cov.T))[-1])
    else:
        n = np.asarray(direction_xy, float).reshape(2)
        n = n / max(float(np.linalg.norm(n)), 1e-12)
        var = float(n @ cov @ n)
    return float(robot_radius_m) + chance_sigma_multiplier(collision_probability) * np.sqrt(max(var, 0.0))
