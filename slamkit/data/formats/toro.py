"""TORO pose-graph files (Grisetti, Stachniss, Burgard, "Nonlinear Constraint Network
Optimization for Efficient Map Learning", IEEE T-ITS 2009; format as documented on
openslam.org/toro and read by ``gtsam.load2D(..., NoiseFormatTORO)``).

Records read::

    VERTEX2 id x y theta
    EDGE2 i j dx dy dtheta I_xx I_xy I_yy I_tt I_xt I_yt          (TORO information order!)
    VERTEX3 id x y z roll pitch yaw                                (TORO-3D / HOG-Man)
    EDGE3 i j x y z roll pitch yaw [21 upper-triangular information entries, x y z roll pitch yaw]

The 2D information is rearranged into the (x, y, theta) matrix
``[[xx, xy, xt], [xy, yy, yt], [xt, yt, tt]]`` exactly as gtsam's ``readNoiseModel`` does for
``NoiseFormatTORO``. ``EQUIV i j`` lines (vertex equivalences in TORO's w100/w10000 examples) are
ignored, as ``gtsam.load2D`` ignores them; their count is recorded in ``notes``.

TORO-3D: rotations are ZYX Euler (R = Rz(yaw) Ry(pitch) Rx(roll)) converted to wxyz
quaternions; the information (roll, pitch, yaw block taken as the rotation-vector block, a
first-order identification about the measurement) is kept translation first. EDGE3 lines that
carry no information (``sphere_smallnoise.graph`` has only the 6 pose numbers) get the identity,
and the count is noted. ``gtsam.load3D`` cannot read such files (it returns one factor).

Bad input follows :mod:`slamkit.data.formats._records`: malformed line, NaN/inf, duplicate
vertex, edge to an undeclared vertex -> ``DataError`` naming file and line; empty graph ->
``DataError``; non-PD information -> ``policy``; disconnected graph -> noted.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slamkit.data.formats._records import (
    Block,
    empty_block,
    InformationPolicy,
    assemble,
    normalize_quats_wxyz,
    note_ignored,
    numeric,
    read_records,
    reject_numeric_tags,
    rpy_to_quat_wxyz,
    symmetric_from_upper,
    wrap_angle_rad,
)
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import DataError

#: TORO's six numbers (xx xy yy tt xt yt) -> positions in the row-major 3x3 (x, y, theta) matrix
_TORO_TO_MATRIX = np.array([[0, 1, 4], [1, 2, 5], [4, 5, 3]])


def toro_information(values: np.ndarray) -> np.ndarray:
    """(K, 6) TORO-ordered information (xx xy yy tt xt yt) -> (K, 3, 3) in (x, y, theta) order."""
    return values[:, _TORO_TO_MATRIX]


def read_toro(path: str | Path, policy: InformationPolicy = "keep", name: str | None = None,
              information_order: str = "toro") -> PoseGraph:
    """Read a 2D (VERTEX2/EDGE2) or 3D (VERTEX3/EDGE3) TORO graph.

    ``information_order='g2o'`` reads 2D EDGE2 information as g2o's upper triangle
    (I11 I12 I13 I22 I23 I33) instead, for files such as gtsam's ``w100_30.g2o`` that use TORO
    tags with g2o numbers."""
    if information_order not in ("toro", "g2o"):
        raise DataError(f"unknown information order {information_order!r}; use 'toro' or 'g2o'", path)
    blocks = read_records(path)
    reject_numeric_tags(path, blocks)
    has2 = "VERTEX2" in blocks or "EDGE2" in blocks
    has3 = "VERTEX3" in blocks or "EDGE3" in blocks
    if has2 and has3:
        raise DataError("file mixes 2D (VERTEX2/EDGE2) and 3D (VERTEX3/EDGE3) records", path)
    if not (has2 or has3):
        raise DataError("empty graph: no VERTEX2/EDGE2 or VERTEX3/EDGE3 records", path)
    notes: list[str] = []
    if has2:
        vl, vid, vval = numeric(path, "VERTEX2", blocks.get("VERTEX2") or empty_block("VERTEX2"), 1, 3)
        el, eid, evals = numeric(path, "EDGE2", blocks.get("EDGE2") or empty_block("EDGE2"), 2, 9)
        poses = np.column_stack([vval[:, :2], wrap_angle_rad(vval[:, 2])])
        meas = np.column_stack([evals[:, :2], wrap_angle_rad(evals[:, 2])])
        info = (toro_information(evals[:, 3:]) if information_order == "toro"
                else symmetric_from_upper(evals[:, 3:], 3))
        dim, handled = 2, {"VERTEX2", "EDGE2"}
    else:
        vl, vid, vval = numeric(path, "VERTEX3", blocks.get("VERTEX3") or empty_block("VERTEX3"), 1, 6)
        poses = np.column_stack([vval[:, :3], rpy_to_quat_wxyz(vval[:, 3:])])
        el, eid, meas, upper, n_identity = edges3(path, blocks.get("EDGE3") or empty_block("EDGE3"), "EDGE3")
        info = symmetric_from_upper(upper, 6)
        if n_identity:
            notes.append(f"{n_identity} EDGE3 lines carry no information: identity used")
        dim, handled = 3, {"VERTEX3", "EDGE3"}
    return assemble(
        path=path, dim=dim, vertex_ids=vid[:, 0], poses=poses, vertex_lines=vl,
        edge_from=eid[:, 0], edge_to=eid[:, 1], measurements=meas, information=info,
        edge_lines=el, policy=policy, name=name, notes=notes + note_ignored(blocks, handled),
    )


def edges3(path, block: Block, tag: str):
    """EDGE3 rows with 6 pose numbers and optionally 21 information numbers (as in iSAM's
    Loader, which accepts both); returns lines, ids, measurements (xyz + wxyz), the 21 upper
    entries (identity's where a row has none; the caller decides if they are information or its
    square root) and the count of rows without information."""
    counts = block.token_counts()
    bad = np.flatnonzero((counts != 8) & (counts != 29))
    if len(bad):
        raise DataError(f"{tag} needs 8 or 29 fields after the tag, got {int(counts[bad[0]])}",
                        path, int(block.lines[bad[0]]))
    lines = np.asarray(block.lines, dtype=np.int64)
    ids = np.zeros((len(block), 2), dtype=np.int64)
    pose6 = np.zeros((len(block), 6))
    upper = np.tile(symmetric_upper_identity(), (len(block), 1))
    for width in (27, 6):
        mask = counts == width + 2
        if not mask.any():
            continue
        _, sid, sval = numeric(path, tag, block.subset(mask), 2, width)
        ids[mask] = sid
        pose6[mask] = sval[:, :6]
        if width == 27:
            upper[mask] = sval[:, 6:]
    n_short = int((counts == 8).sum())
    meas = np.column_stack([pose6[:, :3], rpy_to_quat_wxyz(pose6[:, 3:])])
    meas[:, 3:] = normalize_quats_wxyz(meas[:, 3:], path, lines, tag)
    return lines, ids, meas, upper, n_short


def symmetric_upper_identity() -> np.ndarray:
    rows, cols = np.triu_indices(6)
    return (rows == cols).astype(float)
