"""g2o pose-graph files, 2D and 3D (Kuemmerle et al., "g2o: A General Framework for Graph
Optimization", ICRA 2011; the record layouts follow ``g2o/types/slam2d`` and ``slam3d``).

Records read::

    VERTEX_SE2 id x y theta
    EDGE_SE2 i j dx dy dtheta I11 I12 I13 I22 I23 I33            (upper-triangular information)
    VERTEX_SE3:QUAT id x y z qx qy qz qw
    EDGE_SE3:QUAT i j x y z qx qy qz qw I11 I12 ... I66           (21 upper-triangular entries,
                                                                   order x y z rx ry rz)

Conventions (those of :class:`slamkit.data.pose_graph.PoseGraph`): quaternions are stored wxyz
and normalised; information stays in the file's order (translation first). As in
``gtsam.readG2o`` the 3D rotation block is used as the information of the rotation vector
(GTSAM's tangent), not of g2o's quaternion-vector parametrisation.

Other tags (``FIX``, ``VERTEX_XY``, ``LANDMARK2``, ``EDGE_SE2_XY`` ...) are skipped and counted
in ``notes``; a file that mixes 2D and 3D records is rejected. Files without VERTEX lines
(CSAIL.g2o, manhattan.g2o, kitti_*.g2o) get initial poses chained from the edges in file order,
exactly as ``gtsam.readG2o`` 4.3 does in 2D (for 3D gtsam returns no initial values; we chain the
same way), and ``has_initial=False``.

Bad input (each tested in ``tests/data/test_pose_graph_formats.py``): see
:mod:`slamkit.data.formats._records` -- malformed line, NaN/inf, duplicate vertex, edge to an
undeclared vertex -> ``DataError`` naming file and one-based line; empty graph -> ``DataError``;
non-positive-definite information -> ``policy`` ('keep' default, 'repair', 'reject');
disconnected graph -> noted.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slamkit.data.formats._records import (
    InformationPolicy,
    assemble,
    empty_block,
    normalize_quats_wxyz,
    note_ignored,
    numeric,
    read_records,
    reject_numeric_tags,
    symmetric_from_upper,
    upper_from_symmetric,
    wrap_angle_rad,
)
from slamkit.data.pose_graph import PoseGraph
from slamkit.data.formats._atomic import atomic_write_text
from slamkit.errors import DataError

TAGS_2D = ("VERTEX_SE2", "EDGE_SE2")
TAGS_3D = ("VERTEX_SE3:QUAT", "EDGE_SE3:QUAT")


def read_g2o(path: str | Path, policy: InformationPolicy = "keep", name: str | None = None) -> PoseGraph:
    """Read a 2D or 3D g2o pose graph (dimension detected from the record tags)."""
    blocks = read_records(path)
    reject_numeric_tags(path, blocks)
    has2 = any(t in blocks for t in TAGS_2D)
    has3 = any(t in blocks for t in TAGS_3D)
    if has2 and has3:
        line = min(blocks[t].lines[0] for t in TAGS_3D if t in blocks)
        raise DataError("file mixes 2D (SE2) and 3D (SE3:QUAT) records", path, line)
    if not (has2 or has3):
        hint = ""
        if "EDGE2" in blocks or "VERTEX2" in blocks:
            hint = " (VERTEX2/EDGE2 records: this looks like a TORO file, use read_toro)"
        elif "EDGE3" in blocks:
            hint = " (EDGE3 records: this looks like an iSAM or TORO-3D file)"
        raise DataError(f"empty graph: no VERTEX_SE2/EDGE_SE2 or VERTEX_SE3:QUAT/EDGE_SE3:QUAT "
                        f"records{hint}", path)
    if has2:
        vl, vid, vval = numeric(path, "VERTEX_SE2", _get(blocks, "VERTEX_SE2"), 1, 3)
        el, eid, evals = numeric(path, "EDGE_SE2", _get(blocks, "EDGE_SE2"), 2, 9)
        poses = np.column_stack([vval[:, :2], wrap_angle_rad(vval[:, 2])])
        meas = np.column_stack([evals[:, :2], wrap_angle_rad(evals[:, 2])])
        info = symmetric_from_upper(evals[:, 3:], 3)
        dim = 2
    else:
        vl, vid, vval = numeric(path, "VERTEX_SE3:QUAT", _get(blocks, "VERTEX_SE3:QUAT"), 1, 7)
        el, eid, evals = numeric(path, "EDGE_SE3:QUAT", _get(blocks, "EDGE_SE3:QUAT"), 2, 28)
        poses = _xyz_xyzw_to_xyz_wxyz(vval, path, vl, "VERTEX_SE3:QUAT")
        meas = _xyz_xyzw_to_xyz_wxyz(evals[:, :7], path, el, "EDGE_SE3:QUAT")
        info = symmetric_from_upper(evals[:, 7:], 6)
        dim = 3
    handled = set(TAGS_2D if dim == 2 else TAGS_3D)
    return assemble(
        path=path, dim=dim, vertex_ids=vid[:, 0], poses=poses, vertex_lines=vl,
        edge_from=eid[:, 0], edge_to=eid[:, 1], measurements=meas, information=info,
        edge_lines=el, policy=policy, name=name, notes=note_ignored(blocks, handled),
    )


def _get(blocks, tag):
    return blocks.get(tag) or empty_block(tag)


def _xyz_xyzw_to_xyz_wxyz(values: np.ndarray, path, lines, tag) -> np.ndarray:
    q = normalize_quats_wxyz(values[:, [6, 3, 4, 5]], path, lines, tag)
    return np.column_stack([values[:, :3], q])


def format_g2o(graph: PoseGraph) -> str:
    """The g2o text of ``graph`` (vertices then edges; floats with round-trip precision)."""
    out: list[str] = []
    fmt = "{!r}".format
    if graph.dim == 2:
        for i, p in zip(graph.vertex_ids.tolist(), graph.poses.tolist()):
            out.append("VERTEX_SE2 %d %s" % (i, " ".join(map(fmt, p))))
        upper = upper_from_symmetric(graph.information)
        for a, b, m, u in zip(graph.edge_from.tolist(), graph.edge_to.tolist(),
                              graph.measurements.tolist(), upper.tolist()):
            out.append("EDGE_SE2 %d %d %s" % (a, b, " ".join(map(fmt, m + u))))
    else:
        def xyzw(rows: np.ndarray) -> np.ndarray:
            return rows[:, [0, 1, 2, 4, 5, 6, 3]]

        for i, p in zip(graph.vertex_ids.tolist(), xyzw(graph.poses).tolist()):
            out.append("VERTEX_SE3:QUAT %d %s" % (i, " ".join(map(fmt, p))))
        upper = upper_from_symmetric(graph.information)
        for a, b, m, u in zip(graph.edge_from.tolist(), graph.edge_to.tolist(),
                              xyzw(graph.measurements).tolist(), upper.tolist()):
            out.append("EDGE_SE3:QUAT %d %d %s" % (a, b, " ".join(map(fmt, m + u))))
    return "\n".join(out) + "\n"


def write_g2o(path: str | Path, graph: PoseGraph) -> Path:
    """Write ``graph`` as g2o, atomically (temporary file in the same folder, then rename)."""
    return atomic_write_text(path, format_g2o(graph))
