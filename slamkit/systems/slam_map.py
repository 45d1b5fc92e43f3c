"""A robot's map built by lidar SLAM (issue 30: the navigation map built by SLAM is a system).

:func:`slam_map` runs :class:`~slamkit.systems.lidar_slam.LidarSlam` over a recorded (or
simulated) sequence and returns the log-odds map of its keyframe scans at the optimised poses, in
the frame of the sequence's start pose (nothing is aligned to a ground truth: whatever drift SLAM
leaves is in the map), and the occupancy grid a navigation stack plans and localises on: cells
no scan observed are occupied (``unknown="occupied"``: the robot drives only where it has
mapped) or free (``"free"``, ROS's ``allow_unknown``). :func:`config_for` gives the SLAM config
the lidar mounting the recording states.

Scoring a map against a world (quality, the tour's ATE) is the experiment's
(:mod:`slamkit.experiments.navigation.map_source`); driving a mapping tour is the simulator's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from slamkit.data.sequence import Sequence
from slamkit.errors import ConfigError
from slamkit.geometry import se2
from slamkit.maps.log_odds import LogOddsMap
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.systems.lidar_slam import LidarSlam, LidarSlamConfig, LidarSlamEstimate, occupancy_map

UNKNOWN = ("occupied", "free")


def config_for(sequence: Sequence, config: LidarSlamConfig) -> LidarSlamConfig:
    """``config`` with the lidar mounting the recording states (``metadata['body_xytheta_lidar']``)
    unless the config sets one."""
    mount = sequence.metadata.get("body_xytheta_lidar")
    if mount is not None and not np.any(config.body_xytheta_lidar):
        return replace(config, body_xytheta_lidar=tuple(float(v) for v in mount))
    return config


@dataclass(frozen=True)
class SlamMap:
    """What :func:`slam_map` built: the robot's ``grid``, the ``log_odds`` map it is read from,
    SLAM's ``estimate`` (keyframe stamps and poses in the map frame, loop closures) and the
    ``config`` it ran with (the recording's lidar mounting filled in)."""

    grid: OccupancyGrid
    log_odds: LogOddsMap
    estimate: LidarSlamEstimate
    config: LidarSlamConfig


def slam_map(sequence: Sequence, config: LidarSlamConfig = LidarSlamConfig(), like: OccupancyGrid | None = None,
             unknown: str = "occupied", name: str = "slam_map") -> SlamMap:
    """Run lidar SLAM over ``sequence`` and build the robot's map at ``config.map`` (on the cells
    of ``like`` when given, else covering every return), see the module docstring."""
    if unknown not in UNKNOWN:
        raise ConfigError(f"unknown: {unknown!r}; choose from {UNKNOWN}")
    config = config_for(sequence, config)
    system = LidarSlam(config, sequence.initial_world_xytheta_body, None, name=sequence.name)
    for ev in sequence:
        system.step(ev)
    est = system.finish()
    _points, ranges, angles = system.keyframe_scans()
    sensors = se2.compose(np.asarray(est.keyframe_poses, float).reshape(-1, 3),
                          np.asarray(config.body_xytheta_lidar, float))
    log_odds = occupancy_map(sensors, angles, ranges, system.max_range_m, config.map, like=like)
    occupied = log_odds.occupancy_grid().occupied
    if unknown == "occupied":
        occupied = occupied | ~log_odds.observed
    grid = OccupancyGrid(occupied, log_odds.resolution_m, log_odds.origin_xy_m, name=name)
    return SlamMap(grid, log_odds, est, config)
