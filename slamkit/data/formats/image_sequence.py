"""A camera sequence on disk: image files, the camera, stamps and ground truth, in the KITTI
odometry layout (``calib.txt`` P0 = the left camera's 3x4 projection, ``poses.txt``
camera-to-world ground truth, stamps = frame index x 0.1 s unless ``times`` are given), or a
registry name (``kitti-vo-a``).

What the ``visual_odometry`` pipeline (:mod:`slamkit.experiments.visual_odometry`) and
``slamkit bench vision`` read; a user drives :class:`slamkit.systems.visual_odometry.VisualOdometry`
with it from a notebook (issue 30: it lived in the pipeline's module).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from slamkit.data import registry
from slamkit.data.formats.image import list_images, read_image
from slamkit.data.formats.kitti import read_kitti, read_kitti_calib
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.models.camera import PinholeCamera

__all__ = ["KITTI_FRAME_PERIOD_S", "ImageSequence", "load_image_sequence"]

#: KITTI odometry frames are 0.1 s apart
KITTI_FRAME_PERIOD_S = 0.1


@dataclass(frozen=True)
class ImageSequence:
    """A resolved camera sequence: image files, the camera, stamps and ground truth (or None)."""

    name: str
    images: tuple[Path, ...]
    camera: PinholeCamera
    stamps_s: np.ndarray
    ground_truth: Trajectory | None = None


def load_image_sequence(spec: str | Mapping[str, Any], max_frames: int | None = None) -> ImageSequence:
    """A registry name or ``{name, images, calib, poses, times}`` (KITTI layout)."""
    if isinstance(spec, str):
        entry = registry.get(spec)
        poses = registry.path_of(entry.name, "poses.txt")
        calib = registry.path_of(entry.name, "calib.txt")
        spec = {"name": entry.name, "images": poses.parent / "image_l", "calib": calib, "poses": poses}
    name = str(spec.get("name") or Path(spec["images"]).parent.name)
    files = list_images(spec["images"])
    if max_frames is not None:
        files = files[:max_frames]
    P0 = read_kitti_calib(spec["calib"])
    P = P0.get("P0", next(iter(P0.values())))
    height, width = read_image(files[0]).shape
    camera = PinholeCamera.from_K(P[:, :3], width=width, height=height)
    gt = None
    if spec.get("poses"):
        gt = read_kitti(spec["poses"], spec.get("times"))
        if len(gt) < len(files):
            raise DataError(f"{len(gt)} poses for {len(files)} images", spec["poses"])
        gt = gt.subset(np.arange(len(files)))
    if spec.get("times"):
        stamps = gt.stamps_s if gt is not None else read_kitti(spec["poses"], spec["times"]).stamps_s
    else:
        stamps = np.arange(len(files)) * KITTI_FRAME_PERIOD_S
    if gt is not None:
        gt = Trajectory.from_matrices(stamps, gt.matrices())
    return ImageSequence(name, tuple(files), camera, np.asarray(stamps, float), gt)
