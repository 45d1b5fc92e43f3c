"""The slamkit sequence file (``.slamseq``): a ``Sequence`` on disk, columnar and streamable.

Layout, version 1. The file is a ZIP archive (members stored uncompressed by default, DEFLATE
on request) with fixed member timestamps, so the same sequence always gives the same bytes:

    header.json                    format tag, version, name, counts, metadata, ground-truth frame
    <kind>/<column>.npy            one NumPy ``.npy`` array per column (never pickled)
    ground_truth/stamps_s.npy      (N,)   when the sequence has ground truth
    ground_truth/world_t_body.npy  (N, 3)
    ground_truth/world_q_body_wxyz.npy (N, 4)
    landmarks/ids.npy, landmarks/world_p.npy   (L,), (L, 2 or 3)   when landmarks are known
    initial_pose_xytheta.npy       (3,)   when given

Event kinds and their columns (every kind has ``stamp_s`` (n,) and ``order`` (n,), the event's
position in the sequence, so ties between kinds keep their order exactly):

    odometry        dt_s, v_mps, omega_radps
    range_bearing   offsets (n+1,), landmark_ids, range_m, bearing_rad (flat, event i owns
                    offsets[i]:offsets[i+1])
    gps             world_p_body (n, d), sigma_m
    imu             gyro_radps (n, 3), accel_mps2 (n, 3)
    wheel_encoders  ticks_left, ticks_right (int64)
    scan            max_range_m, offsets (n+1,), angles_rad, ranges_m (flat)

``header.json``: ``{"format": "slamkit-sequence", "version": 1, "name": ..., "num_events": N,
"counts": {kind: n}, "metadata": {...}, "ground_truth": {"planar": bool, "frame": str} | null}``.
Metadata must be JSON (numpy arrays and scalars are converted on save).

Streaming: :func:`open_sequence` reads the header only; a column is read when first asked for,
and iteration builds one event object at a time (a million events never exist as a million
objects unless the caller keeps them). :func:`load_sequence` builds the whole in-memory
``Sequence``. Any ZIP tool can inspect a file; ``numpy.load`` opens it like an ``.npz``.

Bad input raises ``DataError`` naming the file and, where it applies, the member (record) at fault:
a damaged ZIP, a member over :data:`MAX_MEMBER_BYTES` uncompressed (checked on the ZIP directory
before inflating, so a zip bomb is refused unread), a ``.npy`` header that does not parse, a pickled
(object) array, a column of the wrong dtype or shape, columns of unequal length, a header that is
not UTF-8 JSON of the documented shape, and NaN or infinity anywhere except a scan's
``ranges_m`` (where it means "no return").
"""

from __future__ import annotations

import io
import json
import struct
import zipfile
import zlib
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np

from slamkit.data.sequence import (Event, Gps, Imu, Odometry, RangeBearing, Scan, Sequence,
                                   WheelEncoders)
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.paths import atomic_file, check_output_file

FORMAT = "slamkit-sequence"
VERSION = 1
SUFFIX = ".slamseq"
_EPOCH = (1980, 1, 1, 0, 0, 0)
#: largest uncompressed size of one member (1 GiB: 134 M float64 values in one column)
MAX_MEMBER_BYTES = 1 << 30
#: what reading a damaged archive or .npy member can raise, besides our own checks
_CORRUPT = (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, OSError, zlib.error, ValueError,
            NotImplementedError, RuntimeError, struct.error, TypeError, SyntaxError, OverflowError,
            KeyError, IndexError)
#: column -> (dtype kind, ndim); every other column is float64-like and 1-D
_INTEGER_COLUMNS = {"order", "offsets", "landmark_ids", "ticks_left", "ticks_right"}
_MATRIX_COLUMNS = {"world_p_body": (2, 3), "gyro_radps": 3, "accel_mps2": 3}  # fixed member timestamps: byte-identical files for equal input

KINDS: dict[str, type] = {
    "odometry": Odometry,
    "range_bearing": RangeBearing,
    "gps": Gps,
    "imu": Imu,
    "wheel_encoders": WheelEncoders,
    "scan": Scan,
}
_KIND_OF = {cls: kind for kind, cls in KINDS.items()}
_COLUMNS: dict[str, tuple[str, ...]] = {
    "odometry": ("stamp_s", "order", "dt_s", "v_mps", "omega_radps"),
    "range_bearing": ("stamp_s", "order", "offsets", "landmark_ids", "range_m", "bearing_rad"),
    "gps": ("stamp_s", "order", "world_p_body", "sigma_m"),
    "imu": ("stamp_s", "order", "gyro_radps", "accel_mps2"),
    "wheel_encoders": ("stamp_s", "order", "ticks_left", "ticks_right"),
    "scan": ("stamp_s", "order", "max_range_m", "offsets", "angles_rad", "ranges_m"),
}


# ---------------------------------------------------------------------------------------------
# Writing


def _jsonable(value: Any, where: str) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist(), where)
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise DataError(f"metadata field {where!r} of type {type(value).__name__} is not JSON-serialisable")


def _columns_of(events) -> tuple[dict[str, dict[str, np.ndarray]], int]:
    rows: dict[str, list[tuple[int, Event]]] = {k: [] for k in KINDS}
    n = 0
    for i, e in enumerate(events):
        kind = _KIND_OF.get(type(e))
        if kind is None:
            raise DataError(f"event {i} has unsupported type {type(e).__name__}")
        rows[kind].append((i, e))
        n += 1
    cols: dict[str, dict[str, np.ndarray]] = {}
    for kind, items in rows.items():
        if not items:
            continue
        order = np.array([i for i, _ in items], dtype=np.int64)
        ev = [e for _, e in items]
        c: dict[str, np.ndarray] = {"stamp_s": np.array([e.stamp_s for e in ev], dtype=float),
                                    "order": order}
        if kind == "odometry":
            c["dt_s"] = np.array([e.dt_s for e in ev], dtype=float)
            c["v_mps"] = np.array([e.v_mps for e in ev], dtype=float)
            c["omega_radps"] = np.array([e.omega_radps for e in ev], dtype=float)
        elif kind == "range_bearing":
            lengths = [len(np.atleast_1d(e.range_m)) for e in ev]
            c["offsets"] = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
            c["landmark_ids"] = np.concatenate([np.atleast_1d(np.asarray(e.landmark_ids, np.int64))
                                                for e in ev]).astype(np.int64)
            c["range_m"] = np.concatenate([np.atleast_1d(np.asarray(e.range_m, float)) for e in ev])
            c["bearing_rad"] = np.concatenate([np.atleast_1d(np.asarray(e.bearing_rad, float))
                                               for e in ev])
        elif kind == "gps":
            c["world_p_body"] = np.array([np.asarray(e.world_p_body, float).reshape(-1) for e in ev])
            c["sigma_m"] = np.array([e.sigma_m for e in ev], dtype=float)
        elif kind == "imu":
            c["gyro_radps"] = np.array([np.asarray(e.gyro_radps, float).reshape(3) for e in ev])
            c["accel_mps2"] = np.array([np.asarray(e.accel_mps2, float).reshape(3) for e in ev])
        elif kind == "wheel_encoders":
            c["ticks_left"] = np.array([e.ticks_left for e in ev], dtype=np.int64)
            c["ticks_right"] = np.array([e.ticks_right for e in ev], dtype=np.int64)
        elif kind == "scan":
            lengths = [len(np.atleast_1d(e.ranges_m)) for e in ev]
            c["max_range_m"] = np.array([e.max_range_m for e in ev], dtype=float)
            c["offsets"] = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
            c["angles_rad"] = np.concatenate([np.atleast_1d(np.asarray(e.angles_rad, float)) for e in ev])
            c["ranges_m"] = np.concatenate([np.atleast_1d(np.asarray(e.ranges_m, float)) for e in ev])
        cols[kind] = c
    return cols, n


def _write_member(zf: zipfile.ZipFile, name: str, data: bytes, compress: int) -> None:
    info = zipfile.ZipInfo(name, date_time=_EPOCH)
    info.compress_type = compress
    info.external_attr = 0o644 << 16
    zf.writestr(info, data)


def _npy_bytes(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.ascontiguousarray(a), allow_pickle=False)
    return buf.getvalue()


def is_sequence_file(path: Path) -> bool:
    """True for a zip whose ``header.json`` names this format (a file slamkit may overwrite)."""
    try:
        with zipfile.ZipFile(path) as zf:
            return json.loads(zf.read("header.json")).get("format") == FORMAT
    except (zipfile.BadZipFile, KeyError, ValueError, OSError, AttributeError, RuntimeError):
        return False


def save_sequence(path: str | Path, sequence, compress: bool = False) -> Path:
    """Write ``sequence`` (a ``Sequence`` or a :class:`SequenceReader`) to ``path`` atomically
    (a ``.partial`` file renamed when complete). Returns the path."""
    path = Path(path)
    cols, n = _columns_of(iter(sequence))
    header: dict[str, Any] = {
        "format": FORMAT,
        "version": VERSION,
        "name": str(sequence.name),
        "num_events": n,
        "counts": {k: int(len(c["order"])) for k, c in cols.items()},
        "metadata": _jsonable(dict(sequence.metadata or {}), "metadata"),
        "ground_truth": None,
    }
    members: list[tuple[str, bytes]] = []
    for kind, c in cols.items():
        for col in _COLUMNS[kind]:
            members.append((f"{kind}/{col}.npy", _npy_bytes(c[col])))
    gt = sequence.ground_truth
    if gt is not None:
        header["ground_truth"] = {"planar": bool(gt.planar), "frame": str(gt.frame)}
        members += [("ground_truth/stamps_s.npy", _npy_bytes(gt.stamps_s)),
                    ("ground_truth/world_t_body.npy", _npy_bytes(gt.world_t_body)),
                    ("ground_truth/world_q_body_wxyz.npy", _npy_bytes(gt.world_q_body_wxyz))]
    lms = sequence.world_p_landmarks
    if lms is not None:
        ids = np.array(sorted(int(k) for k in lms), dtype=np.int64)
        dim = len(np.asarray(lms[ids[0]]).reshape(-1)) if len(ids) else 2
        pts = np.array([np.asarray(lms[int(i)], float).reshape(dim) for i in ids]).reshape(-1, dim)
        members += [("landmarks/ids.npy", _npy_bytes(ids)), ("landmarks/world_p.npy", _npy_bytes(pts))]
    if sequence.initial_world_xytheta_body is not None:
        members.append(("initial_pose_xytheta.npy",
                        _npy_bytes(np.asarray(sequence.initial_world_xytheta_body, float).reshape(3))))
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    path = check_output_file(path, is_sequence_file, "sequence file")
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path) as tmp, zipfile.ZipFile(tmp, "w", allowZip64=True) as zf:
        _write_member(zf, "header.json", json.dumps(header, sort_keys=True, indent=1).encode(), method)
        for name, data in members:
            _write_member(zf, name, data, method)
    return path


# ---------------------------------------------------------------------------------------------
# Reading


class SequenceReader:
    """A sequence file opened lazily. Duck-types ``Sequence`` (``name``, ``metadata``,
    ``ground_truth``, ``world_p_landmarks``, ``initial_world_xytheta_body``, ``len``, iteration,
    ``of_type``) and adds :meth:`columns` for vectorised consumers."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        try:
            self._zip = zipfile.ZipFile(self.path, "r")
        except FileNotFoundError:
            raise DataError("no such sequence file", self.path) from None
        except _CORRUPT as exc:
            raise DataError(f"not a slamkit sequence file (not a readable ZIP archive: {exc})",
                            self.path) from None
        self._names = set(self._zip.namelist())
        raw = self._read_bytes("header.json")
        try:
            header = json.loads(raw, parse_constant=_reject_constant)
        except (ValueError, UnicodeDecodeError, RecursionError) as exc:
            raise DataError(f"record header.json is not valid JSON: {exc}", self.path) from None
        if not isinstance(header, dict) or header.get("format") != FORMAT:
            raise DataError(f"record header.json: format is not {FORMAT!r}", self.path)
        if header.get("version") != VERSION:
            raise DataError(f"record header.json: unsupported version {header.get('version')!r} "
                            f"(this slamkit reads version {VERSION})", self.path)
        for key in ("name", "num_events", "counts", "metadata"):
            if key not in header:
                raise DataError(f"record header.json: missing field {key!r}", self.path)
        counts = header["counts"]
        if not (isinstance(header["name"], str) and _count(header["num_events"]) and isinstance(counts, dict)
                and all(_count(v) for v in counts.values()) and isinstance(header["metadata"], dict)
                and (header.get("ground_truth") is None or isinstance(header["ground_truth"], dict))):
            raise DataError("record header.json: name must be a string, num_events and counts "
                            "non-negative integers, metadata a mapping, ground_truth a mapping or null",
                            self.path)
        if sum(counts.values()) != header["num_events"]:
            raise DataError(f"record header.json: counts add up to {sum(counts.values())}, "
                            f"num_events is {header['num_events']}", self.path)
        unknown = set(header["counts"]) - set(KINDS)
        if unknown:
            raise DataError(f"record header.json: unknown event kinds {sorted(unknown)}", self.path)
        self.header = header
        self.name: str = header["name"]
        self.metadata: Mapping[str, Any] = header["metadata"]
        self._cache: dict[str, dict[str, np.ndarray]] = {}
        self._ground_truth: Trajectory | None = None
        self._landmarks: dict[int, np.ndarray] | None = None

    # -- low level
    def _read_bytes(self, member: str) -> bytes:
        if member not in self._names:
            raise DataError(f"record {member} is missing", self.path)
        size = self._zip.getinfo(member).file_size
        if size > MAX_MEMBER_BYTES:
            raise DataError(f"record {member} declares {size} bytes uncompressed, more than the limit "
                            f"of {MAX_MEMBER_BYTES}", self.path)
        try:
            return self._zip.read(member)
        except _CORRUPT as exc:
            raise DataError(f"record {member} is corrupt or truncated: {exc}", self.path) from None

    def _array(self, member: str) -> np.ndarray:
        data = self._read_bytes(member)
        try:
            a = np.lib.format.read_array(io.BytesIO(data), allow_pickle=False)
        except _CORRUPT as exc:
            raise DataError(f"record {member} is not a valid .npy array: {exc}", self.path) from None
        column = member.rsplit("/", 1)[-1].removesuffix(".npy")
        if column in _INTEGER_COLUMNS or member == "landmarks/ids.npy":
            if a.dtype.kind not in "iu":
                raise DataError(f"record {member}: dtype {a.dtype} is not an integer type", self.path)
        elif a.dtype.kind not in "fiu":
            raise DataError(f"record {member}: dtype {a.dtype} is not a number type", self.path)
        else:
            a = a.astype(float, copy=False)
            finite = np.isfinite(a)
            if column != "ranges_m" and not finite.all():  # a scan's inf/NaN range is "no return"
                raise DataError(f"record {member}: NaN or infinity at index {int(np.flatnonzero(~finite.reshape(-1))[0])}",
                                self.path)
        a.setflags(write=False)
        return a

    def _shaped(self, member: str, shape: tuple) -> np.ndarray:
        """The array of ``member`` with ``shape`` (None: any length; a tuple: one of those widths)."""
        a = self._array(member)
        ok = a.ndim == len(shape) and all(
            want is None or (a.shape[k] in want if isinstance(want, tuple) else a.shape[k] == want)
            for k, want in enumerate(shape))
        if not ok:
            raise DataError(f"record {member}: shape {a.shape}, expected {_shape_text(shape)}", self.path)
        return a

    # -- columns
    def columns(self, kind: str) -> dict[str, np.ndarray]:
        """All columns of one event kind (empty dict when the file has none), validated."""
        if kind not in KINDS:
            raise DataError(f"unknown event kind {kind!r}; kinds are {sorted(KINDS)}", self.path)
        if kind in self._cache:
            return self._cache[kind]
        n = int(self.header["counts"].get(kind, 0))
        if n == 0:
            self._cache[kind] = {}
            return {}
        c = {col: self._shaped(f"{kind}/{col}.npy", (None, _MATRIX_COLUMNS[col]) if col in _MATRIX_COLUMNS else (None,))
             for col in _COLUMNS[kind]}
        for col, a in c.items():
            member = f"{kind}/{col}.npy"
            if col == "offsets":
                if a.shape != (n + 1,) or a[0] != 0 or np.any(np.diff(a) < 0):
                    raise DataError(f"record {member}: offsets must be (n+1,) non-decreasing from 0",
                                    self.path)
            elif col in ("landmark_ids", "range_m", "bearing_rad", "angles_rad", "ranges_m"):
                if a.ndim != 1 or len(a) != int(c["offsets"][-1]):
                    raise DataError(f"record {member}: {len(a)} values but offsets end at "
                                    f"{int(c['offsets'][-1])}", self.path)
            elif len(a) != n:
                raise DataError(f"record {member}: {len(a)} rows, header says {n}", self.path)
        if not np.all(np.isfinite(c["stamp_s"])):
            raise DataError(f"record {kind}/stamp_s.npy: NaN or infinite stamp", self.path)
        self._cache[kind] = c
        return c

    # -- Sequence-like interface
    def __len__(self) -> int:
        return int(self.header["num_events"])

    @property
    def ground_truth(self) -> Trajectory | None:
        if self._ground_truth is None and self.header.get("ground_truth"):
            gt = self.header["ground_truth"]
            stamps = self._shaped("ground_truth/stamps_s.npy", (None,))
            t = self._shaped("ground_truth/world_t_body.npy", (len(stamps), 3))
            q = self._shaped("ground_truth/world_q_body_wxyz.npy", (len(stamps), 4))
            try:
                self._ground_truth = Trajectory(stamps, t, q, planar=bool(gt.get("planar")),
                                                frame=str(gt.get("frame", "world")))
            except DataError as exc:
                if exc.path is not None:
                    raise
                raise DataError(f"record ground_truth: {exc}", self.path) from None
        return self._ground_truth

    @property
    def world_p_landmarks(self) -> dict[int, np.ndarray] | None:
        if self._landmarks is None and "landmarks/ids.npy" in self._names:
            ids = self._shaped("landmarks/ids.npy", (None,))
            pts = self._shaped("landmarks/world_p.npy", (None, (2, 3)))
            if len(ids) != len(pts):
                raise DataError(f"record landmarks: {len(ids)} ids but {len(pts)} positions", self.path)
            self._landmarks = {int(i): pts[j] for j, i in enumerate(ids)}
        return self._landmarks

    @property
    def initial_world_xytheta_body(self) -> np.ndarray | None:
        if "initial_pose_xytheta.npy" not in self._names:
            return None
        return self._shaped("initial_pose_xytheta.npy", (3,))

    def _positions(self) -> tuple[np.ndarray, np.ndarray]:
        """(kind code, row) of every event in sequence order, validated as a permutation."""
        kinds = list(KINDS)
        codes, rows, orders = [], [], []
        for code, kind in enumerate(kinds):
            c = self.columns(kind)
            if not c:
                continue
            m = len(c["order"])
            codes.append(np.full(m, code, dtype=np.int8))
            rows.append(np.arange(m, dtype=np.int64))
            orders.append(c["order"])
        if not orders:
            return np.zeros(0, np.int8), np.zeros(0, np.int64)
        order = np.concatenate(orders)
        n = len(self)
        if len(order) != n or not np.array_equal(np.sort(order), np.arange(n)):
            raise DataError(f"records */order.npy are not a permutation of 0..{n - 1}", self.path)
        pos = np.empty(n, dtype=np.int64)
        pos[order] = np.arange(n)
        return np.concatenate(codes)[pos], np.concatenate(rows)[pos]

    def _event(self, kind: str, c: dict[str, np.ndarray], i: int) -> Event:
        t = float(c["stamp_s"][i])
        if kind == "odometry":
            return Odometry(t, float(c["dt_s"][i]), float(c["v_mps"][i]), float(c["omega_radps"][i]))
        if kind == "range_bearing":
            a, b = c["offsets"][i], c["offsets"][i + 1]
            return RangeBearing(t, c["landmark_ids"][a:b], c["range_m"][a:b], c["bearing_rad"][a:b])
        if kind == "gps":
            return Gps(t, c["world_p_body"][i], float(c["sigma_m"][i]))
        if kind == "imu":
            return Imu(t, c["gyro_radps"][i], c["accel_mps2"][i])
        if kind == "wheel_encoders":
            return WheelEncoders(t, int(c["ticks_left"][i]), int(c["ticks_right"][i]))
        a, b = c["offsets"][i], c["offsets"][i + 1]
        return Scan(t, c["angles_rad"][a:b], c["ranges_m"][a:b], float(c["max_range_m"][i]))

    def __iter__(self) -> Iterator[Event]:
        kinds = list(KINDS)
        codes, rows = self._positions()
        cols = [self.columns(k) for k in kinds]
        for code, row in zip(codes.tolist(), rows.tolist()):
            yield self._event(kinds[code], cols[code], row)

    def of_type(self, kind_type: type) -> list:
        kind = _KIND_OF.get(kind_type)
        if kind is None:
            raise DataError(f"unsupported event type {kind_type!r}", self.path)
        c = self.columns(kind)
        if not c:
            return []
        order = np.argsort(c["order"], kind="stable")
        return [self._event(kind, c, int(i)) for i in order]

    def to_sequence(self) -> Sequence:
        return Sequence(name=self.name, events=tuple(self), ground_truth=self.ground_truth,
                        world_p_landmarks=self.world_p_landmarks,
                        initial_world_xytheta_body=self.initial_world_xytheta_body, metadata=self.metadata)

    def close(self) -> None:
        self._zip.close()

    def __enter__(self) -> "SequenceReader":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _reject_constant(name: str) -> None:
    # Python's json reads NaN and Infinity, which JSON does not have (and a header never holds)
    raise ValueError(f"{name} is not a JSON number")


def _count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _shape_text(shape: tuple) -> str:
    parts = ["n" if w is None else "|".join(map(str, w)) if isinstance(w, tuple) else str(w) for w in shape]
    return "(" + ", ".join(parts) + ("," if len(parts) == 1 else "") + ")"


def open_sequence(path: str | Path) -> SequenceReader:
    """Open a sequence file lazily (header read now, columns on demand)."""
    return SequenceReader(path)


def load_sequence(path: str | Path) -> Sequence:
    """Read a whole sequence file into an in-memory ``Sequence``."""
    with SequenceReader(path) as reader:
        return reader.to_sequence()
