"""Odometry events from a stream of odometry poses (wheel odometry as logs and bags record it).

slamkit's :class:`~slamkit.data.sequence.Odometry` event is a body-frame (v, omega) held over
``dt_s``, integrated with the exact-arc model (``slamkit.models.diff_drive.motion``). A log
that records integrated odometry poses (CARMEN ``ODOM``, ROS ``nav_msgs/Odometry`` pose) gives
one event per consecutive pair: the heading change a = wrap(theta_1 - theta_0) and the arc
length d whose arc best explains the body-frame displacement (dx, dy). An arc of length d
turning by a ends at d sinc(a/2) (cos(a/2), sin(a/2)); projecting (dx, dy) on that direction
gives the least-squares d = (dx cos(a/2) + dy sin(a/2)) / sinc(a/2). For a displacement that is
an exact arc this inverts ``motion`` exactly (to rounding); a sideways slip, which a diff-drive
cannot produce, is dropped.
"""

from __future__ import annotations

import numpy as np

from slamkit.data.sequence import Odometry
from slamkit.errors import DataError
from slamkit.geometry.angles import wrap_angle
from slamkit.models.diff_drive import sinc


def arc_increments(world_xytheta_body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) odometry poses -> (N-1,) arc lengths d (m) and heading changes a (rad)."""
    p = np.asarray(world_xytheta_body, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise DataError(f"odometry poses must have shape (N, 3), got {p.shape}")
    a = wrap_angle(np.diff(p[:, 2]))
    c, s = np.cos(p[:-1, 2]), np.sin(p[:-1, 2])
    dxw, dyw = np.diff(p[:, 0]), np.diff(p[:, 1])
    dx, dy = c * dxw + s * dyw, -s * dxw + c * dyw  # displacement in the earlier body frame
    half = 0.5 * a
    d = (dx * np.cos(half) + dy * np.sin(half)) / sinc(half)
    return d, a


def odometry_from_poses(stamps_s: np.ndarray, world_xytheta_body: np.ndarray,
                        what: str = "odometry", late_stamps: bool = False) -> list[Odometry]:
    """One :class:`Odometry` event per consecutive pose pair, stamped at the later pose, with
    dt = the stamp difference. Stamps must increase strictly (a repeated stamp would need an
    infinite velocity): a DataError names ``what`` and the index otherwise. ``late_stamps``:
    the poses are in the order they were taken but some stamps are late (a CARMEN log in log
    order); where a stamp does not increase, the motion is held over the median of the
    increasing steps instead, since such a stamp does not say when the pose was taken."""
    t = np.asarray(stamps_s, dtype=float)
    if len(t) != len(world_xytheta_body):
        raise DataError(f"{what}: {len(t)} stamps for {len(world_xytheta_body)} poses")
    dt = np.diff(t)
    if late_stamps and np.any(dt > 0):
        dt = np.where(dt > 0, dt, float(np.median(dt[dt > 0])))
    bad = np.flatnonzero(~(dt > 0))
    if len(bad):
        k = int(bad[0]) + 1
        raise DataError(f"{what}: stamps must increase strictly; pose {k} at {float(t[k])!r} s follows "
                        f"{float(t[k - 1])!r} s")
    d, a = arc_increments(world_xytheta_body)
    return [Odometry(float(t[k + 1]), float(dt[k]), float(d[k] / dt[k]), float(a[k] / dt[k]))
            for k in range(len(dt))]
