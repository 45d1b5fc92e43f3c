"""The gtsam wheel's EqVIO replay file ``eqvio_processed_30s.csv``: 30 s of real EuRoC V1_01_easy
IMU readings (200 Hz) and tracked image features (20 Hz), as gtsam's ``EqVIOFilterExample`` reads
it (``gtsam_unstable/examples/EqVIOReplayHelper.h``).

One CSV with a header ``row_type,t_abs,t_rel,seq,frame_idx,landmark_id,gx,gy,gz,ax,ay,az,bgx,
bgy,bgz,bax,bay,baz,u_norm,v_norm,key,value`` and three row types, replayed in ``seq`` order:

* ``meta``: ``key,value`` (``format_version`` 1, ``measurement_space`` ``normalized``, the
  camera intrinsics ``camera_fx`` ..., the EqF tuning ``eqf.*``, and the camera extrinsics
  ``T_ci_{tx,ty,tz,qw,qx,qy,qz}``);
* ``imu``: ``t_abs`` (s), gyro ``gx gy gz`` (rad/s), specific force ``ax ay az`` (m/s^2) in the
  IMU frame (the bias columns are zero in this file);
* ``vision_feature``: one tracked feature of camera frame ``frame_idx`` at ``t_abs``:
  ``landmark_id`` (a track id) and its undistorted normalised image coordinates
  ``u_norm v_norm`` (x/z, y/z in the camera frame: the example's camera is Cal3_S2(1, 1, 0, 0, 0)).

``T_ci`` is the camera pose in the IMU frame, imu_T_camera: its translation (-0.0216, -0.0647,
0.0098) m and rotation are EuRoC's cam0 ``sensor.yaml`` ``T_BS`` (body = IMU). The IMU and
camera stamps share one clock (EuRoC's VI-sensor is hardware-synchronised; the frames fall on
IMU stamps). Bad input -> ``DataError`` naming the file and line.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slamkit._text import is_number_token, read_text, split_lines
from slamkit.errors import DataError
from slamkit.geometry import so3

__all__ = ["EqvioData", "read_eqvio_csv"]

_EXTRINSIC_KEYS = ("T_ci_tx", "T_ci_ty", "T_ci_tz", "T_ci_qw", "T_ci_qx", "T_ci_qy", "T_ci_qz")


@dataclass(frozen=True)
class EqvioData:
    metadata: dict[str, str]
    imu_stamps_s: np.ndarray       #: (N,)
    gyro_radps: np.ndarray         #: (N, 3) IMU frame
    accel_mps2: np.ndarray         #: (N, 3) specific force, IMU frame
    frame_stamps_s: np.ndarray     #: (F,)
    frame_features: tuple          #: F tuples (landmark ids (k,), normalised xy (k, 2))
    imu_T_camera: np.ndarray       #: (4, 4)
    camera_fx_fy_cx_cy: tuple[float, float, float, float]  #: of the original images (pixels)

    @property
    def num_features(self) -> int:
        return sum(len(ids) for ids, _ in self.frame_features)


_COLUMNS = ("row_type", "t_abs", "seq", "frame_idx", "landmark_id", "gx", "gy", "gz", "ax", "ay", "az",
            "u_norm", "v_norm", "key", "value")


def _float(row: dict, key: str, path: Path, line: int) -> float:
    token = row.get(key)
    if token is None or not is_number_token(token.strip()):
        raise DataError(f"column {key!r} is not a number: {token!r}", path, line)
    value = float(token)
    if not np.isfinite(value):
        raise DataError(f"column {key!r} is not finite: {token!r}", path, line)
    return value


def _int(row: dict, key: str, path: Path, line: int) -> int:
    value = _float(row, key, path, line)
    # seq, frame and track ids count from 0; 2^53 is where a float stops holding every integer
    if value != int(value) or not 0 <= value < 2.0**53:
        raise DataError(f"column {key!r} is not an integer in [0, 2^53): {row.get(key)!r}", path, line)
    return int(value)


def _meta_float(meta: dict[str, tuple[str, int]], key: str, path: Path) -> float:
    token, line = meta[key]
    if not is_number_token(token.strip()) or not np.isfinite(float(token)):
        raise DataError(f"meta {key!r} is {token!r}, not a finite number", path, line)
    return float(token)


def read_eqvio_csv(path: str | Path) -> EqvioData:
    path = Path(path)
    text = read_text(path)  # non-UTF-8 bytes: a DataError naming the line
    meta: dict[str, tuple[str, int]] = {}  # key -> (value, line)
    imu: list[tuple[int, float, list[float], list[float], int]] = []
    feats: dict[int, list] = {}
    # the shared line rule (only "\n" ends a line), so line N is what ``sed -n Np`` shows
    reader = csv.DictReader(split_lines(text))
    try:
        fieldnames = reader.fieldnames
        missing = sorted(set(_COLUMNS) - set(fieldnames or []))
        if missing:
            raise DataError(f"the header lacks columns {missing}", path, 1)
        for row in reader:
            line = reader.line_num
            kind = row["row_type"]
            if kind == "meta":
                if not row["key"]:
                    raise DataError("a meta row without a key", path, line)
                meta[row["key"]] = (row["value"] or "", line)
            elif kind == "imu":
                imu.append((_int(row, "seq", path, line), _float(row, "t_abs", path, line),
                            [_float(row, k, path, line) for k in ("gx", "gy", "gz")],
                            [_float(row, k, path, line) for k in ("ax", "ay", "az")], line))
            elif kind == "vision_feature":
                frame = _int(row, "frame_idx", path, line)
                t = _float(row, "t_abs", path, line)
                entry = feats.setdefault(frame, [t, [], [], line])
                if t != entry[0]:
                    raise DataError(f"frame {frame} at t_abs {t!r} s, but line {entry[3]} has it at {entry[0]!r} s",
                                    path, line)
                entry[1].append(_int(row, "landmark_id", path, line))
                entry[2].append((_float(row, "u_norm", path, line), _float(row, "v_norm", path, line)))
            else:
                raise DataError(f"unknown row_type {kind!r}", path, line)
    except csv.Error as exc:
        raise DataError(f"not a CSV row: {exc}", path, reader.line_num) from None
    space = meta.get("measurement_space", ("normalized", None))
    if space[0] != "normalized":
        raise DataError(f"measurement_space {space[0]!r}: only 'normalized' is read", path, space[1])
    missing = [k for k in _EXTRINSIC_KEYS + ("camera_fx", "camera_fy", "camera_cx", "camera_cy") if k not in meta]
    if missing:
        raise DataError(f"metadata lacks {missing}", path)
    if not imu or not feats:
        raise DataError("the file holds no imu or no vision_feature rows", path)
    imu.sort(key=lambda r: r[0])
    seqs = np.array([r[0] for r in imu])
    stamps = np.array([r[1] for r in imu])
    # replayed in seq order: a repeated seq or a stamp that does not increase along it is refused
    bad = np.flatnonzero((np.diff(seqs) == 0) | (np.diff(stamps) <= 0))
    if len(bad):
        k = int(bad[0]) + 1
        raise DataError(f"imu stamps must increase with seq: seq {imu[k][0]} at {imu[k][1]!r} s follows seq "
                        f"{imu[k - 1][0]} at {imu[k - 1][1]!r} s (line {imu[k - 1][4]})", path, imu[k][4])
    frames = sorted(feats)
    frame_stamps = np.array([feats[f][0] for f in frames])
    bad = np.flatnonzero(np.diff(frame_stamps) <= 0)
    if len(bad):
        k = int(bad[0]) + 1
        raise DataError(f"frame stamps must increase with frame_idx: frame {frames[k]} at {float(frame_stamps[k])!r} s "
                        f"follows frame {frames[k - 1]} at {float(frame_stamps[k - 1])!r} s", path, feats[frames[k]][3])
    m = {k: _meta_float(meta, k, path) for k in _EXTRINSIC_KEYS}
    q = np.array([m["T_ci_qw"], m["T_ci_qx"], m["T_ci_qy"], m["T_ci_qz"]])
    norm = float(np.linalg.norm(q))
    if not 0.5 < norm < 2.0:  # a unit quaternion written with a few digits, not a zero or garbage one
        raise DataError(f"T_ci quaternion has norm {norm:.6g}, expected 1", path, meta["T_ci_qw"][1])
    T = np.eye(4)
    T[:3, :3] = so3.from_quat_wxyz(q / norm)
    T[:3, 3] = [m["T_ci_tx"], m["T_ci_ty"], m["T_ci_tz"]]
    camera = tuple(_meta_float(meta, k, path) for k in ("camera_fx", "camera_fy", "camera_cx", "camera_cy"))
    if not (camera[0] > 0 and camera[1] > 0):
        raise DataError(f"camera focal lengths must be > 0, got {camera[:2]}", path, meta["camera_fx"][1])
    return EqvioData(
        metadata={k: v for k, (v, _) in meta.items()}, imu_stamps_s=stamps, gyro_radps=np.array([r[2] for r in imu]),
        accel_mps2=np.array([r[3] for r in imu]),
        frame_stamps_s=frame_stamps,
        frame_features=tuple((np.array(feats[f][1], dtype=int), np.array(feats[f][2], dtype=float).reshape(-1, 2))
                             for f in frames),
        imu_T_camera=T,
        camera_fx_fy_cx_cy=camera)
