"""iSAM text files (Kaess, Ranganathan, Dellaert, "iSAM: Incremental Smoothing and Mapping",
IEEE T-RO 24(6) 2008; record layouts as parsed by iSAM 1.7's ``isam/Loader.cpp``).

Records read (``s`` = entries of the upper-triangular SQUARE-ROOT information R, row major; the
information is ``R^T R``, unlike g2o/TORO which store the information itself)::

    EDGE2 i j dx dy dtheta sxx sxy sxt syy syt stt          (``ODOMETRY`` is a synonym)
    EDGE3 i j x y z roll pitch yaw [21 entries, order x y z roll pitch yaw]
    LANDMARK pose landmark dx dy sxx sxy syy                 (landmark in the pose's frame)
    POINT3 pose point x y z sxx sxy sxz syy syz szz

Conventions: EDGE3 rotations are ZYX Euler (R = Rz(yaw) Ry(pitch) Rx(roll), iSAM's
``Pose3d(x, y, z, yaw, pitch, roll)``), converted to wxyz quaternions. iSAM weights the Euler-angle
difference; we keep its 6x6 information in (x, y, z, roll, pitch, yaw) order as the information
of (x, y, z, rx, ry, rz) -- translation first like every PoseGraph -- which is exact to first
order about the measurement (small roll/pitch/yaw differences equal rotation-vector components).
An EDGE3 without the 21 entries gets R = identity, as in iSAM.

iSAM files have no vertex lines: initial poses are chained from the edges in file order
(``has_initial=False``), like the g2o reader does for vertex-less files.

``LANDMARK`` and ``POINT3`` lines do not belong in a :class:`PoseGraph`: :func:`read_isam`
counts them in ``notes``; :func:`read_isam_with_landmarks` also returns them as
:class:`LandmarkObservations`. An observation made from a pose no edge mentions is a
``DataError`` naming its line.

``gtsam.load2D``/``load3D`` read these files too but take the numbers as covariances (2D) or as
information (3D) -- both wrong for iSAM; see ``MANIFEST.md`` in the shared datasets.

Bad input follows :mod:`slamkit.data.formats._records` (malformed line, NaN/inf -> ``DataError``
with file and line; empty graph -> ``DataError``; non-PD information -> ``policy``;
disconnected graph -> noted).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slamkit.data.formats._records import (
    Block,
    empty_block,
    InformationPolicy,
    assemble,
    note_ignored,
    numeric,
    read_records,
    reject_numeric_tags,
    wrap_angle_rad,
)
from slamkit.data.formats.toro import edges3
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import DataError

LANDMARK_TAGS = ("LANDMARK", "POINT3")


@dataclass(frozen=True)
class LandmarkObservations:
    """Pose-to-landmark measurements: landmark position in the observing pose's frame."""

    dim: int
    pose_id: np.ndarray  # (K,)
    landmark_id: np.ndarray  # (K,)
    body_p_landmark: np.ndarray  # (K, dim)
    information: np.ndarray  # (K, dim, dim)
    source: str | None = None

    def __post_init__(self) -> None:
        for name in ("pose_id", "landmark_id", "body_p_landmark", "information"):
            value = np.asarray(getattr(self, name))
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def num_landmarks(self) -> int:
        return len(np.unique(self.landmark_id))

    def __len__(self) -> int:
        return len(self.pose_id)


def upper_to_matrix(values: np.ndarray, n: int) -> np.ndarray:
    """(K, n(n+1)/2) row-major upper-triangular entries -> (K, n, n) upper-triangular R."""
    rows, cols = np.triu_indices(n)
    out = np.zeros((len(values), n, n))
    out[:, rows, cols] = values
    return out


def information_from_sqrt_upper(values: np.ndarray, n: int) -> np.ndarray:
    """iSAM square-root information entries -> information ``R^T R`` (K, n, n)."""
    r = upper_to_matrix(values, n)
    return np.einsum("kji,kjl->kil", r, r)


def read_isam(path: str | Path, policy: InformationPolicy = "keep", name: str | None = None) -> PoseGraph:
    """The pose graph of an iSAM file (EDGE2/ODOMETRY or EDGE3); landmark lines are only counted."""
    graph, _ = _read(path, policy, name, want_landmarks=False)
    return graph


def read_isam_with_landmarks(path: str | Path, policy: InformationPolicy = "keep",
                             name: str | None = None) -> tuple[PoseGraph, LandmarkObservations | None]:
    """The pose graph and the LANDMARK (2D) or POINT3 (3D) observations (None if there are none)."""
    return _read(path, policy, name, want_landmarks=True)


def _read(path, policy, name, want_landmarks):
    blocks = read_records(path)
    reject_numeric_tags(path, blocks)
    edge2 = _merge(blocks.get("EDGE2") or empty_block("EDGE2"), blocks.get("ODOMETRY"))
    has2, has3 = len(edge2) > 0, "EDGE3" in blocks
    if has2 and has3:
        raise DataError("file mixes 2D (EDGE2/ODOMETRY) and 3D (EDGE3) records", path)
    if not (has2 or has3):
        raise DataError("empty graph: no EDGE2/ODOMETRY or EDGE3 records", path)
    notes: list[str] = []
    if has2:
        el, eid, evals = numeric(path, "EDGE2", edge2, 2, 9)
        meas = np.column_stack([evals[:, :2], wrap_angle_rad(evals[:, 2])])
        info = information_from_sqrt_upper(evals[:, 3:], 3)
        dim = 2
    else:
        el, eid, meas, upper, n_identity = edges3(path, blocks["EDGE3"], "EDGE3")
        info = information_from_sqrt_upper(upper, 6)
        if n_identity:
            notes.append(f"{n_identity} EDGE3 lines carry no information: identity used")
        dim = 3
    handled = {"EDGE2", "ODOMETRY", "EDGE3"}
    if want_landmarks:
        handled |= set(LANDMARK_TAGS)
    graph = assemble(
        path=path, dim=dim, vertex_ids=np.zeros(0, np.int64), poses=np.zeros((0, 3 if dim == 2 else 7)),
        vertex_lines=np.zeros(0, np.int64), edge_from=eid[:, 0], edge_to=eid[:, 1],
        measurements=meas, information=info, edge_lines=el, policy=policy, name=name,
        notes=notes + note_ignored(blocks, handled),
    )
    if not want_landmarks:
        return graph, None
    return graph, _landmarks(path, blocks, dim, graph)


def _merge(edge2: Block, odometry: Block | None) -> Block:
    """EDGE2 and ODOMETRY lines as one EDGE2 block in file order."""
    if odometry is None or not len(odometry):
        return edge2
    rests = edge2.rests + odometry.rests
    lines = np.concatenate([edge2.lines, odometry.lines])
    order = np.argsort(lines, kind="stable")
    return Block("EDGE2", lines[order], [rests[k] for k in order])


def _landmarks(path, blocks, dim, graph: PoseGraph) -> LandmarkObservations | None:
    tag = "LANDMARK" if dim == 2 else "POINT3"
    other = "POINT3" if dim == 2 else "LANDMARK"
    if other in blocks:
        raise DataError(f"{other} records in a {dim}D file", path, blocks[other].lines[0])
    if tag not in blocks:
        return None
    n_info = 3 if dim == 2 else 6
    lines, ids, values = numeric(path, tag, blocks[tag], 2, dim + n_info)
    pos = np.clip(np.searchsorted(graph.vertex_ids, ids[:, 0]), 0, graph.num_poses - 1)
    missing = graph.vertex_ids[pos] != ids[:, 0]
    if missing.any():
        k = int(np.flatnonzero(missing)[0])
        raise DataError(f"{tag} is observed from pose {int(ids[k, 0])}, which no edge mentions",
                        path, int(lines[k]))
    return LandmarkObservations(
        dim=dim, pose_id=ids[:, 0], landmark_id=ids[:, 1], body_p_landmark=values[:, :dim],
        information=information_from_sqrt_upper(values[:, dim:], dim), source=str(path),
    )
