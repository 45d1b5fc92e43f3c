"""CMU "Navigating with ranging radios" Plaza 1 and Plaza 2 (Djugash & Singh; shipped in the gtsam
wheel) as a :class:`~slamkit.data.sequence.Sequence` of odometry and range-only events.

Files (MANIFEST.md, "Datasets already shipped in the gtsam wheel"):

* ``PlazaK_DR.txt``: dead reckoning, one row per step ``time_s  delta_distance_m
  delta_heading_rad`` (the robot drove ``delta_distance_m`` along its heading and turned by
  ``delta_heading_rad`` since the previous row);
* ``PlazaK_TD.txt``: ranges, ``time_s  sender_id  beacon_id  range_m`` (the sender is the
  vehicle's radio, always 2; the beacon is one of 4 UWB nodes);
* ``PlazaK_.mat`` (MAT v5, read with ``scipy.io.loadmat``): ``GT`` (``time x y heading``, one row
  per DR row plus the start) and ``TL`` (``beacon_id x y``, the surveyed beacon positions).

Events: row k of DR becomes ``Odometry(t_k, dt_k, v = d_k / dt_k, omega = dh_k / dt_k)`` with
``dt_k = t_k - t_{k-1}`` (``t_{-1}`` the first GT stamp), so the exact-arc motion model of
``slamkit.models.diff_drive`` drives d_k along an arc turning by dh_k; each TD row becomes a
``Range(t, [beacon_id], [range_m * range_scale])``. Stamps are shifted so the first GT row is at
0 s (``metadata['time_offset_s']``); ranges before it are dropped.

Measured facts about these files that the reader records rather than hides (``metadata``):

* Plaza 2's GT heading points backwards: the direction the GT positions move in minus the GT
  heading has a median of 3.11 rad (Plaza 1: -0.02 rad), while DR's distances are positive. The
  reader adds pi to a GT heading whose median offset to the direction of motion exceeds pi/2
  (``ground_truth_heading_offset_rad``), so heading is the direction DR's distance advances along
  on both runs (gtsam's own RangeISAMExample_plaza2 starts from ``pi - heading`` for the same
  reason).
* The ranges are ~7% longer than the GT geometry: a least-squares fit ``range = a * |GT - TL|
  + b`` over every range gives a = 1.0694, b = 0.03 m (Plaza 1) and a = 1.0696, b = 0.01 m
  (Plaza 2), residual std 0.54 and 0.56 m; the per-beacon scales agree to 0.003. The fit is
  recomputed on every read (``range_scale_fit``, ``range_offset_fit_m``: a figure to compare
  with, fitted against the ground truth). ``range_scale`` says what the estimators do about it:
  a number divides the ranges by it (1, the default: the ranges as recorded; 1.0696: the
  "calibrated" mode, a calibration taken from the ground truth of the run being scored), and
  ``"estimate"`` keeps the ranges as recorded and declares the scale unknown
  (``metadata['range_scale_sigma']`` = ``range_scale_sigma``, default 0.1), so every range-only
  estimator estimates it jointly from a prior N(1, 0.1^2), with no ground truth.

The noise estimators should assume is the reader's argument (the dataset publishes none) and is
stored in ``metadata`` (``odometry_sigma``, ``sigma_range_m``, ``range_gate_m``).
"""

from __future__ import annotations

import io
import struct
import zlib
from pathlib import Path

import numpy as np

from slamkit._text import number_rows
from slamkit.data.sequence import Event, Odometry, Range, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.geometry.angles import wrap_angle

PLAZA_DATASETS = ("plaza1", "plaza2")
#: ``range_scale`` value that asks the estimators to estimate the range scale
RANGE_SCALE_ESTIMATE = "estimate"

#: GT steps shorter than this (m) do not vote on the heading convention
_MOVING_STEP_M = 0.05


def _mat_tables(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(GT (N, 4), TL (B, 3)) from a Plaza ``.mat`` file."""
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise DataError("no such file", path) from None
    except OSError as exc:
        raise DataError(f"cannot read: {exc}", path) from None
    _check_mat_streams(data, path)
    try:
        mat = loadmat(io.BytesIO(data))
    except (ValueError, OSError, TypeError, KeyError, IndexError, EOFError, OverflowError, struct.error,
            zlib.error, MatReadError, UnboundLocalError) as exc:
        # scipy's MAT parser meets corrupt bytes with any of these (a bad zlib stream, an element
        # tag that is not miMATRIX: TypeError; an array class byte it does not know, 117:
        # UnboundLocalError from its compiled reader)
        raise DataError(f"not a readable MAT v5 file: {type(exc).__name__}: {exc}", path) from None
    tables = []
    for key, width, least in (("GT", 4, 2), ("TL", 3, 1)):
        table = mat.get(key)
        if table is None or np.ndim(table) != 2 or np.shape(table)[1] != width:
            raise DataError(f"needs a {key} table of {width} columns, found "
                            f"{None if table is None else np.shape(table)}", path)
        try:
            table = np.asarray(table, dtype=float)
        except (TypeError, ValueError):
            raise DataError(f"the {key} table is not numbers (MAT class {np.asarray(table).dtype})", path) from None
        if len(table) < least:
            raise DataError(f"the {key} table has {len(table)} rows; at least {least} are needed", path)
        if not np.all(np.isfinite(table)):
            raise DataError(f"the {key} table holds non-finite values", path)
        tables.append(table)
    return tables[0], tables[1]


#: the most bytes the compressed elements of a Plaza ``.mat`` may expand to (the files: 1.1 MB)
MAX_MAT_EXPANDED_BYTES = 64 * 1024 * 1024


def _check_mat_streams(data: bytes, path: Path) -> None:
    """Walk the MAT v5 elements of ``data`` and inflate every compressed one with its Adler-32
    check, before scipy sees the file: scipy inflates without the check and hands corrupt bytes
    to its compiled element reader, which can crash the process (4 bytes changed at offset 264 of
    Plaza1_.mat: a segmentation fault in scipy 1.17)."""
    if len(data) < 128 or data[126:128] not in (b"IM", b"MI"):
        raise DataError("not a MAT v5 file (no endian indicator at byte 126)", path)
    order = "<" if data[126:128] == b"IM" else ">"
    offset, expanded = 128, 0
    while offset < len(data):
        if offset + 8 > len(data):
            raise DataError(f"truncated MAT element tag at byte {offset}", path)
        kind, size = struct.unpack(order + "II", data[offset:offset + 8])
        if kind >> 16:  # small data element: tag and data in 8 bytes
            offset += 8
            continue
        end = offset + 8 + size
        if end > len(data):
            raise DataError(f"MAT element at byte {offset} declares {size} bytes; the file ends first", path)
        if kind == 15:  # miCOMPRESSED
            stream = zlib.decompressobj()
            try:
                expanded += len(stream.decompress(data[offset + 8:end], MAX_MAT_EXPANDED_BYTES - expanded + 1))
                if expanded > MAX_MAT_EXPANDED_BYTES:
                    raise DataError(f"compressed MAT elements expand to more than {MAX_MAT_EXPANDED_BYTES} "
                                    "bytes", path)
                stream.flush()
            except zlib.error as exc:
                raise DataError(f"corrupt compressed MAT element at byte {offset}: {exc}", path) from None
            if not stream.eof:
                raise DataError(f"compressed MAT element at byte {offset} is truncated", path)
            offset = end
        else:
            offset = end + (-size % 8)


def heading_offset_rad(world_xy: np.ndarray, heading_rad: np.ndarray) -> float:
    """Median over the moving steps of (direction of motion - heading), wrapped to [-pi, pi)."""
    step = np.diff(world_xy, axis=0)
    moving = np.hypot(step[:, 0], step[:, 1]) > _MOVING_STEP_M
    if not moving.any():
        return 0.0
    direction = np.arctan2(step[moving, 1], step[moving, 0])
    return float(np.median(wrap_angle(direction - heading_rad[:-1][moving])))


def range_scale_fit(stamps_s: np.ndarray, ids: np.ndarray, ranges_m: np.ndarray,
                    ground_truth: Trajectory, beacons: dict[int, np.ndarray]) -> tuple[float, float]:
    """Least-squares (a, b) of ``range = a * true_range + b``, the true range from the GT position
    (linearly interpolated to each range stamp) to the surveyed beacon."""
    xy = ground_truth.xytheta()[:, :2]
    t = ground_truth.stamps_s
    x = np.interp(stamps_s, t, xy[:, 0])
    y = np.interp(stamps_s, t, xy[:, 1])
    b = np.array([beacons[int(i)] for i in ids])
    true = np.hypot(x - b[:, 0], y - b[:, 1])
    A = np.column_stack([true, np.ones_like(true)])
    (a, c), *_ = np.linalg.lstsq(A, ranges_m, rcond=None)
    return float(a), float(c)


def read_plaza_sequence(mat_path: str | Path, dr_path: str | Path, td_path: str | Path,
                        name: str = "plaza", max_duration_s: float | None = None,
                        range_scale: float | str = 1.0, range_scale_sigma: float = 0.1,
                        odometry_sigma: tuple[float, float] = (0.1, 0.02),
                        sigma_range_m: float = 0.6, range_gate_m: float = 3.0) -> Sequence:
    """One Plaza run as a Sequence (see the module docstring). ``max_duration_s`` keeps the
    first seconds only; ``range_scale`` divides every range, or is ``"estimate"`` (ranges as
    recorded, scale declared unknown with prior sigma ``range_scale_sigma``); ``odometry_sigma`` (v m/s, omega
    rad/s), ``sigma_range_m`` and ``range_gate_m`` are the noise and outlier gate the
    estimators should assume, stored in the metadata."""
    mat_path, dr_path, td_path = Path(mat_path), Path(dr_path), Path(td_path)
    estimate_scale = range_scale == RANGE_SCALE_ESTIMATE
    divisor = 1.0 if estimate_scale else range_scale
    if isinstance(divisor, str) or not (np.isfinite(divisor) and divisor > 0):
        raise DataError(f"range_scale must be a positive number or {RANGE_SCALE_ESTIMATE!r}, got "
                        f"{range_scale!r}", td_path)
    if estimate_scale and not (np.isfinite(range_scale_sigma) and range_scale_sigma > 0):
        raise DataError(f"range_scale_sigma must be positive, got {range_scale_sigma}", td_path)
    gt, tl = _mat_tables(mat_path)
    dr_lines, dr = number_rows(dr_path, 3, "no dead-reckoning rows")
    td = number_rows(td_path, 4, "no range rows")[1]
    t0 = float(gt[0, 0])
    dr_t, td_t, gt_t = dr[:, 0] - t0, td[:, 0] - t0, gt[:, 0] - t0
    if max_duration_s is not None:
        dr_lines, dr, dr_t = dr_lines[dr_t <= max_duration_s], dr[dr_t <= max_duration_s], dr_t[dr_t <= max_duration_s]
        td, td_t = td[td_t <= max_duration_s], td_t[td_t <= max_duration_s]
        gt, gt_t = gt[gt_t <= max_duration_s], gt_t[gt_t <= max_duration_s]
    dt = np.diff(np.concatenate([[0.0], dr_t]))
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise DataError(f"dead-reckoning time does not increase at data row {k + 1}", dr_path, int(dr_lines[k]))
    offset = heading_offset_rad(gt[:, 1:3], gt[:, 3])
    flip = np.pi if abs(offset) > np.pi / 2 else 0.0
    heading = wrap_angle(gt[:, 3] + flip)
    ground_truth = Trajectory.from_se2(gt_t, np.column_stack([gt[:, 1:3], heading]))
    beacons = {int(i): np.array([x, y]) for i, x, y in tl}
    unknown = sorted(set(int(i) for i in td[:, 2]) - set(beacons))
    if unknown:
        raise DataError(f"ranges to beacons {unknown} that the TL table does not survey", td_path)
    keep = td_t >= 0.0
    td, td_t = td[keep], td_t[keep]
    a, b = range_scale_fit(td_t, td[:, 2], td[:, 3], ground_truth, beacons)
    with np.errstate(over="ignore"):
        v, omega = dr[:, 1] / dt, dr[:, 2] / dt
    bad = ~(np.isfinite(v) & np.isfinite(omega))
    if bad.any():  # a finite step of 1e308 m over 0.2 s
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"dead-reckoning step ({float(dr[k, 1])!r} m, {float(dr[k, 2])!r} rad) over {float(dt[k])!r} s is not a finite "
                        "speed", dr_path, int(dr_lines[k]))
    events: list[Event] = [Odometry(float(t), float(h), float(vk), float(wk))
                           for t, h, vk, wk in zip(dr_t, dt, v, omega)]
    events += [Range(float(t), np.array([int(i)], dtype=np.int64), np.array([r / divisor]))
               for t, i, r in zip(td_t, td[:, 2], td[:, 3])]
    return Sequence.from_events(
        name, events, ground_truth=ground_truth, world_p_landmarks=beacons,
        initial_world_xytheta_body=ground_truth.xytheta()[0],
        metadata={"source": str(mat_path), "format": "plaza", "time_offset_s": t0,
                  "units": "SI (m, s, rad)", "known_correspondences": True, "range_only": True,
                  "ground_truth_heading_offset_rad": flip, "heading_offset_median_rad": offset,
                  "range_scale": range_scale,
                  "range_scale_sigma": range_scale_sigma if estimate_scale else 0.0, "range_scale_fit": a, "range_offset_fit_m": b,
                  "odometry_sigma": list(odometry_sigma), "sigma_range_m": sigma_range_m,
                  "range_gate_m": range_gate_m, "initial_pose_sigma": [1e-3, 1e-3, 1e-3],
                  "noise_note": "assumed noise: the dataset publishes none"})


def load_plaza_sequence(name: str, **params) -> Sequence:
    """Registry ``plaza1`` or ``plaza2`` (params: those of :func:`read_plaza_sequence`)."""
    from slamkit.data import registry

    entry = registry.get(name)
    if entry.format != "plaza":
        raise DataError(f"dataset {name!r} is not a Plaza run; use one of {PLAZA_DATASETS}")
    k = entry.name[-1]
    files = [registry.path_of(entry.name, f"Plaza{k}_{suffix}") for suffix in (".mat", "DR.txt", "TD.txt")]
    return read_plaza_sequence(*files, name=entry.name, **params)
