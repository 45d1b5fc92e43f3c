"""The parsed pose-graph problem every reader returns and the back-end consumes.

Conventions (one place, so readers and back-end agree):

* 2D: ``poses`` (N, 3) = (x, y, theta) of ``world_T_body``; ``measurements`` (M, 3) =
  ``from_T_to`` as (dx, dy, dtheta); ``information`` (M, 3, 3) in that same (x, y, theta)
  order, which is also GTSAM's Pose2 tangent order.
* 3D: ``poses`` (N, 7) = (x, y, z, qw, qx, qy, qz); ``measurements`` (M, 7) likewise;
  ``information`` (M, 6, 6) in g2o order (x, y, z, rx, ry, rz) -- translation first. GTSAM's
  Pose3 tangent is rotation first; the back-end permutes.
* ``vertex_ids`` are the file's ids; edges refer to ids, not row indices.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from slamkit.errors import DataError
from slamkit.geometry import se3


@dataclass(frozen=True)
class PoseGraph:
    dim: int
    vertex_ids: np.ndarray
    poses: np.ndarray
    edge_from: np.ndarray
    edge_to: np.ndarray
    measurements: np.ndarray
    information: np.ndarray
    name: str = "pose_graph"
    source: str | None = None
    #: False when the file had no vertices and ``poses`` were chained from odometry edges.
    has_initial: bool = True
    #: free-form notes a reader attaches (for example how many edges were repaired)
    notes: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        if self.dim not in (2, 3):
            raise DataError(f"pose graph dimension must be 2 or 3, got {self.dim}", self.source)
        pose_width, meas_width, info_width = (3, 3, 3) if self.dim == 2 else (7, 7, 6)
        ids = np.asarray(self.vertex_ids, dtype=np.int64).reshape(-1)
        poses = np.asarray(self.poses, dtype=float).reshape(-1, pose_width)
        ef = np.asarray(self.edge_from, dtype=np.int64).reshape(-1)
        et = np.asarray(self.edge_to, dtype=np.int64).reshape(-1)
        meas = np.asarray(self.measurements, dtype=float).reshape(-1, meas_width)
        info = np.asarray(self.information, dtype=float).reshape(-1, info_width, info_width)
        if len(ids) != len(poses):
            raise DataError(f"{len(ids)} vertex ids but {len(poses)} poses", self.source)
        if not (len(ef) == len(et) == len(meas) == len(info)):
            raise DataError("edge arrays disagree in length", self.source)
        for name, value in (
            ("vertex_ids", ids), ("poses", poses), ("edge_from", ef), ("edge_to", et),
            ("measurements", meas), ("information", info),
        ):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def num_poses(self) -> int:
        return len(self.vertex_ids)

    @property
    def num_edges(self) -> int:
        return len(self.edge_from)

    def index_of(self) -> dict[int, int]:
        """Map from vertex id to row index."""
        return {int(v): i for i, v in enumerate(self.vertex_ids)}

    def is_odometry(self) -> np.ndarray:
        """Boolean mask (M,) of edges between consecutive vertex ids (the rest are loop closures)."""
        return np.abs(self.edge_to - self.edge_from) == 1


def rows_to_transforms(dim: int, rows: np.ndarray) -> np.ndarray:
    """Poses or measurements in the PoseGraph layout -> the group's array form: planar (..., 3)
    (x, y, theta) unchanged, spatial (..., 7) (x, y, z, qw, qx, qy, qz) -> (..., 4, 4)."""
    rows = np.asarray(rows, dtype=float)
    return rows if dim == 2 else se3.from_quat_wxyz_t(rows[..., 3:7], rows[..., :3])


def transforms_to_rows(dim: int, transforms: np.ndarray) -> np.ndarray:
    """The inverse of :func:`rows_to_transforms` (spatial quaternions with qw >= 0)."""
    if dim == 2:
        return np.asarray(transforms, dtype=float)
    quat_wxyz, t = se3.to_quat_wxyz_t(transforms)
    return np.concatenate([t, quat_wxyz], axis=-1)
