"""TUM RGB-D trajectory files (Sturm et al., "A Benchmark for the Evaluation of RGB-D SLAM
Systems", IROS 2012; format at https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats).

One pose per line::

    timestamp tx ty tz qx qy qz qw

``world_T_body`` with the quaternion scalar *last* in the file (slamkit stores wxyz). Lines that
are blank or start with ``#`` are skipped; commas are accepted as separators as well as spaces
(some tools write CSV-like TUM files). Bad input -> ``DataError`` naming file and one-based line:
wrong field count, a token that is not a number, NaN/inf, a zero quaternion, no poses at all.
Stamps that go backwards are rejected too (every metric assumes time order).

Writing is atomic (temporary file in the target folder, then ``os.replace``) and uses the
shortest decimal that round-trips each float, so ``read_tum(write_tum(t))`` is exact.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slamkit._text import float_table, read_lines
from slamkit.data.trajectory import Trajectory
from slamkit.data.formats._atomic import atomic_write_text
from slamkit.errors import DataError

TUM_FIELDS = 8


def read_numeric_rows(path: str | Path, n_fields: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Rows of ``n_fields`` finite floats from a whitespace/comma separated text file.

    Returns (values (K, n_fields), one-based line numbers (K,)). Shared by the TUM and KITTI
    readers."""
    path = Path(path)
    rows: list[list[str]] = []
    lines: list[int] = []
    for lineno, line in enumerate(read_lines(path), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        tokens = stripped.replace(",", " ").split()
        if len(tokens) != n_fields:
            raise DataError(f"{what} line needs {n_fields} numbers, got {len(tokens)}", path, lineno)
        rows.append(tokens)
        lines.append(lineno)
    if not rows:
        raise DataError(f"no {what} poses in file", path)
    values = float_table(rows, lines, path)
    finite = np.isfinite(values).all(axis=1)
    if not finite.all():
        raise DataError("NaN or infinity in pose", path, lines[int(np.flatnonzero(~finite)[0])])
    return values, np.asarray(lines, dtype=np.int64)


def check_stamps(stamps: np.ndarray, lines: np.ndarray, path: str | Path) -> None:
    back = np.flatnonzero(np.diff(stamps) < 0)
    if len(back):
        k = int(back[0]) + 1
        raise DataError(f"timestamp {float(stamps[k])!r} is earlier than the previous one {float(stamps[k - 1])!r}",
                        path, int(lines[k]))


def format_rows(values: np.ndarray) -> str:
    """Shortest round-trip decimal (``repr``) for every float, space separated, one row a line."""
    return "".join(" ".join(map(repr, row)) + "\n" for row in np.asarray(values, dtype=float).tolist())


def read_tum(path: str | Path, planar: bool = False) -> Trajectory:
    """Read a TUM trajectory. ``planar=True`` marks the result as planar (no check is made)."""
    values, lines = read_numeric_rows(path, TUM_FIELDS, "TUM")
    check_stamps(values[:, 0], lines, path)
    q_xyzw = values[:, 4:8]
    zero = np.linalg.norm(q_xyzw, axis=1) < 1e-12
    if zero.any():
        raise DataError("zero quaternion", path, int(lines[int(np.flatnonzero(zero)[0])]))
    q_wxyz = q_xyzw[:, [3, 0, 1, 2]]
    return Trajectory(values[:, 0], values[:, 1:4], q_wxyz, planar=planar)


def format_tum(trajectory: Trajectory, header: str | None = None) -> str:
    q = trajectory.world_q_body_wxyz
    values = np.column_stack([trajectory.stamps_s, trajectory.world_t_body, q[:, [1, 2, 3, 0]]])
    head = "" if header is None else "".join(f"# {h}\n" for h in header.splitlines())
    return head + format_rows(values)


def write_tum(path: str | Path, trajectory: Trajectory, header: str | None = None) -> Path:
    """Write ``trajectory`` as TUM, atomically; ``header`` lines are written as ``#`` comments."""
    return atomic_write_text(path, format_tum(trajectory, header))
