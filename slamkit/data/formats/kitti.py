"""KITTI odometry pose files (Geiger et al., "Are we ready for Autonomous Driving? The KITTI
Vision Benchmark Suite", CVPR 2012; devkit ``readme.txt``).

One pose per line: the 12 entries of the 3x4 matrix ``world_T_body`` = [R | t], row major.
The file carries no timestamps: stamps are the zero-based line index (0, 1, 2, ...) unless a
KITTI ``times.txt`` (one stamp per line) is given.

Rotation blocks in KITTI files are printed with ~9 significant digits, so they are orthonormal
only to ~1e-9; Shepperd's method (``slamkit.geometry.so3.to_quat_wxyz``) turns them into the
nearest-behaving unit quaternion. Bad input -> ``DataError`` naming file and one-based line
(wrong field count, non-number, NaN/inf, a rotation block that is far from a rotation).
Writing is atomic and exact (shortest round-trip decimals).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slamkit._text import read_text
from slamkit.data.formats._atomic import atomic_write_text
from slamkit.data.formats.tum import check_stamps, format_rows, read_numeric_rows
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.geometry import so3

KITTI_FIELDS = 12
#: largest |R R^T - I| accepted for a rotation block (KITTI prints ~9 significant digits)
ROTATION_TOLERANCE = 1e-4


def read_kitti(path: str | Path, times_path: str | Path | None = None, planar: bool = False) -> Trajectory:
    """Read a KITTI pose file; stamps from ``times_path`` or the zero-based line index."""
    values, lines = read_numeric_rows(path, KITTI_FIELDS, "KITTI")
    M = values.reshape(-1, 3, 4)
    R = M[:, :, :3]
    err = np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3)).max(axis=(1, 2))
    det = np.linalg.det(R)
    bad = (err > ROTATION_TOLERANCE) | (det <= 0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"rotation block is not a rotation (|R R^T - I| = {err[k]:.3g}, "
                        f"det = {det[k]:.3g})", path, int(lines[k]))
    if times_path is None:
        stamps = np.arange(len(M), dtype=float)
    else:
        times, time_lines = read_numeric_rows(times_path, 1, "KITTI times")
        stamps = times[:, 0]
        if len(stamps) != len(M):
            raise DataError(f"{len(stamps)} stamps for {len(M)} poses in {path}", times_path)
        check_stamps(stamps, time_lines, times_path)
    return Trajectory(stamps, M[:, :, 3], so3.to_quat_wxyz(R), planar=planar)


def format_kitti(trajectory: Trajectory) -> str:
    return format_rows(trajectory.matrices()[:, :3, :].reshape(-1, KITTI_FIELDS))


def write_kitti(path: str | Path, trajectory: Trajectory) -> Path:
    """Write ``trajectory`` as KITTI poses (stamps are dropped), atomically."""
    return atomic_write_text(path, format_kitti(trajectory))


def read_kitti_calib(path: str | Path) -> dict[str, np.ndarray]:
    """KITTI odometry ``calib.txt``: ``NAME: 12 numbers`` per line (``P0:`` ...; the name may be
    missing, then ``P0``, ``P1`` ... by line), each a 3x4 row-major projection matrix."""
    path = Path(path)
    text = read_text(path)  # missing, a folder or not UTF-8: a DataError naming file (and line)
    out: dict[str, np.ndarray] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        name, _, rest = line.partition(":") if ":" in line else (f"P{len(out)}", "", line)
        try:
            values = np.array([float(v) for v in rest.split()])
        except ValueError:
            raise DataError("a calibration line holds a non-number", path, number) from None
        if values.size != KITTI_FIELDS or not np.isfinite(values).all():
            raise DataError(f"a projection matrix needs {KITTI_FIELDS} finite numbers, got {values.size}",
                            path, number)
        out[name.strip()] = values.reshape(3, 4)
    if not out:
        raise DataError("no projection matrix in the calibration file", path)
    return out
