"""Rerun recordings of lidar SLAM runs (``slamkit.experiments.lidar_slam``, the system in
``slamkit.systems.lidar_slam``), simulated worlds and recorded logs alike.

Entity tree per run (``<run>`` = the result's label, ``<world>_<robust>`` or the log's name;
mirrors the frame tree):

    <run>/world/ground_truth_map        occupied cells of the true grid (static, simulated worlds)
    <run>/world/ground_truth            the true keyframe path (static, simulated worlds)
    <run>/world/trajectory/frontend     chained ICP odometry: before loop closure (static)
    <run>/world/trajectory/optimised    the pose graph after loop closure (static)
    <run>/world/trajectory/scans        every scan's pose (static, recorded logs)
    <run>/world/keyframes               keyframe positions after optimisation (static)
    <run>/world/loop_closures           accepted loop-closure edges (static)
    <run>/world/false_loop_closures     injected wrong edges, when any (static)
    <run>/world/robot                   optimised keyframe pose over the ``keyframe`` timeline
    <run>/world/robot/scan              the keyframe's scan end points in the robot frame
    <run>/map/occupancy                 the growing log-odds map as an image (p(occupied),
                                        rows flipped so north is up), ``map_frames`` times along
                                        the run (at most 0.1 m per cell)
    <run>/plots/icp_fitness ...         not logged: numbers live in results.json

Timelines: ``keyframe`` (index) and ``sim_time`` (seconds).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from slamkit.experiments.lidar_slam import LidarSlamResult
from slamkit.maps.log_odds import LogOddsMap
from slamkit.viz.recording import OutputRecorder, open_recording
from slamkit.viz.views import scene_bounds, top_down_view

COLOR_MAP = (90, 90, 90)
COLOR_GROUND_TRUTH = (40, 200, 80)
COLOR_FRONTEND = (160, 160, 160)
COLOR_OPTIMISED = (30, 120, 255)
COLOR_LOOP = (255, 140, 0)
COLOR_FALSE_LOOP = (230, 30, 30)
COLOR_SCAN = (30, 160, 255)


def blueprint(runs: list[str], results=None) -> rrb.Blueprint:
    """Per run the world seen from straight above on a metre grid (fitted to the run's
    trajectories when ``results`` are given) beside the occupancy map."""
    views = []
    for k, r in enumerate(runs):
        res = results[k] if results is not None else None
        if res is not None:
            parts = [res.optimised_poses[:, :2], res.frontend_poses[:, :2]]
            if res.ground_truth_poses is not None:
                parts.append(res.ground_truth_poses[:, :2])
            views.append(top_down_view(f"{r}/world", f"{r}: world", *scene_bounds(*parts)))
        else:
            views.append(rrb.Spatial3DView(origin=f"{r}/world", name=f"{r}: world"))
        views.append(rrb.Spatial2DView(origin=f"{r}/map", name=f"{r}: map"))
    return rrb.Blueprint(rrb.Grid(*views), collapse_panels=True)


def _xyz(xy: np.ndarray, z: float = 0.0) -> np.ndarray:
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return np.column_stack([xy, np.full(len(xy), z)])


def _map_image(m: LogOddsMap) -> np.ndarray:
    """uint8 grey image: white free, black occupied, mid-grey unknown; row 0 at the top (north)."""
    return np.ascontiguousarray((255.0 * (1.0 - m.probability()))[::-1].astype(np.uint8))


def run_label(result) -> str:
    return result.label or f"{result.name}_{result.config.robust}"


def log_lidar_slam(stream: rr.RecordingStream, result, prefix: str = "", map_frames: int = 40) -> None:
    """Log one ``LidarSlamResult`` under ``prefix`` (see the module docstring)."""
    p = f"{prefix}/" if prefix else ""
    if result.truth is not None:
        g = result.truth
        iy, ix = np.nonzero(g.occupied)
        stream.log(f"{p}world/ground_truth_map",
                   rr.Points3D(_xyz(g.cell_to_world(np.column_stack([ix, iy]))),
                               radii=[0.5 * g.resolution_m], colors=[COLOR_MAP]), static=True)
    if result.ground_truth_poses is not None:
        stream.log(f"{p}world/ground_truth", rr.LineStrips3D([_xyz(result.ground_truth_poses[:, :2])],
                                                             radii=[0.02], colors=[COLOR_GROUND_TRUTH]),
                   static=True)
    fe, opt = result.frontend_poses, result.optimised_poses
    stream.log(f"{p}world/trajectory/frontend",
               rr.LineStrips3D([_xyz(fe[:, :2])], radii=[0.02], colors=[COLOR_FRONTEND]), static=True)
    stream.log(f"{p}world/trajectory/optimised",
               rr.LineStrips3D([_xyz(opt[:, :2])], radii=[0.03], colors=[COLOR_OPTIMISED]), static=True)
    if result.scan_poses is not None and result.ground_truth_poses is None:
        # a recorded log: the trajectory of every scan (what the relations score)
        stream.log(f"{p}world/trajectory/scans", rr.LineStrips3D([_xyz(result.scan_poses[:, :2])], radii=[0.01],
                                                                 colors=[COLOR_OPTIMISED]), static=True)
    stream.log(f"{p}world/keyframes", rr.Points3D(_xyz(opt[:, :2]), radii=[0.06], colors=[COLOR_OPTIMISED],
                                                  labels=[str(k) for k in range(len(opt))]),
               static=True)
    if result.loops:
        seg = np.stack([_xyz(opt[[lc.i for lc in result.loops], :2]),
                        _xyz(opt[[lc.j for lc in result.loops], :2])], axis=1)
        stream.log(f"{p}world/loop_closures", rr.LineStrips3D(seg, radii=[0.015], colors=[COLOR_LOOP]),
                   static=True)
    if result.false_loops:
        fl = np.asarray(result.false_loops)
        seg = np.stack([_xyz(opt[fl[:, 0], :2]), _xyz(opt[fl[:, 1], :2])], axis=1)
        stream.log(f"{p}world/false_loop_closures",
                   rr.LineStrips3D(seg, radii=[0.03], colors=[COLOR_FALSE_LOOP]), static=True)
    # robot pose per keyframe as transform columns, scans in the robot frame
    k = np.arange(len(opt))
    times = [rr.TimeColumn("keyframe", sequence=k), rr.TimeColumn("sim_time", duration=result.stamps_s)]
    half = 0.5 * opt[:, 2]
    quat_xyzw = np.column_stack([np.zeros(len(opt)), np.zeros(len(opt)), np.sin(half), np.cos(half)])
    stream.send_columns(f"{p}world/robot", indexes=times,
                        columns=rr.Transform3D.columns(translation=_xyz(opt[:, :2]), quaternion=quat_xyzw))
    # the growing map: every keyframe integrated, an image logged map_frames times (at 0.1 m per
    # cell or finer maps coarsened to it, so a 45-minute log stays a few MB)
    cfg = result.map.config
    coarse = replace(cfg, resolution_m=max(cfg.resolution_m, 0.1))
    hi = result.map.origin_xy_m + np.array(result.map.shape[::-1]) * result.map.resolution_m
    m = LogOddsMap.covering(result.map.origin_xy_m, hi, coarse)
    every = max(1, len(opt) // max(map_frames, 1))
    sensor = result.sensor_poses(opt)
    for i, pts in enumerate(result.keyframe_points):
        stream.set_time("keyframe", sequence=i)
        stream.set_time("sim_time", duration=float(result.stamps_s[i]))
        stream.log(f"{p}world/robot/scan", rr.Points3D(_xyz(pts), radii=[0.03], colors=[COLOR_SCAN]))
        if result.keyframe_ranges_m:
            m.update(sensor[i], result.keyframe_angles_rad[i], result.keyframe_ranges_m[i], result.max_range_m)
            if i % every == 0 or i == len(opt) - 1:
                stream.log(f"{p}map/occupancy", rr.Image(_map_image(m), color_model="L"))


def record_lidar_slam(results, path: str | Path | None = None, spawn: bool = False) -> Path | None:
    """Record ``LidarSlamResult``s (one subtree each) to ``path`` and/or a spawned viewer."""
    results = list(results)
    labels = [run_label(r) for r in results]
    with open_recording("slamkit_lidar_slam", path, spawn, blueprint(labels, results)) as rec:
        for label, res in zip(labels, results):
            log_lidar_slam(rec.stream, res, label)
    return None if path is None else Path(path)


class LidarSlamObserver(OutputRecorder):
    """Records the ``lidar_slam`` pipeline from its output (``payload``: LidarSlamResult list)."""

    payload_type = list[LidarSlamResult]

    def on_output(self, output) -> None:
        results = output.payload  # a PipelineOutput whose payload is the LidarSlamResult list
        if results:
            record_lidar_slam(results, self.path, self.spawn)
