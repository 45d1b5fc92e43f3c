"""The world of the ``local_planning`` comparison: a seeded static map (the office and warehouse
generators at 20 m x 20 m, or an open room with boxes), moving circles crossing the path, the
perfect obstacle sensor and the ground-truth clearance that decides a collision.

What the controller is told (a :class:`slamkit.control.protocols.LocalWorld`) and the start, goal
and global path of a scenario (drawn with A*) are assembled in
:mod:`slamkit.experiments.closed_loop`: this layer may not plan, and the controllers' types are
the control layer's (the same split as :mod:`slamkit.sim.navigation_world` and
``slamkit.experiments.navigation``). Moved here from the pipeline module in issue 30.
"""

from __future__ import annotations

import numpy as np

from slamkit.errors import ConfigError
from slamkit.maps.distance_field import bilinear
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.moving_obstacles import MovingObstacles
from slamkit.sim.navigation_world import world_map

__all__ = ["SCENARIO_KINDS", "clearance_m", "open_room", "scenario_map", "visible_obstacles"]

SCENARIO_KINDS = ("office", "warehouse", "open")


def open_room(rng: np.random.Generator, width_m: float = 16.0, height_m: float = 12.0,
              resolution_m: float = 0.1, boxes: int = 6) -> OccupancyGrid:
    """A walled room (two-cell walls) with ``boxes`` rectangular boxes of 5-12 cells a side, kept
    10 cells off the walls."""
    w, h = int(round(width_m / resolution_m)), int(round(height_m / resolution_m))
    occ = np.zeros((h, w), dtype=bool)
    t = 2  # two-cell walls
    occ[:t, :] = occ[-t:, :] = occ[:, :t] = occ[:, -t:] = True
    for _ in range(boxes):
        bw, bh = rng.integers(5, 13, size=2)
        x0, y0 = rng.integers(t + 10, w - t - 10 - bw), rng.integers(t + 10, h - t - 10 - bh)
        occ[y0:y0 + bh, x0:x0 + bw] = True
    return OccupancyGrid(occ, resolution_m, np.zeros(2), name="open")


def scenario_map(kind: str, rng: np.random.Generator) -> OccupancyGrid:
    """The static map of a scenario of ``kind`` (one of :data:`SCENARIO_KINDS`), drawn from ``rng``."""
    if kind == "open":
        return open_room(rng)
    if kind in ("office", "warehouse"):
        return world_map(kind, rng, resolution_m=0.1, size_m=20.0)
    raise ConfigError(f"unknown scenario kind {kind!r}; choose from {SCENARIO_KINDS}")


def visible_obstacles(obstacles: MovingObstacles, world_xy_m: np.ndarray, t_s: float, sensor_range_m: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The perfect tracker: centres (K, 2), radii (K,) and velocities (K, 2) at ``t_s`` of the
    circles whose surface is within ``sensor_range_m`` of the robot's centre, their true values."""
    xy = obstacles.position_at(t_s)
    seen = np.linalg.norm(xy - world_xy_m, axis=1) - obstacles.radius_m <= sensor_range_m
    return xy[seen], obstacles.radius_m[seen], obstacles.velocity_at(t_s)[seen]


def clearance_m(grid: OccupancyGrid, distance_m: np.ndarray, obstacles: MovingObstacles, xy_m: np.ndarray,
                t_s: float, robot_radius_m: float) -> float:
    """Distance from the robot's disc to the nearest obstacle surface (< 0: collision).
    ``distance_m`` is the map's distance field on its cells (bilinear between cell centres, 0
    outside); static distances run between cell centres, so half a cell is taken off for the
    occupied cell's extent."""
    d_static = float(bilinear(distance_m, grid.resolution_m, grid.origin_xy_m, xy_m, outside=0.0)[0]) \
        - 0.5 * grid.resolution_m
    d = d_static
    if len(obstacles):
        centres = obstacles.position_at(t_s)
        d = min(d, float((np.linalg.norm(centres - xy_m, axis=1) - obstacles.radius_m).min()))
    return d - robot_radius_m
