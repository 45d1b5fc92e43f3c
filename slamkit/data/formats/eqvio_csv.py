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


def _float(row: dict, key: str, path: Path, line: int) -> float:
    try:
        value = float(row[key])
    except (TypeError, ValueError):
        raise DataError(f"column {key!r} is not a number: {row.get(key)!r}", path, line) from None
    if not np.isfinite(value):
        raise DataError(f"column {key!r} is not finite", path, line)
    return value


def read_eqvio_csv(path: str | Path) -> EqvioData:
    path = Path(path)
    try:
        handle = path.open(newline="")
    except FileNotFoundError:
        raise DataError("no such file", path) from None
    meta: dict[str, str] = {}
    imu: list[tuple[int, float, list[float], list[float]]] = []
    feats: dict[int, list] = {}
    with handle:
        reader = csv.DictReader(handle)
        needed = {"row_type", "t_abs", "seq", "frame_idx", "landmark_id", "gx", "ax", "u_norm", "key", "value"}
        if reader.fieldnames is None or not needed <= set(reader.fieldnames):
            raise DataError(f"the header lacks columns {sorted(needed - set(reader.fieldnames or []))}", path, 1)
        for line, row in enumerate(reader, start=2):
            kind = row["row_type"]
            if kind == "meta":
                meta[row["key"]] = row["value"]
            elif kind == "imu":
                imu.append((int(_float(row, "seq", path, line)), _float(row, "t_abs", path, line),
                            [_float(row, k, path, line) for k in ("gx", "gy", "gz")],
                            [_float(row, k, path, line) for k in ("ax", "ay", "az")]))
            elif kind == "vision_feature":
                frame = int(_float(row, "frame_idx", path, line))
                entry = feats.setdefault(frame, [_float(row, "t_abs", path, line), [], []])
                entry[1].append(int(_float(row, "landmark_id", path, line)))
                entry[2].append((_float(row, "u_norm", path, line), _float(row, "v_norm", path, line)))
            else:
                raise DataError(f"unknown row_type {kind!r}", path, line)
    if meta.get("measurement_space", "normalized") != "normalized":
        raise DataError(f"measurement_space {meta['measurement_space']!r}: only 'normalized' is read", path)
    missing = [k for k in _EXTRINSIC_KEYS + ("camera_fx", "camera_fy", "camera_cx", "camera_cy") if k not in meta]
    if missing:
        raise DataError(f"metadata lacks {missing}", path)
    if not imu or not feats:
        raise DataError("the file holds no imu or no vision_feature rows", path)
    imu.sort(key=lambda r: r[0])
    stamps = np.array([r[1] for r in imu])
    if np.any(np.diff(stamps) <= 0):
        raise DataError("imu stamps are not increasing", path)
    m = {k: float(meta[k]) for k in _EXTRINSIC_KEYS}
    q = np.array([m["T_ci_qw"], m["T_ci_qx"], m["T_ci_qy"], m["T_ci_qz"]])
    T = np.eye(4)
    T[:3, :3] = so3.from_quat_wxyz(q / np.linalg.norm(q))
    T[:3, 3] = [m["T_ci_tx"], m["T_ci_ty"], m["T_ci_tz"]]
    frames = sorted(feats)
    return EqvioData(
        metadata=meta, imu_stamps_s=stamps, gyro_radps=np.array([r[2] for r in imu]),
        accel_mps2=np.array([r[3] for r in imu]),
        frame_stamps_s=np.array([feats[f][0] for f in frames]),
        frame_features=tuple((np.array(feats[f][1], dtype=int), np.array(feats[f][2], dtype=float).reshape(-1, 2))
                             for f in frames),
        imu_T_camera=T,
        camera_fx_fy_cx_cy=tuple(float(meta[k]) for k in ("camera_fx", "camera_fy", "camera_cx", "camera_cy")))
