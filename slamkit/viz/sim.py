"""Rerun recordings of simulated sequences: what the robot saw, where it really was.

Entity tree (mirrors the frame tree; static data logged once):

    world/map                 occupied cell centres of the grid (static)
    world/landmarks           true landmark positions with their ids (static)
    world/ground_truth        the whole true path (static)
    world/robot               the true pose over ``sim_time`` (Transform3D columns)
    world/robot/body          a small marker for the robot footprint (static, body frame)
    world/robot/scan          lidar end points in the body frame, per scan
    world/robot/scan/beams    the beams as segments from the sensor to their end points
    world/robot/observations  range-bearing rays to the landmarks seen, per observation
    world/gps                 GPS fixes (world frame), per fix
    world/moving_obstacles    moving discs at every scan stamp (when the sequence has them)
    plots/odometry/v_mps, plots/odometry/omega_radps   odometry readings (sent as columns)

Time runs on the ``sim_time`` timeline (seconds since the start of the sequence).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from slamkit.data.sequence import Gps, Odometry, RangeBearing, Scan
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.moving_obstacles import MovingObstacles
from slamkit.data.inertial import is_inertial
from slamkit.viz.recording import open_recording
from slamkit.viz.views import labels_fit, scene_bounds, top_down_view

TIMELINE = "sim_time"
COLOR_MAP = (90, 90, 90)
COLOR_LANDMARK = (230, 60, 60)
COLOR_GROUND_TRUTH = (40, 200, 80)
COLOR_SCAN = (30, 120, 255)
COLOR_OBSERVATION = (255, 140, 0)
COLOR_GPS = (200, 60, 200)
COLOR_OBSTACLE = (250, 200, 0)


def blueprint(sequence=None, grid: OccupancyGrid | None = None) -> rrb.Blueprint:
    """The world seen from straight above on a metre grid when the scene is known (a planar
    sequence, its map), beside the odometry plot."""
    world = rrb.Spatial3DView(origin="world", name="world")
    if sequence is not None and not is_inertial(sequence):
        parts = [np.asarray(list(sequence.world_p_landmarks.values()), float)[:, :2]] if sequence.world_p_landmarks else []
        if sequence.ground_truth is not None and len(sequence.ground_truth):
            parts.append(sequence.ground_truth.xytheta()[:, :2])
        if grid is not None:
            parts.append(np.array([grid.origin_xy_m, grid.origin_xy_m + grid.resolution_m * np.array([grid.width, grid.height])]))
        world = top_down_view("world", "world", *scene_bounds(*parts))
    return rrb.Blueprint(
        rrb.Horizontal(
            world,
            rrb.TimeSeriesView(origin="plots", name="odometry"),
            column_shares=[3, 1],
        ),
        collapse_panels=True,
    )


def _xyz(xy: np.ndarray, z: float = 0.0) -> np.ndarray:
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return np.column_stack([xy, np.full(len(xy), z)])


def log_map(stream: rr.RecordingStream, grid: OccupancyGrid, entity: str = "world/map") -> None:
    """Occupied cells as points at their centres, radius half a cell, logged once (static)."""
    iy, ix = np.nonzero(grid.occupied)
    centres = grid.cell_to_world(np.column_stack([ix, iy]))
    stream.log(entity, rr.Points3D(_xyz(centres), radii=[0.5 * grid.resolution_m], colors=[COLOR_MAP]),
               static=True)


def log_sequence(stream: rr.RecordingStream, sequence, grid: OccupancyGrid | None = None,
                 max_beams_drawn: int = 90) -> None:
    """Log a simulated (or any) sequence: map, landmarks, ground truth, robot pose over time,
    scans, range-bearing rays, GPS fixes and odometry plots."""
    if grid is not None:
        log_map(stream, grid)
    lms = sequence.world_p_landmarks
    if lms:
        ids = sorted(lms)
        pts = np.array([np.asarray(lms[i], float)[:2] for i in ids])
        stream.log("world/landmarks", rr.Points3D(_xyz(pts), radii=[0.12], colors=[COLOR_LANDMARK],
                                                  labels=[str(i) for i in ids], show_labels=labels_fit(pts)),
                   static=True)
    gt = sequence.ground_truth
    if gt is not None and len(gt):
        stream.log("world/ground_truth", rr.LineStrips3D([gt.world_t_body], radii=[0.03],
                                                         colors=[COLOR_GROUND_TRUTH]), static=True)
        q = gt.world_q_body_wxyz
        stream.send_columns(
            "world/robot",
            indexes=[rr.TimeColumn(TIMELINE, duration=gt.stamps_s)],
            columns=rr.Transform3D.columns(translation=gt.world_t_body,
                                           quaternion=np.column_stack([q[:, 1:], q[:, :1]])),
        )
        stream.log("world/robot/body", rr.Boxes3D(half_sizes=[[0.25, 0.18, 0.05]],
                                                  colors=[COLOR_GROUND_TRUTH]), static=True)
    obstacles = None
    if isinstance(sequence.metadata, dict) and sequence.metadata.get("moving_obstacles"):
        obstacles = MovingObstacles(**sequence.metadata["moving_obstacles"])
    odo_t, odo_v, odo_w = [], [], []
    for event in sequence:
        if isinstance(event, Odometry):
            odo_t.append(event.stamp_s)
            odo_v.append(event.v_mps)
            odo_w.append(event.omega_radps)
            continue
        if isinstance(event, Scan):
            stream.set_time(TIMELINE, duration=event.stamp_s)
            r = np.asarray(event.ranges_m, float)
            a = np.asarray(event.angles_rad, float)
            ok = np.isfinite(r)
            end = np.column_stack([r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])])
            stream.log("world/robot/scan", rr.Points3D(_xyz(end), radii=[0.03], colors=[COLOR_SCAN]))
            step = max(1, int(np.ceil(len(end) / max_beams_drawn)))
            sub = _xyz(end[::step])
            beams = np.stack([np.zeros_like(sub), sub], axis=1)
            stream.log("world/robot/scan/beams", rr.LineStrips3D(beams, radii=[0.005], colors=[COLOR_SCAN]))
            if obstacles is not None:
                stream.log("world/moving_obstacles",
                           rr.Points3D(_xyz(obstacles.position_at(event.stamp_s)),
                                       radii=obstacles.radius_m, colors=[COLOR_OBSTACLE]))
        elif isinstance(event, RangeBearing):
            stream.set_time(TIMELINE, duration=event.stamp_s)
            r = np.asarray(event.range_m, float)
            b = np.asarray(event.bearing_rad, float)
            end = _xyz(np.column_stack([r * np.cos(b), r * np.sin(b)]))
            rays = np.stack([np.zeros_like(end), end], axis=1)
            stream.log("world/robot/observations",
                       rr.LineStrips3D(rays, radii=[0.01], colors=[COLOR_OBSERVATION],
                                       labels=[str(int(i)) for i in event.landmark_ids]))
        elif isinstance(event, Gps):
            stream.set_time(TIMELINE, duration=event.stamp_s)
            stream.log("world/gps", rr.Points3D(_xyz(np.asarray(event.world_p_body)[:2]),
                                                radii=[0.2], colors=[COLOR_GPS]))
    if odo_t:
        index = [rr.TimeColumn(TIMELINE, duration=np.asarray(odo_t))]
        stream.send_columns("plots/odometry/v_mps", indexes=index,
                            columns=rr.Scalars.columns(scalars=np.asarray(odo_v)))
        stream.send_columns("plots/odometry/omega_radps", indexes=index,
                            columns=rr.Scalars.columns(scalars=np.asarray(odo_w)))


def record_simulation(path: str | Path, sequence, grid: OccupancyGrid | None = None,
                      application_id: str = "slamkit_simulate") -> Path:
    """Write ``sequence`` (and its map) to an ``.rrd`` file atomically; returns the path."""
    with open_recording(application_id, path=path, blueprint=blueprint(sequence, grid)) as rec:
        log_sequence(rec.stream, sequence, grid)
    return Path(path)
