"""Rerun recordings of visual odometry runs (``slamkit.experiments.visual_odometry``).

Entity tree per run (``<run>`` = ``<sequence>/<label>``; mirrors the frame tree: the world is the
first camera, z forward, and an estimate with ground truth is drawn after its Sim(3) alignment
so both share the metric frame):

    <run>/world/ground_truth            the true camera path (static)
    <run>/world/estimate                the estimated camera path (static)
    <run>/world/points                  the triangulated map points (static)
    <run>/world/camera                  the camera pose over the ``frame`` timeline
    <run>/world/camera/image            pinhole (the frustum) and the frame, half resolution
                                        (JPEG), first run of a sequence only
    <run>/world/camera/image/keypoints  the frame's ORB keypoints
    <run>/world/camera/image/matches    putative matches drawn from the previous keypoint
                                        position: essential-matrix inliers green, outliers red

Timelines: ``frame`` (index) and ``sensor_time`` (seconds).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from slamkit.data.formats.image import read_image
from slamkit.experiments.visual_odometry import VoPayload, VoRun
from slamkit.geometry import se3, so3
from slamkit.metrics.alignment import align
from slamkit.viz.recording import OutputRecorder, open_recording

COLOR_GROUND_TRUTH = (40, 200, 80)
COLOR_ESTIMATE = (30, 120, 255)
COLOR_POINTS = (200, 200, 200)
COLOR_KEYPOINT = (255, 200, 0)
COLOR_INLIER = (40, 220, 40)
COLOR_OUTLIER = (230, 40, 40)
IMAGE_SCALE = 0.5


def run_path(run: VoRun) -> str:
    return f"{run.sequence.name}/{run.label}"


def blueprint(paths: list[str]) -> rrb.Blueprint:
    views = []
    for p in paths:
        views.append(rrb.Spatial3DView(origin=f"{p}/world", name=f"{p}: world"))
        views.append(rrb.Spatial2DView(origin=f"{p}/world/camera/image", name=f"{p}: image"))
    return rrb.Blueprint(rrb.Grid(*views), collapse_panels=True)


def _aligned(run: VoRun) -> tuple[np.ndarray, np.ndarray]:
    """(world_T_camera (F, 4, 4), world_p (P, 3)) in the ground truth's metric frame when there
    is one (Sim(3) alignment), else as estimated."""
    poses, points = run.estimate.world_T_camera, run.estimate.world_p
    gt = run.sequence.ground_truth
    if gt is None or len(poses) < 3:
        return poses, points
    a = align(run.trajectory(), gt, "sim3")
    out = poses.copy()
    out[:, :3, :3] = a.rotation @ poses[:, :3, :3]
    out[:, :3, 3] = a.scale * poses[:, :3, 3] @ a.rotation.T + a.translation
    return out, a.scale * points @ a.rotation.T + a.translation


def log_vo_run(stream: rr.RecordingStream, run: VoRun, with_images: bool = True, max_frames: int = 60) -> None:
    p = run_path(run)
    poses, points = _aligned(run)
    gt = run.sequence.ground_truth
    if gt is not None:
        stream.log(f"{p}/world/ground_truth", rr.LineStrips3D([gt.world_t_body], radii=[0.05],
                                                             colors=[COLOR_GROUND_TRUTH]), static=True)
    stream.log(f"{p}/world/estimate", rr.LineStrips3D([poses[:, :3, 3]], radii=[0.05], colors=[COLOR_ESTIMATE]),
               static=True)
    if len(points):
        stream.log(f"{p}/world/points", rr.Points3D(points, radii=[0.03], colors=[COLOR_POINTS]), static=True)
    n = len(run.frames)
    times = [rr.TimeColumn("frame", sequence=np.arange(n)), rr.TimeColumn("sensor_time", duration=run.estimate.stamps_s)]
    quat_wxyz = so3.to_quat_wxyz(se3.rotation(poses))
    stream.send_columns(f"{p}/world/camera", indexes=times,
                        columns=rr.Transform3D.columns(translation=se3.translation(poses),
                                                       quaternion=quat_wxyz[:, [1, 2, 3, 0]]))
    cam = run.sequence.camera
    s = IMAGE_SCALE
    stream.log(f"{p}/world/camera/image",
               rr.Pinhole(focal_length=[cam.fx * s, cam.fy * s], principal_point=[cam.cx * s, cam.cy * s],
                          width=int(round(cam.width * s)), height=int(round(cam.height * s)),
                          camera_xyz=rr.ViewCoordinates.RDF, image_plane_distance=1.0), static=True)
    every = max(1, int(np.ceil(n / max(max_frames, 1))))
    previous_uv = None
    for k, frame in enumerate(run.frames):
        if k % every and k != n - 1:
            previous_uv = frame.keypoints_uv
            continue
        stream.set_time("frame", sequence=k)
        stream.set_time("sensor_time", duration=float(frame.stamp_s))
        if with_images:
            grey = read_image(run.sequence.images[k])[::2, ::2] if s == 0.5 else read_image(run.sequence.images[k])
            stream.log(f"{p}/world/camera/image", rr.Image(np.clip(grey, 0, 255).astype(np.uint8),
                                                           color_model="L").compress(jpeg_quality=75))
        stream.log(f"{p}/world/camera/image/keypoints",
                   rr.Points2D(frame.keypoints_uv * s, radii=[1.0], colors=[COLOR_KEYPOINT]))
        if previous_uv is not None and len(frame.matches):
            seg = np.stack([previous_uv[frame.matches[:, 0]], frame.keypoints_uv[frame.matches[:, 1]]], axis=1) * s
            colors = np.where(frame.inliers[:, None], COLOR_INLIER, COLOR_OUTLIER).astype(np.uint8)
            stream.log(f"{p}/world/camera/image/matches", rr.LineStrips2D(seg, radii=[0.5], colors=colors))
        previous_uv = frame.keypoints_uv


def record_visual_odometry(payload: VoPayload, path: str | Path | None = None, spawn: bool = False) -> Path | None:
    runs = list(payload.runs)
    with open_recording("slamkit_visual_odometry", path, spawn, blueprint([run_path(r) for r in runs])) as rec:
        imaged: set[str] = set()
        for r in runs:
            log_vo_run(rec.stream, r, with_images=r.sequence.name not in imaged, max_frames=payload.max_recorded_frames)
            imaged.add(r.sequence.name)
    return None if path is None else Path(path)


class VisualOdometryObserver(OutputRecorder):
    """Records the ``visual_odometry`` pipeline from its output (``payload``: VoPayload)."""

    payload_type = VoPayload

    def on_output(self, output) -> None:
        if output.payload is not None and output.payload.runs:
            record_visual_odometry(output.payload, self.path, self.spawn)
