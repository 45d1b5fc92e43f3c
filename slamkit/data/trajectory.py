"""Timestamped trajectories: the common currency of metrics, file formats and estimators.

Poses are stored as ``world_T_body``: translation ``world_t_body`` (N, 3) in metres and
orientation ``world_q_body_wxyz`` (N, 4). Planar trajectories keep z = 0 and a yaw-only
quaternion, so one type serves SE(2) and SE(3) evaluation; ``planar`` records which it is.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from slamkit.errors import DataError


def _yaw_to_quat_wxyz(yaw_rad: np.ndarray) -> np.ndarray:
    half = 0.5 * np.asarray(yaw_rad, dtype=float)
    q = np.zeros(half.shape + (4,))
    q[..., 0] = np.cos(half)
    q[..., 3] = np.sin(half)
    return q


def _quat_wxyz_to_yaw(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


@dataclass(frozen=True)
class Trajectory:
    """An immutable, time-ordered sequence of poses ``world_T_body``."""

    stamps_s: np.ndarray
    world_t_body: np.ndarray
    world_q_body_wxyz: np.ndarray
    planar: bool = False
    frame: str = field(default="world")

    def __post_init__(self) -> None:
        stamps = np.asarray(self.stamps_s, dtype=float).reshape(-1)
        t = np.asarray(self.world_t_body, dtype=float).reshape(-1, 3)
        q = np.asarray(self.world_q_body_wxyz, dtype=float).reshape(-1, 4)
        if not (len(stamps) == len(t) == len(q)):
            raise DataError(
                f"trajectory arrays disagree in length: {len(stamps)} stamps, {len(t)} positions, "
                f"{len(q)} quaternions"
            )
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q)) and np.all(np.isfinite(stamps))):
            raise DataError("trajectory contains NaN or infinite values")
        norms = np.linalg.norm(q, axis=1)
        if np.any(norms < 1e-12):
            raise DataError("trajectory contains a zero quaternion")
        q = q / norms[:, None]
        for name, value in (("stamps_s", stamps), ("world_t_body", t), ("world_q_body_wxyz", q)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    def __len__(self) -> int:
        return len(self.stamps_s)

    @classmethod
    def from_se2(cls, stamps_s: np.ndarray, world_xytheta_body: np.ndarray, **kwargs) -> "Trajectory":
        """Build from planar poses (N, 3) = (x, y, theta)."""
        p = np.asarray(world_xytheta_body, dtype=float).reshape(-1, 3)
        t = np.column_stack([p[:, 0], p[:, 1], np.zeros(len(p))])
        return cls(stamps_s, t, _yaw_to_quat_wxyz(p[:, 2]), planar=True, **kwargs)

    @classmethod
    def from_matrices(cls, stamps_s: np.ndarray, world_T_body: np.ndarray, **kwargs) -> "Trajectory":
        """Build from homogeneous matrices (N, 4, 4)."""
        from slamkit.geometry import so3

        T = np.asarray(world_T_body, dtype=float).reshape(-1, 4, 4)
        return cls(stamps_s, T[:, :3, 3], so3.to_quat_wxyz(T[:, :3, :3]), **kwargs)

    def xytheta(self) -> np.ndarray:
        """Planar poses (N, 3): x, y and yaw (the yaw of the ZYX Euler decomposition)."""
        return np.column_stack([self.world_t_body[:, :2], _quat_wxyz_to_yaw(self.world_q_body_wxyz)])

    def matrices(self) -> np.ndarray:
        """Homogeneous matrices (N, 4, 4) of ``world_T_body``."""
        from slamkit.geometry import so3

        T = np.tile(np.eye(4), (len(self), 1, 1))
        T[:, :3, :3] = so3.from_quat_wxyz(self.world_q_body_wxyz)
        T[:, :3, 3] = self.world_t_body
        return T

    def path_length_m(self) -> float:
        return float(np.sum(np.linalg.norm(np.diff(self.world_t_body, axis=0), axis=1)))

    def subset(self, index: np.ndarray) -> "Trajectory":
        return Trajectory(
            self.stamps_s[index], self.world_t_body[index], self.world_q_body_wxyz[index],
            planar=self.planar, frame=self.frame,
        )
