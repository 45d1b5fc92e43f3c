"""The KITTI IMU/GPS files of GTSAM's ``IMUKittiExampleGPS`` as an inertial Sequence.

Files (gtsam wheel ``Data`` folder, registry entry ``kitti-imu-gps``):

* ``KittiEquivBiasedImu.txt``: a header line, then ``time dt ax ay az wx wy wz`` (space
  separated; s, s, m/s^2, rad/s), about 100 Hz; ``dt`` is the interval ending at ``time`` (the
  first row's ``dt`` is the absolute time and is not used: slamkit takes intervals from stamps);
* ``KittiGps_converted.txt``: a header line, then ``time,x,y,z`` (s, m) in a local level frame;
* ``KittiEquivBiasedImu_metadata.txt``: body-to-IMU pose (identity), accelerometer sigma,
  gyroscope sigma, integration sigma, accelerometer bias sigma, gyroscope bias sigma, mean dt.

Noise: GTSAM's example uses the first two sigmas as continuous-time densities (its
``setAccelerometerCovariance(sigma^2 I)``) and the bias sigmas per IMU sample (its bias between
factor has sigma sqrt(n) sigma_b over n samples), i.e. a density sigma_b / sqrt(mean dt); GPS
fixes with variance 0.07 m^2 per axis (its ``noise_model_gps``), gravity 9.8 m/s^2, z up.

With these numbers the data are rougher than the model (measured with the error-state EKF over
the whole run: NIS mean 24.9, median 1.71, 41% of the 468 fixes above the chi2(3) 95% point;
at t = 33-35 s the accelerometer reads 0.4-0.75 m/s^2 more than gravity for two seconds while the
fixes stay level, and iSAM2's own one-second IMU predictions then miss the next fix by 2-3.4 m).
They are kept as GTSAM's example has them, so filter and smoothers share them; estimators
override them per run with ``imu_noise``.

Bad input -> DataError naming the file and line: a malformed or non-finite number, a stamp that
does not increase, a non-positive sigma, undecodable bytes.

Start: the fix ``start_fix`` (default 1, as the example; fix 0 lies before a 1.9 s IMU gap). The
start position is that fix, the velocity the central difference of its neighbours, the heading
and pitch the direction of that velocity, roll 0; the sigmas of this guess are
:data:`START_SIGMA`. Stamps are shifted so the start is t = 0 (``metadata["time_offset_s"]``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from slamkit._text import number_rows
from slamkit.data.inertial import InertialSetup, NavState, outage_windows, setup_to_metadata, withhold_gps
from slamkit.data.sequence import Gps, Imu, Sequence
from slamkit.errors import ConfigError, DataError
from slamkit.geometry import so3
from slamkit.models.imu import ImuNoise

#: GTSAM's KITTI example: gravity and the GPS variance (m^2)
GRAVITY_MPS2 = 9.8
GPS_VARIANCE_M2 = 0.07
#: sigmas of the start guess: position (m) = the GPS sigma, velocity (m/s), attitude (roll, pitch,
#: yaw; rad, world frame), accel bias (m/s^2) and gyro bias (rad/s) as in GTSAM's example prior
START_SIGMA = {"velocity": 0.5, "attitude": (0.05, 0.05, 0.1), "accel_bias": 0.1, "gyro_bias": 5e-4}


def read_kitti_imu_gps(imu_path: str | Path, gps_path: str | Path, metadata_path: str | Path,
                       name: str = "kitti-imu-gps", start_fix: int = 1, max_duration_s: float | None = None,
                       outage_s: float | None = None, gap_s: float = 60.0, first_outage_after_s: float = 60.0
                       ) -> Sequence:
    """The KITTI files as a Sequence (see the module docstring). With ``outage_s``, GPS is
    withheld in windows of that length separated by ``gap_s`` of GPS, the first
    ``first_outage_after_s`` after the start (:func:`slamkit.data.inertial.withhold_gps`)."""
    # the shared table rule: ASCII numbers, finite, one-based line numbers in every message
    imu_lines, imu = number_rows(imu_path, 8, "no IMU rows", header_lines=1)
    gps_lines, gps = number_rows(gps_path, 4, "no GPS rows", header_lines=1, delimiter=",")
    meta_lines, meta = number_rows(metadata_path, 12, "no metadata row", header_lines=1)
    for path, lines, t in ((imu_path, imu_lines, imu[:, 0]), (gps_path, gps_lines, gps[:, 0])):
        back = np.flatnonzero(np.diff(t) <= 0)
        if len(back):
            k = int(back[0]) + 1
            raise DataError(f"time {float(t[k])!r} s does not follow {float(t[k - 1])!r} s (line {int(lines[k - 1])}); "
                            "stamps must increase", path, int(lines[k]))
    if len(meta) != 1:
        raise DataError(f"expected one metadata row, got {len(meta)}", metadata_path, int(meta_lines[1]))
    meta = meta[0]
    if np.any(meta[:6] != 0):
        raise DataError(f"only an identity body-to-IMU pose is supported, got {meta[:6]}", metadata_path,
                        int(meta_lines[0]))
    for k, field in ((6, "AccelerometerSigma"), (7, "GyroscopeSigma"), (9, "AccelerometerBiasSigma"),
                     (10, "GyroscopeBiasSigma"), (11, "AverageDeltaT")):
        if not meta[k] > 0:
            raise DataError(f"{field} must be > 0, got {float(meta[k])!r}", metadata_path, int(meta_lines[0]))
    accel_sigma, gyro_sigma, _, accel_bias_sigma, gyro_bias_sigma, mean_dt = meta[6:]
    if not 1 <= start_fix < len(gps) - 1:
        raise DataError(f"{len(gps)} fixes: start_fix must be in [1, {len(gps) - 2}], got {start_fix}", gps_path)
    t0 = float(gps[start_fix, 0])
    p0 = gps[start_fix, 1:]
    v0 = (gps[start_fix + 1, 1:] - gps[start_fix - 1, 1:]) / (gps[start_fix + 1, 0] - gps[start_fix - 1, 0])
    if not np.isfinite(v0).all():  # fixes 1e308 m apart
        raise DataError(f"the start velocity from fixes {start_fix - 1} and {start_fix + 1} is not finite: {v0}",
                        gps_path, int(gps_lines[start_fix]))
    yaw = np.arctan2(v0[1], v0[0])
    pitch = -np.arcsin(np.clip(v0[2] / max(np.linalg.norm(v0), 1e-9), -1.0, 1.0))
    with np.errstate(over="ignore"):
        walks = (float(gyro_bias_sigma / np.sqrt(mean_dt)), float(accel_bias_sigma / np.sqrt(mean_dt)))
    if not np.isfinite(walks).all():  # a bias sigma of 1e308 over a 1e-320 s sample
        raise DataError(f"bias random walks {walks} (bias sigmas over sqrt(AverageDeltaT)) are not finite",
                        metadata_path, int(meta_lines[0]))
    noise = ImuNoise(gyro_noise_density=float(gyro_sigma), gyro_bias_random_walk=walks[0],
                     accel_noise_density=float(accel_sigma), accel_bias_random_walk=walks[1])
    gps_sigma = float(np.sqrt(GPS_VARIANCE_M2))
    s = START_SIGMA
    sigma = np.concatenate([np.full(3, gps_sigma), np.full(3, s["velocity"]), s["attitude"],
                            np.full(3, s["accel_bias"]), np.full(3, s["gyro_bias"])])
    start = NavState(0.0, p0, v0, so3.from_euler_zyx(yaw, pitch, 0.0))
    setup = InertialSetup(start, sigma, noise, np.array([0.0, 0.0, -GRAVITY_MPS2]), gps_sigma)
    if max_duration_s is not None and not (math.isfinite(max_duration_s) and max_duration_s > 0):
        raise ConfigError(f"max_duration_s must be a finite number > 0 (or unset: the whole run), got "
                          f"{max_duration_s!r}")
    end = np.inf if max_duration_s is None else t0 + float(max_duration_s)
    imu_rows = imu[(imu[:, 0] > t0) & (imu[:, 0] <= end)]
    gps_rows = gps[(gps[:, 0] > t0) & (gps[:, 0] <= end)]
    if not len(imu_rows) or not len(gps_rows):
        # an empty sequence would run every estimator on nothing and report only its run time
        raise DataError(f"max_duration_s {max_duration_s!r} keeps {len(imu_rows)} IMU rows and {len(gps_rows)} GPS "
                        f"fixes after fix {start_fix} (the next fix is {float(gps[start_fix + 1, 0] - t0):.3g} s "
                        "later): nothing to estimate", imu_path)
    events: list = [Imu(float(r[0] - t0), r[5:8].copy(), r[2:5].copy()) for r in imu_rows]
    events += [Gps(float(r[0] - t0), r[1:4].copy(), gps_sigma) for r in gps_rows]
    metadata = {"inertial": setup_to_metadata(setup), "time_offset_s": t0,
                "frames": "world: local level frame of the converted GPS, z up; body = IMU (x forward)",
                "noise_note": "IMU densities from the metadata file as GTSAM's example reads them"}
    seq = Sequence.from_events(name, events, metadata=metadata)
    if outage_s is not None:
        duration = float(min(end, imu_rows[-1, 0]) - t0)
        windows = outage_windows(0.0, duration, float(outage_s), float(gap_s), float(first_outage_after_s))
        seq = withhold_gps(seq, windows)
    return seq


def load_kitti_imu_gps(name: str = "kitti-imu-gps", **params) -> Sequence:
    """The registry dataset ``kitti-imu-gps`` (params as :func:`read_kitti_imu_gps`)."""
    from slamkit.data import registry

    entry = registry.get(name)
    files = [registry.path_of(entry.name, f) for f in ("KittiEquivBiasedImu.txt", "KittiGps_converted.txt",
                                                        "KittiEquivBiasedImu_metadata.txt")]
    label = params.pop("label", None) or (entry.name if params.get("outage_s") is None
                                          else f"{entry.name}_outage{params['outage_s']:g}s")
    return read_kitti_imu_gps(*files, name=label, **params)
