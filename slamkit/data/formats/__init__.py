"""File formats: pose graphs (g2o, TORO, iSAM) and trajectories (TUM, KITTI).

``load_pose_graph(path, format='auto')`` reads any supported pose-graph file into a
:class:`slamkit.data.pose_graph.PoseGraph`. Format detection (``format='auto'``) looks at the
record tags first and the extension only to break ties:

* ``VERTEX_SE2``/``EDGE_SE2``/``VERTEX_SE3:QUAT``/``EDGE_SE3:QUAT`` -> g2o;
* ``VERTEX2``/``VERTEX3``/``EQUIV`` -> TORO, except in a ``.g2o`` file, where EDGE2 information
  is read in g2o's order (``toro_g2o_order``: gtsam's ``w100_30.g2o`` is such a file);
* ``ODOMETRY``/``LANDMARK``/``POINT3`` -> iSAM;
* bare ``EDGE2``/``EDGE3`` (no vertices): ``.graph`` -> TORO, otherwise iSAM (square-root
  information; the iSAM distribution's ``.txt`` files).
"""

from __future__ import annotations

import functools
from pathlib import Path

from slamkit.data.formats._records import InformationPolicy, connected_components
from slamkit.data.formats.g2o import read_g2o, write_g2o
from slamkit.data.formats.ground_truth import GROUND_TRUTH_FORMATS, read_ground_truth
from slamkit.data.formats.isam import LandmarkObservations, read_isam, read_isam_with_landmarks
from slamkit.data.formats.toro import read_toro
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import DataError

POSE_GRAPH_FORMATS = ("g2o", "toro", "toro_g2o_order", "isam")

_G2O_TAGS = {"VERTEX_SE2", "EDGE_SE2", "VERTEX_SE3:QUAT", "EDGE_SE3:QUAT"}
_TORO_TAGS = {"VERTEX2", "VERTEX3", "EQUIV"}
_ISAM_TAGS = {"ODOMETRY", "LANDMARK", "POINT3"}


def detect_pose_graph_format(path: str | Path) -> str:
    """'g2o', 'toro', 'toro_g2o_order' or 'isam' from the record tags (see the module docstring)."""
    path = Path(path)
    try:
        with path.open("r", errors="replace") as handle:
            tags = {line.split(None, 1)[0] for line in handle if line.strip()}
    except FileNotFoundError:
        raise DataError("no such file", path) from None
    except IsADirectoryError:
        raise DataError("is a directory, not a file", path) from None
    if tags & _G2O_TAGS:
        return "g2o"
    if tags & _TORO_TAGS:
        return "toro_g2o_order" if path.suffix.lower() == ".g2o" else "toro"
    if tags & _ISAM_TAGS:
        return "isam"
    if tags & {"EDGE2", "EDGE3"}:
        if path.suffix.lower() == ".g2o":
            return "toro_g2o_order"
        return "toro" if path.suffix.lower() == ".graph" else "isam"
    if path.suffix.lower() == ".g2o":
        return "g2o"
    raise DataError("cannot tell the pose-graph format: no g2o, TORO or iSAM record tags", path)


def load_pose_graph(path: str | Path, format: str = "auto", policy: InformationPolicy = "keep",
                    name: str | None = None) -> PoseGraph:
    """Read a pose graph in any supported format ('auto' or one of ``POSE_GRAPH_FORMATS``)."""
    fmt = detect_pose_graph_format(path) if format == "auto" else format
    readers = {"g2o": read_g2o, "toro": read_toro, "isam": read_isam,
               "toro_g2o_order": functools.partial(read_toro, information_order="g2o")}
    if fmt not in readers:
        raise DataError(f"unknown pose-graph format {fmt!r}; use 'auto' or one of {POSE_GRAPH_FORMATS}",
                        path)
    return readers[fmt](path, policy=policy, name=name)


__all__ = [
    "GROUND_TRUTH_FORMATS",
    "LandmarkObservations",
    "POSE_GRAPH_FORMATS",
    "connected_components",
    "detect_pose_graph_format",
    "load_pose_graph",
    "read_g2o",
    "read_ground_truth",
    "read_isam",
    "read_isam_with_landmarks",
    "read_toro",
    "write_g2o",
]
