"""Shared machinery of the pose-graph text readers (g2o, TORO, iSAM).

All three formats are "one record per line, first token is a tag". The readers here split the
file once, group lines by tag and convert each group in bulk: with the compiled scanner
(``_textscan.c``, built when slamkit is installed; loaded by :mod:`slamkit._native`) one C pass per tag over the
file's bytes (w10000's 74k records in ~30 ms, 4x faster than the numpy path), otherwise one numpy
``loadtxt`` call per tag. Both convert numbers with correct rounding, so they give the same bits;
the scanner accepts only a subset of numpy's number syntax and hands any line it does not accept
back to the numpy path. Only when a bulk conversion fails do we walk that group line by line to
name the one-based line and token at fault, so errors read the same whichever path ran.

The assembly step (:func:`assemble`) is where the documented bad-input outcomes live, so every
reader behaves the same:

* wrong token count or a token that is not a number -> ``DataError`` naming file and line;
* NaN or infinity anywhere in a record -> ``DataError`` naming file and line;
* an edge translation whose square (``|t|^2``, or ``t^T I_tt t`` under its translation
  information) overflows to infinity -> ``DataError`` naming file and line;
* two vertices with the same id -> ``DataError`` naming the second line;
* an edge to a vertex the file never declares -> ``DataError`` naming the edge's line, unless the
  file declares no vertices at all: then initial poses are chained from the edges in file order
  exactly as ``gtsam.readG2o`` / ``load2D`` do (first endpoint unseen -> identity; second endpoint
  unseen -> first * measurement) and ``has_initial`` is False;
* no edges and no vertices -> ``DataError`` ("empty graph");
* information that is not positive definite (smallest eigenvalue <= 0) -> ``policy`` decides:
  ``'keep'`` (default) passes the matrix on unchanged and records the count in ``notes`` --
  gtsam.readG2o does the same (its ``Gaussian::Information`` factors it with an unchecked
  Cholesky); ``'repair'`` clips eigenvalues to ``1e-9 * max(largest |eigenvalue|, 1)`` (the
  nearest PD matrix in Frobenius norm up to that floor) and records the count; ``'reject'``
  raises ``DataError`` naming the first offending line;
* more than one connected component -> recorded in ``notes`` (the back-end needs a prior per
  component); see :func:`connected_components`.

Vertices are returned sorted by id (GTSAM's ``Values`` order), edges in file order.
"""

from __future__ import annotations

import io
import warnings
import math
from functools import cached_property
from pathlib import Path
from typing import Literal

import numpy as np

from slamkit._native import load_extension
from slamkit._text import is_number_token, parse_number, read_bytes, read_text, split_lines
from slamkit.data.pose_graph import PoseGraph
from slamkit.geometry import so3
from slamkit.errors import DataError

InformationPolicy = Literal["keep", "repair", "reject"]
POLICIES = ("keep", "repair", "reject")
#: eigenvalue floor of ``policy='repair'``, relative to the matrix's largest eigenvalue
REPAIR_RELATIVE_FLOOR = 1e-9


class FileBytes:
    """The raw bytes of a file the native scanner split; the Python split of the same text is
    made only when a slow path (error location, subsets, merged blocks) needs the line texts."""

    def __init__(self, data: bytes) -> None:
        self.data = data

    @cached_property
    def python_blocks(self) -> dict[str, "Block"]:
        # only ASCII without a lone "\r" reaches here (the scanner's condition)
        return split_text(self.data.decode("ascii"))


class Block:
    """All lines of one tag: one-based line numbers and the text after the tag on each line.

    A block from the native scanner holds only its line numbers and the file's bytes
    (``source``); :func:`numeric` converts it in C, and ``rests`` is computed on demand."""

    def __init__(self, tag: str, lines: np.ndarray, rests: list[str] | None = None,
                 source: FileBytes | None = None) -> None:
        if rests is None and source is None:
            raise ValueError("a Block needs its line texts or the file bytes they come from")
        self.tag = tag
        self.lines = lines
        self._rests = rests
        self.source = source

    @property
    def rests(self) -> list[str]:
        if self._rests is None:
            assert self.source is not None
            self._rests = self.source.python_blocks[self.tag].rests
        return self._rests

    @property
    def rows(self) -> list[list[str]]:
        """Tokens after the tag, per line (the slow path; only used to locate errors)."""
        return [rest.split() for rest in self.rests]

    @cached_property
    def payload(self) -> str:
        """The lines without their tags, joined by newlines (a lone "\r" inside a line is a
        blank, as ``str.split`` sees it; numpy's parser would end the line there)."""
        return "\n".join(self.rests).replace("\r", " ")

    def token_counts(self) -> np.ndarray:
        """Number of fields after the tag on each line, computed on bytes without a Python loop."""
        if not len(self):
            return np.zeros(0, dtype=np.int64)
        data = self.payload.encode("utf-8", errors="replace")
        buf = np.frombuffer(data, dtype=np.uint8)
        space = (buf == 32) | (buf == 9) | (buf == 10) | (buf == 13) | (buf == 11) | (buf == 12)
        starts = ~space
        starts[1:] &= space[:-1]
        line_of_byte = np.cumsum(buf == 10)
        return np.bincount(line_of_byte[starts], minlength=len(self))[: len(self)]

    def subset(self, mask: np.ndarray) -> "Block":
        index = np.flatnonzero(mask)
        rests = self.rests
        return Block(self.tag, self.lines[index], [rests[k] for k in index])

    def __len__(self) -> int:
        return len(self.lines)


def empty_block(tag: str) -> Block:
    return Block(tag, np.zeros(0, dtype=np.int64), [])


TEXTSCAN_MODULE = "slamkit.data.formats._textscan"


def textscan():
    """The compiled scanner (``_textscan.c``), or None: then everything runs in Python/numpy
    with the same results (``SLAMKIT_NO_NATIVE=1`` forces that)."""
    return load_extension(TEXTSCAN_MODULE)


def read_records(path: str | Path) -> dict[str, Block]:
    """Split a text file into blocks by first token; blank lines and ``#`` comments are skipped.

    With the native scanner, an ASCII file (only printable characters, tabs and line breaks) is
    split in C and its blocks are converted in C by :func:`numeric`; anything else takes the
    Python path (same blocks, same errors)."""
    path = Path(path)
    scanner = textscan()
    if scanner is not None:
        data = read_bytes(path)
        found = scanner.tags(data) if data.isascii() else None
        if found is not None:
            source = FileBytes(data)
            return {tag: Block(tag, np.frombuffer(lines, dtype=np.int64), source=source)
                    for tag, lines in found.items()}
    return split_text(read_text(path))


def split_text(text: str) -> dict[str, Block]:
    """The Python splitter of :func:`read_records` (per-line ``str.partition``); lines split by
    the shared rule of :mod:`slamkit._text` (``"\n"``, tolerating ``"\r\n"``)."""
    lines = split_lines(text)
    # partition(" ") is the cheap common case (tag at column 0, then a space); lines that start
    # with whitespace or use other separators take the general split
    parts = [line.partition(" ") for line in lines]
    heads = [part[0] for part in parts]
    rests = [part[2] for part in parts]
    for k, head in enumerate(heads):
        if not head or head != head.strip() or len(head.split()) != 1:
            tokens = lines[k].split(None, 1)
            heads[k] = tokens[0] if tokens else ""
            rests[k] = tokens[1] if len(tokens) > 1 else ""
    head_array = np.array(heads)
    blocks: dict[str, Block] = {}
    for tag in dict.fromkeys(heads):
        if not tag or tag.startswith("#"):
            continue
        index = np.flatnonzero(head_array == tag)
        blocks[tag] = Block(tag, index + 1, [rests[k] for k in index])
    return blocks


def numeric(path: str | Path, tag: str, block: Block, n_ids: int,
            n_values: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Convert a block to line numbers (K,), integer ids (K, n_ids) and finite floats (K, n_values).

    Fast paths: the native scanner for a block it split (exactly ``n_ids + n_values`` plain
    decimal numbers per line, correctly rounded like numpy), else one ``np.loadtxt`` (numpy's C
    parser, which also checks that every row has the same number of fields) over the whole
    block; any failure falls back to a line-by-line scan that names the line and field at
    fault."""
    expected = n_ids + n_values
    lines = np.asarray(block.lines, dtype=np.int64)
    if not len(block):
        return lines, np.zeros((0, n_ids), np.int64), np.zeros((0, n_values))
    table = None
    scanner = textscan() if block.source is not None else None
    if scanner is not None:
        scanned = scanner.scan(block.source.data, tag, expected)
        if scanned is not None:
            table = np.frombuffer(scanned[0], dtype=float).reshape(-1, expected)
            if len(table) != len(block):  # pragma: no cover - tags() and scan() split alike
                table = None
    if table is None:
        try:
            with warnings.catch_warnings():
                # a block of tags with no numbers is reported below, naming its line
                warnings.simplefilter("ignore", UserWarning)
                table = np.loadtxt(io.StringIO(block.payload), dtype=float, comments=None, ndmin=2)
        except ValueError:
            table = None
    if table is None or table.shape != (len(block), expected):
        _locate_bad_line(path, tag, block, expected)
    id_part = table[:, :n_ids]
    integral = (id_part == np.round(id_part)) & (np.abs(id_part) < 2.0**53)
    if not integral.all():
        k = int(np.flatnonzero(~integral.all(axis=1))[0])
        col = int(np.flatnonzero(~integral[k])[0])
        raise DataError(f"{tag} field {col + 1} is {block.rows[k][col]!r}, expected an integer id",
                        path, int(lines[k]))
    values = table[:, n_ids:]
    finite = np.isfinite(values).all(axis=1)
    if not finite.all():
        bad = int(np.flatnonzero(~finite)[0])
        raise DataError(f"{tag} contains NaN or infinity", path, int(lines[bad]))
    return lines, id_part.astype(np.int64), np.ascontiguousarray(values)


def _locate_bad_line(path, tag, block: Block, expected: int) -> None:
    for lineno, row in zip(block.lines.tolist(), block.rows):
        if len(row) != expected:
            raise DataError(f"{tag} needs {expected} fields after the tag, got {len(row)}", path, lineno)
        for col in range(expected):
            parse_number(row[col], f"{tag} field {col + 1}", path, lineno)
    raise DataError(f"{tag}: could not convert values", path)  # pragma: no cover


def wrap_angle_rad(angle_rad: np.ndarray) -> np.ndarray:
    """Angles outside (-pi, pi] wrapped the way gtsam's Rot2 does (atan2 of sin and cos), so a
    file's 5.2 rad reads as gtsam's -1.083 rad; angles already in range are kept bit-exact."""
    angle_rad = np.asarray(angle_rad, dtype=float)
    outside = (angle_rad > np.pi) | (angle_rad <= -np.pi)
    if not outside.any():
        return angle_rad
    out = angle_rad.copy()
    out[outside] = np.arctan2(np.sin(angle_rad[outside]), np.cos(angle_rad[outside]))
    return out


def symmetric_from_upper(values: np.ndarray, n: int) -> np.ndarray:
    """(K, n(n+1)/2) row-major upper-triangular entries -> (K, n, n) symmetric matrices."""
    rows, cols = np.triu_indices(n)
    out = np.zeros((len(values), n, n))
    out[:, rows, cols] = values
    out[:, cols, rows] = values
    return out


def upper_from_symmetric(matrices: np.ndarray) -> np.ndarray:
    n = matrices.shape[-1]
    rows, cols = np.triu_indices(n)
    return matrices[:, rows, cols]


def normalize_quats_wxyz(q: np.ndarray, path, lines: np.ndarray, tag: str) -> np.ndarray:
    norms = np.linalg.norm(q, axis=1)
    bad = norms < 1e-12
    if bad.any():
        raise DataError(f"{tag} has a zero quaternion", path, int(lines[np.flatnonzero(bad)[0]]))
    return q / norms[:, None]


def rpy_to_quat_wxyz(rpy: np.ndarray) -> np.ndarray:
    """(K, 3) roll, pitch, yaw (ZYX: R = Rz(yaw) Ry(pitch) Rx(roll), as iSAM's Pose3d and gtsam's
    Rot3::RzRyRx) -> (K, 4) unit wxyz quaternions with w >= 0."""
    rpy = np.asarray(rpy, dtype=float).reshape(-1, 3)
    return so3.to_quat_wxyz(so3.from_euler_zyx(rpy[:, 2], rpy[:, 1], rpy[:, 0]))


def chain_initial(dim: int, edge_from: np.ndarray, edge_to: np.ndarray,
                  measurements: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Initial poses from edges in file order, as gtsam.load2D does for vertex-less files.

    An edge whose first endpoint is unseen puts that vertex at the identity; an unseen second
    endpoint is placed at ``first * measurement``. Returns (ids in first-seen order, poses)."""
    known: dict[int, int] = {}
    poses: list = []
    if dim == 2:
        # Compose on (cos, sin) pairs like gtsam's Rot2 so chained poses agree with
        # gtsam.readG2o to rounding, not just to 1e-12 after thousands of steps.
        rots: list[tuple[float, float]] = []
        for a, b, (dx, dy, dth) in zip(edge_from.tolist(), edge_to.tolist(), measurements.tolist()):
            if a not in known:
                known[a] = len(poses)
                poses.append((0.0, 0.0))
                rots.append((1.0, 0.0))
            if b not in known:
                k = known[a]
                x, y = poses[k]
                c, s = rots[k]
                mc, ms = math.cos(dth), math.sin(dth)
                nc, ns = c * mc - s * ms, s * mc + c * ms
                scale = nc * nc + ns * ns
                if abs(scale - 1.0) > 1e-10:
                    scale = 1.0 / math.sqrt(scale)
                    nc, ns = nc * scale, ns * scale
                known[b] = len(poses)
                poses.append((x + c * dx - s * dy, y + s * dx + c * dy))
                rots.append((nc, ns))
        xy = np.asarray(poses, dtype=float).reshape(-1, 2)
        cs = np.asarray(rots, dtype=float).reshape(-1, 2)
        out = np.column_stack([xy, np.arctan2(cs[:, 1], cs[:, 0])])
    else:
        # scalar Python on tuples: per-edge numpy calls would cost ~20x more here
        for a, b, m in zip(edge_from.tolist(), edge_to.tolist(), measurements.tolist()):
            if a not in known:
                known[a] = len(poses)
                poses.append((0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0))
            if b not in known:
                x, y, z, w1, x1, y1, z1 = poses[known[a]]
                tx, ty, tz, w2, x2, y2, z2 = m
                qw = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
                qx = w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2
                qy = w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2
                qz = w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2
                norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
                # rotate (tx, ty, tz) by q1: v + 2 u x (u x v + w v)
                cx = y1 * tz - z1 * ty + w1 * tx
                cy = z1 * tx - x1 * tz + w1 * ty
                cz = x1 * ty - y1 * tx + w1 * tz
                rx = tx + 2.0 * (y1 * cz - z1 * cy)
                ry = ty + 2.0 * (z1 * cx - x1 * cz)
                rz = tz + 2.0 * (x1 * cy - y1 * cx)
                known[b] = len(poses)
                poses.append((x + rx, y + ry, z + rz, qw / norm, qx / norm, qy / norm, qz / norm))
        out = np.asarray(poses, dtype=float).reshape(-1, 7)
    return np.fromiter(known.keys(), dtype=np.int64, count=len(known)), out


def connected_components(graph: PoseGraph) -> tuple[int, np.ndarray]:
    """Number of connected components and a label per vertex (row order of ``graph.vertex_ids``).

    Edges are treated as undirected; a vertex without edges is its own component."""
    n = graph.num_poses
    if n == 0:
        return 0, np.zeros(0, dtype=np.int64)
    rows = vertex_rows(graph.vertex_ids, graph.edge_from, graph.edge_to)
    if rows is None:
        lookup = graph.index_of()
        rows = (np.fromiter((lookup[int(i)] for i in graph.edge_from), np.int64, graph.num_edges),
                np.fromiter((lookup[int(i)] for i in graph.edge_to), np.int64, graph.num_edges))
    return _components(n, *rows)


def _components(n: int, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components as _cc

    adjacency = coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
    count, labels = _cc(adjacency, directed=False)
    return int(count), labels.astype(np.int64)


def vertex_rows(sorted_ids: np.ndarray, *ends: np.ndarray) -> tuple[np.ndarray, ...] | None:
    """Row of each id in ``ends`` within strictly increasing ``sorted_ids`` (None if the ids are
    not strictly increasing); an id that is absent gets some row whose id differs, so callers
    check ``sorted_ids[row] == id``. Ids that are ``first, first + 1, ...`` (most files) need
    only a subtraction; otherwise a binary search."""
    n = len(sorted_ids)
    if n == 0 or not _sorted(sorted_ids):
        return None
    first = sorted_ids[0]
    if sorted_ids[-1] - first == n - 1:  # strictly increasing and this span: contiguous
        return tuple(np.clip(e - first, 0, n - 1) for e in ends)
    return tuple(np.clip(np.searchsorted(sorted_ids, e), 0, n - 1) for e in ends)


def _sorted(ids: np.ndarray) -> bool:
    return bool(len(ids) < 2 or np.all(ids[1:] > ids[:-1]))


#: a Gershgorin margin above this fraction of a matrix's largest entry proves it positive
#: definite beyond any doubt from eigvalsh's rounding (backward error ~ n * eps * ||A||)
_GERSHGORIN_SAFE_MARGIN = 1e-6


def smallest_eigenvalue_positive(information: np.ndarray) -> np.ndarray:
    """(K,) bool: ``np.linalg.eigvalsh(information)[:, 0] > 0``, computed with eigvalsh only for
    matrices that Gershgorin's theorem does not already clear (strictly diagonally dominant with
    a positive diagonal and a safe margin: all eigenvalues positive); a file with one matrix for
    every edge (w10000's 64k identities) needs one decomposition. Like eigvalsh, only the lower
    triangle is read."""
    k, n = information.shape[0], information.shape[-1]
    if k == 0:
        return np.zeros(0, dtype=bool)
    flat = information.reshape(k, n * n)
    if np.array_equal(flat, np.broadcast_to(flat[0], flat.shape)):  # one matrix for every edge
        return np.full(k, bool(np.linalg.eigvalsh(information[:1])[0, 0] > 0.0))
    # row sums of |off-diagonal| of the symmetric matrix eigvalsh sees: the strict lower
    # triangle's row sums plus its column sums (its mirror image)
    strict_lower = np.abs(information) * np.tri(n, n, -1)
    off = strict_lower.sum(axis=2) + strict_lower.sum(axis=1)
    diag = np.diagonal(information, axis1=1, axis2=2)
    scale = np.maximum(strict_lower.max(axis=(1, 2)), np.abs(diag).max(axis=1))
    margin = (diag - off).min(axis=1)
    cleared = (margin > _GERSHGORIN_SAFE_MARGIN * scale) & np.isfinite(margin)
    positive = cleared.copy()
    rest = np.flatnonzero(~cleared)
    if len(rest):
        positive[rest] = np.linalg.eigvalsh(information[rest])[:, 0] > 0.0
    return positive


def assemble(*, path: str | Path, dim: int, vertex_ids: np.ndarray, poses: np.ndarray,
             vertex_lines: np.ndarray, edge_from: np.ndarray, edge_to: np.ndarray,
             measurements: np.ndarray, information: np.ndarray, edge_lines: np.ndarray,
             policy: InformationPolicy, name: str | None = None,
             notes: list[str] | None = None) -> PoseGraph:
    """Validate parsed arrays and build the :class:`PoseGraph` (see the module docstring)."""
    if policy not in POLICIES:
        raise DataError(f"unknown information policy {policy!r}; use one of {POLICIES}", path)
    notes = list(notes or [])
    if len(vertex_ids) == 0 and len(edge_from) == 0:
        raise DataError("empty graph: no vertices and no edges", path)

    _check_translation_scale(path, dim, measurements, information, edge_lines)
    has_initial = len(vertex_ids) > 0
    if has_initial:
        order = np.argsort(vertex_ids, kind="stable")
        ids_sorted = vertex_ids[order]
        dup = np.flatnonzero(ids_sorted[1:] == ids_sorted[:-1])
        if len(dup):
            second = order[dup + 1]
            first_bad = int(second[np.argmin(vertex_lines[second])])
            raise DataError(f"vertex {int(vertex_ids[first_bad])} is declared twice", path,
                            int(vertex_lines[first_bad]))
        vertex_ids, poses = ids_sorted, poses[order]
        rows = vertex_rows(vertex_ids, edge_from, edge_to)
        assert rows is not None  # sorted and free of duplicates
        for ends, pos in zip((edge_from, edge_to), rows):
            missing = vertex_ids[pos] != ends
            if missing.any():
                k = int(np.flatnonzero(missing)[0])
                raise DataError(f"edge refers to vertex {int(ends[k])}, which the file never declares",
                                path, int(edge_lines[k]))
    else:
        ids, chained = chain_initial(dim, edge_from, edge_to, measurements)
        order = np.argsort(ids, kind="stable")
        vertex_ids, poses = ids[order], chained[order]
        if not np.isfinite(poses).all():
            raise DataError("initial poses chained from the edges overflow to infinity "
                            "(translations too large)", path)
        notes.append("no vertices in file: initial poses chained from edges in file order")
        rows = vertex_rows(vertex_ids, edge_from, edge_to)

    information = np.asarray(information, dtype=float)
    overflow = ~np.isfinite(information).all(axis=(1, 2)) if information.ndim == 3 else np.zeros(0, bool)
    if overflow.any():
        # finite entries whose square-root-information product overflows (iSAM), under any policy
        raise DataError("information matrix overflows to infinity", path,
                        int(edge_lines[np.flatnonzero(overflow)[0]]))
    if len(information):
        non_pd = ~smallest_eigenvalue_positive(information)
        n_bad = int(non_pd.sum())
        if n_bad:
            first_line = int(edge_lines[np.flatnonzero(non_pd)[0]])
            if policy == "reject":
                smallest = np.linalg.eigvalsh(information[np.flatnonzero(non_pd)[0]])[0]
                raise DataError(f"information matrix is not positive definite (smallest eigenvalue "
                                f"{smallest:.3g}); {n_bad} such edges in the file",
                                path, first_line)
            if policy == "repair":
                information = information.copy()
                vals, vecs = np.linalg.eigh(information[non_pd])
                floor = REPAIR_RELATIVE_FLOOR * np.maximum(np.abs(vals).max(axis=1), 1.0)
                vals = np.maximum(vals, floor[:, None])
                information[non_pd] = np.einsum("kij,kj,klj->kil", vecs, vals, vecs)
                notes.append(f"non_pd_information: {n_bad} of {len(information)} edges repaired "
                             f"by eigenvalue clipping (first at line {first_line})")
            else:
                notes.append(f"non_pd_information: {n_bad} of {len(information)} edges kept as "
                             f"given (first at line {first_line})")

    graph = PoseGraph(
        dim=dim, vertex_ids=vertex_ids, poses=poses, edge_from=edge_from, edge_to=edge_to,
        measurements=measurements, information=information,
        name=name or Path(path).stem, source=str(path), has_initial=has_initial, notes=tuple(notes),
    )
    count, _ = _components(graph.num_poses, *rows) if rows is not None else connected_components(graph)
    if count > 1:
        graph = PoseGraph(
            dim=dim, vertex_ids=graph.vertex_ids, poses=graph.poses, edge_from=graph.edge_from,
            edge_to=graph.edge_to, measurements=graph.measurements, information=graph.information,
            name=graph.name, source=graph.source, has_initial=has_initial,
            notes=graph.notes + (f"disconnected: {count} connected components",),
        )
    return graph


def _check_translation_scale(path, dim: int, measurements: np.ndarray, information: np.ndarray,
                             edge_lines: np.ndarray) -> None:
    """Refuse an edge whose translation squares to infinity, alone (``|t|^2``) or weighted by its
    translation information (``t^T I_tt t``): every solver and the certificate form these terms
    (a single ``EDGE2 0 1 1e300 ...`` made the certificate's eigensolver fail). Edges whose
    information itself is not finite are left to the information check."""
    if not len(measurements):
        return
    t = np.asarray(measurements, dtype=float)[:, :dim]
    info = np.asarray(information, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        squared = np.einsum("ki,ki->k", t, t)
        weighted = (np.einsum("ki,kij,kj->k", t, info[:, :dim, :dim], t) if info.ndim == 3
                    else np.zeros(len(t)))
    bad = ~(np.isfinite(squared) & np.isfinite(weighted))
    if info.ndim == 3:
        bad &= np.isfinite(info).all(axis=(1, 2))
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        shown = ", ".join(f"{v:.3g}" for v in t[k])
        raise DataError(f"edge translation ({shown}) is too large: its squared error overflows to infinity",
                        path, int(edge_lines[k]))


def note_ignored(blocks: dict[str, Block], handled: set[str]) -> list[str]:
    """Notes for tags a reader skips, e.g. ``ignored 40 EQUIV lines``."""
    return [f"ignored {len(blocks[tag])} {tag} lines" for tag in sorted(blocks)
            if tag not in handled]


def reject_numeric_tags(path, blocks: dict[str, Block]) -> None:
    """A first token that is a number means this is not a tagged graph file (or a line lost its tag)."""
    for tag, block in blocks.items():
        if not is_number_token(tag):
            continue
        raise DataError(f"line starts with the number {tag!r}, expected a record tag such as "
                        "VERTEX_SE2 or EDGE_SE2", path, block.lines[0])
