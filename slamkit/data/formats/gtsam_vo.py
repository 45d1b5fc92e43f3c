"""gtsam's stereo visual-odometry example files (``StereoVOExample_large.py``): real KITTI
stereo features in three whitespace-separated text files.

* calibration: ``fx fy skew cx cy baseline_m`` (and optionally a 4x4 body_T_camera, ignored);
* camera poses: ``id`` then the 16 entries of the 4x4 ``world_T_camera`` row major (the
  initial estimate: camera z forward, x right, y down);
* stereo factors: ``pose_id landmark_id uL uR v X Y Z``: one stereo observation (left and right
  column, common row, pixels) with (X, Y, Z) the landmark in that camera's frame (an initial
  estimate from the disparity).

Bad input -> ``DataError`` naming the file and one-based line.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slamkit.errors import DataError


@dataclass(frozen=True)
class StereoVoData:
    fx: float
    fy: float
    skew: float
    cx: float
    cy: float
    baseline_m: float
    pose_ids: np.ndarray          #: (F,) ints
    world_T_camera: np.ndarray    #: (F, 4, 4) initial estimate
    obs_pose: np.ndarray          #: (M,) pose id of each observation
    obs_landmark: np.ndarray      #: (M,) landmark id
    obs_uL_uR_v: np.ndarray       #: (M, 3) pixels
    obs_camera_p: np.ndarray      #: (M, 3) the landmark in the observing camera's frame


def _rows(path: Path, min_fields: int) -> np.ndarray:
    rows = []
    try:
        lines = path.read_text().splitlines()
    except FileNotFoundError:
        raise DataError("no such file", path) from None
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            values = [float(v) for v in line.split()]
        except ValueError:
            raise DataError("a field is not a number", path, number) from None
        if len(values) < min_fields or not np.isfinite(values).all():
            raise DataError(f"expected at least {min_fields} finite numbers, got {len(values)}", path, number)
        rows.append(values[:min_fields])
    if not rows:
        raise DataError("the file holds no rows", path)
    return np.asarray(rows)


def read_stereo_vo(calibration: str | Path, poses: str | Path, factors: str | Path) -> StereoVoData:
    cal = _rows(Path(calibration), 6)[0]
    if not (cal[0] > 0 and cal[1] > 0 and cal[5] > 0):
        raise DataError("focal lengths and baseline must be positive", calibration, 1)
    P = _rows(Path(poses), 17)
    F = _rows(Path(factors), 8)
    known = set(P[:, 0].astype(int).tolist())
    unknown = sorted(set(F[:, 0].astype(int).tolist()) - known)
    if unknown:
        raise DataError(f"factors refer to poses {unknown[:5]} that the pose file does not list", factors)
    return StereoVoData(float(cal[0]), float(cal[1]), float(cal[2]), float(cal[3]), float(cal[4]), float(cal[5]),
                        P[:, 0].astype(int), P[:, 1:].reshape(-1, 4, 4), F[:, 0].astype(int), F[:, 1].astype(int),
                        F[:, 2:5], F[:, 5:8])
