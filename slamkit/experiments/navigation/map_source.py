"""The robot's map in the navigation pipeline (issue 14, step 1): where the static map the stack
plans and localises on comes from. The simulator always keeps the true world for physics and
scoring; only the stack's map changes.

Sources (``map: {source: ...}`` in ``pipelines/navigation*.yaml``):

* ``truth`` -- the world's own grid (for ``willow`` that is the ROS map itself);
* ``slam_tour`` -- built offline by slamkit's own lidar SLAM (the system
  :func:`slamkit.systems.slam_map.slam_map`) on a seeded mapping tour of the world: the
  grid-world simulator drives the robot through ``tour_goals`` goals spread over the free space
  (:func:`slamkit.sim.grid_world.mapping_tour`, its 360-beam lidar and noisy wheel
  odometry), SLAM runs on the tour, and its log-odds map at ``resolution_m`` (5 cm) is the
  robot's map. The map's frame is the SLAM estimate's: the robot was put down at the tour's
  known start pose, nothing is aligned to the ground truth afterwards, so any drift SLAM leaves
  is in the map the robot navigates on. Cells no tour scan observed are occupied in the robot's
  map (``unknown: occupied``: the robot only drives where it has mapped) or free
  (``unknown: free``, ROS's ``allow_unknown``).

Scored against the true grid (the metrics every episode on that map carries): ``map_precision_1cell``
/ ``map_recall_1cell`` / ``map_iou_1cell`` (occupied cells matched within one cell, on the cells
the tour observed: :func:`slamkit.maps.log_odds.map_quality`), ``map_free_coverage`` (the true
free cells the map holds as observed and free), ``map_tour_ate_m`` (keyframe ATE RMSE after SE(2)
alignment, as the lidar_slam pipeline reports it), ``map_tour_error_max_m`` (the largest keyframe
position error *without* alignment: the error the map's frame carries), ``map_build_s``.

The built map is cached per world (the true grid's fingerprint and the source config) under the
results folder (``maps/<world>_<key>.npz``), so the variants of a run build it once.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from slamkit.config import build
from slamkit.errors import ConfigError
from slamkit.geometry import se2
from slamkit.maps.log_odds import map_quality, resample_to
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.metrics.trajectory_score import ate_at_stamps_m, poses_at_stamps
from slamkit.paths import atomic_file
from slamkit.sim.grid_world import mapping_tour
from slamkit.sim.navigation_world import NavigationScenario
from slamkit.systems.lidar_slam import LidarSlamConfig
from slamkit.systems.slam_map import slam_map

MAP_SOURCES = ("truth", "slam_tour")


def _tour_slam() -> dict[str, Any]:
    # pipelines/lidar_slam.yaml's settings for the simulated worlds, with the map at 5 cm
    return {"keyframes": {"min_translation_m": 0.5, "min_rotation_rad": 0.35},
            "icp": {"method": "point_to_line", "trim_fraction": 0.9, "max_correspondence_m": 1.0},
            "loops": {"search_radius_m": 3.0, "min_fitness": 0.6, "max_candidates_per_keyframe": 2,
                      "icp": {"trim_fraction": 0.9}}}


@dataclass(frozen=True)
class MapSourceConfig:
    source: str = "truth"
    #: the mapping tour: goals spread over the free space (farthest-point sampling along the
    #: routes, ``slamkit.sim.grid_world.route``), joined by shortest routes, driven by pure
    #: pursuit for at most ``tour_duration_s`` at ``tour_speed_mps``
    tour_goals: int = 10
    tour_duration_s: float = 300.0
    tour_speed_mps: float = 0.6
    #: the routes keep this far from walls: 0.45 m, the grid world's default, shuts the tour out
    #: of rooms behind 1 m doors (office seed 0, 8 goals, share of the true free cells the map
    #: observed: 0.75 random goals at 0.45 m, 0.82 spread at 0.45 m, 0.97 spread at 0.3 m)
    tour_clearance_m: float = 0.3
    #: the robot's map resolution
    resolution_m: float = 0.05
    #: cells the tour never observed: "occupied" or "free"
    unknown: str = "occupied"
    #: LidarSlamConfig fields as a mapping (nested like pipelines/lidar_slam.yaml's ``slam``)
    slam: Mapping[str, Any] = field(default_factory=_tour_slam)

    def __post_init__(self) -> None:
        if self.source not in MAP_SOURCES:
            raise ConfigError(f"map.source: {self.source!r}; choose from {MAP_SOURCES}")
        if self.unknown not in ("occupied", "free"):
            raise ConfigError(f"map.unknown: {self.unknown!r}; choose from ('occupied', 'free')")
        if not (isinstance(self.tour_goals, int) and self.tour_goals >= 1):
            raise ConfigError(f"map.tour_goals must be an integer >= 1, got {self.tour_goals!r}")
        for name in ("tour_duration_s", "tour_speed_mps", "tour_clearance_m", "resolution_m"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"map.{name} must be a finite number > 0, got {v!r}")
        build(LidarSlamConfig, self.slam, "lidar_slam.slam")  # unknown keys and bad values are errors now, not mid-run


@dataclass(frozen=True)
class RobotMap:
    """The stack's map and how it compares with the truth (empty for ``truth``).

    ``anchors_world_xytheta`` / ``anchors_map_xytheta`` (K, 3): the mapping tour's keyframes, true
    and as SLAM placed them in the map (None for ``truth``, whose frame is the world's). A user
    gives the robot its start and goal *on its map* (RViz's pose estimate and goal): the place on
    the map where the physical target appears. :meth:`to_map` reproduces that from the nearest
    keyframe, so a map frame that drifted a few cm from the world does not turn into a missed
    goal, while success is still scored against the true goal in the world."""

    grid: OccupancyGrid
    source: str
    metrics: Mapping[str, float] = field(default_factory=dict)
    anchors_world_xytheta: np.ndarray | None = field(default=None, repr=False)
    anchors_map_xytheta: np.ndarray | None = field(default=None, repr=False)

    def to_map(self, world_xytheta: np.ndarray) -> np.ndarray:
        """A world pose (3,) as it appears in the robot's map: through the transform of the
        keyframe nearest to it (map_T_world = map_T_key (world_T_key)^-1)."""
        pose = np.asarray(world_xytheta, dtype=float)
        if self.anchors_world_xytheta is None:
            return pose.copy()
        k = int(np.argmin(np.linalg.norm(self.anchors_world_xytheta[:, :2] - pose[:2], axis=1)))
        map_T_world = se2.compose(self.anchors_map_xytheta[k], se2.inverse(self.anchors_world_xytheta[k]))
        return se2.compose(map_T_world, pose)


def robot_map(scenario: NavigationScenario, config: MapSourceConfig, cache_dir: Path | None = None) -> RobotMap:
    """The map the stack of ``scenario`` gets (see the module docstring)."""
    if config.source == "truth":
        return RobotMap(scenario.grid, "truth")
    key = _cache_key(scenario.grid, config)
    world = scenario.name.rsplit("_", 1)[0]
    path = None if cache_dir is None else Path(cache_dir) / f"{world}_{key}.npz"
    if path is not None and path.is_file():
        with np.load(path) as z:
            grid = OccupancyGrid(z["occupied"], float(z["resolution_m"]), z["origin_xy_m"],
                                 name=f"{world}_slam_tour")
            return RobotMap(grid, config.source, json.loads(str(z["metrics"])),
                            z["anchors_world_xytheta"], z["anchors_map_xytheta"])
    robot = slam_tour_map(scenario.grid, config, seed=int(key[:8], 16), name=f"{world}_slam_tour")
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        g = robot.grid
        # whole or absent: an interrupted write must not leave a map the next run would load
        with atomic_file(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, occupied=g.occupied, resolution_m=g.resolution_m,
                                origin_xy_m=g.origin_xy_m, metrics=json.dumps(robot.metrics),
                                anchors_world_xytheta=robot.anchors_world_xytheta,
                                anchors_map_xytheta=robot.anchors_map_xytheta)
    return robot


def _cache_key(truth: OccupancyGrid, config: MapSourceConfig) -> str:
    h = hashlib.sha1(np.packbits(truth.occupied).tobytes())
    h.update(repr((truth.shape, truth.resolution_m, truth.origin_xy_m.tolist())).encode())
    h.update(json.dumps(dataclasses.asdict(config), sort_keys=True, default=str).encode())
    return h.hexdigest()[:12]


def slam_tour_map(truth: OccupancyGrid, config: MapSourceConfig, seed: int,
                  name: str = "slam_tour") -> RobotMap:
    """Drive a seeded mapping tour through ``truth``, run lidar SLAM on it and return the
    robot's map (on ``truth``'s extent at ``config.resolution_m``) with its scores and the tour's
    keyframes as anchors between the world and the map."""
    t0 = time.perf_counter()
    sequence = mapping_tour(truth, config.tour_goals, config.tour_clearance_m, config.tour_duration_s,
                            config.tour_speed_mps, np.random.default_rng(seed), name)
    slam = build(LidarSlamConfig, {**dict(config.slam), "map": {**dict(config.slam.get("map", {})),
                                                                "resolution_m": config.resolution_m}},
                 "lidar_slam.slam")
    # the map is built at SLAM's own poses, in the frame of the tour's known start, on truth's cells
    built = slam_map(sequence, slam, like=truth, unknown=config.unknown, name=name)
    log_odds, grid = built.log_odds, built.grid
    quality = map_quality(log_odds, truth, tolerance_cells=1)
    truth_free = ~resample_to(truth, log_odds.shape, log_odds.origin_xy_m, log_odds.resolution_m)
    held_free = log_odds.observed & ~log_odds.occupancy_grid().occupied
    stamps = np.asarray(built.estimate.keyframe_stamps_s)
    poses = built.estimate.keyframe_poses
    gt = poses_at_stamps(sequence.ground_truth, stamps)
    metrics = {
        "map_precision_1cell": quality.precision,
        "map_recall_1cell": quality.recall,
        "map_iou_1cell": quality.iou,
        "map_free_coverage": float((truth_free & held_free).sum() / max(truth_free.sum(), 1)),
        "map_tour_ate_m": ate_at_stamps_m(sequence.ground_truth, stamps, poses),
        "map_tour_error_max_m": float(np.linalg.norm(poses[:, :2] - gt[:, :2], axis=1).max()),
        "map_tour_length_m": float(np.linalg.norm(np.diff(gt[:, :2], axis=0), axis=1).sum()),
        "map_loop_closures": float(len(built.estimate.loops)),
        "map_build_s": time.perf_counter() - t0,
    }
    return RobotMap(grid, config.source, metrics, np.asarray(gt, float), np.asarray(poses, float))

