"""Issue 31: the KITTI IMU/GPS reader's parameters that only the data can bound (an empty time
window, more outage windows than any drive has) are refused, on small files written here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from slamkit.data.formats.kitti_imu_gps import read_kitti_imu_gps
from slamkit.data.inertial import MAX_OUTAGE_WINDOWS, outage_windows
from slamkit.data.sequence import Gps, Imu
from slamkit.errors import ConfigError, DataError


def kitti_files(folder: Path, seconds: int = 20) -> list[Path]:
    """IMU at 100 Hz and GPS at 1 Hz along x at 1 m/s, from t = 100 s; identity body pose."""
    t_imu = 100.0 + np.arange(seconds * 100 + 1) * 0.01
    imu = np.column_stack([t_imu, np.full_like(t_imu, 0.01), np.zeros((len(t_imu), 2)), np.full_like(t_imu, 9.8),
                           np.zeros((len(t_imu), 3))])
    t_gps = 100.0 + np.arange(seconds + 1, dtype=float)
    gps = np.column_stack([t_gps, t_gps - 100.0, np.zeros((len(t_gps), 2))])
    paths = [folder / "imu.txt", folder / "gps.txt", folder / "meta.txt"]
    np.savetxt(paths[0], imu, header="Time dt accelX accelY accelZ omegaX omegaY omegaZ", comments="")
    np.savetxt(paths[1], gps, delimiter=",", header="Time,X,Y,Z", comments="")
    paths[2].write_text("BodyPtx BodyPty BodyPtz BodyPrx BodyPry BodyPrz AccelerometerSigma GyroscopeSigma "
                        "IntegrationSigma AccelerometerBiasSigma GyroscopeBiasSigma AverageDeltaT\n"
                        "0 0 0 0 0 0 0.01 0.000175 0 0.000167 2.91e-006 0.01\n")
    return paths


def test_the_files_read_with_their_window_and_outages(tmp_path: Path) -> None:
    seq = read_kitti_imu_gps(*kitti_files(tmp_path), max_duration_s=10.0, outage_s=2.0, gap_s=3.0,
                             first_outage_after_s=1.0)
    # start fix 1 (t = 101 s): IMU rows in (101, 111], fixes 102..111; windows [1, 3), [6, 8)
    assert len(seq.of_type(Imu)) == 1000
    assert [g.stamp_s for g in seq.of_type(Gps)] == [3.0, 4.0, 5.0, 8.0, 9.0, 10.0]


@pytest.mark.parametrize("max_duration_s", [0.0, -1.0, float("nan"), float("inf")])
def test_a_max_duration_that_is_not_a_positive_number_is_a_config_error(tmp_path: Path, max_duration_s) -> None:
    with pytest.raises(ConfigError, match=r"max_duration_s must be a finite number > 0 \(or unset: the whole run\)"):
        read_kitti_imu_gps(*kitti_files(tmp_path), max_duration_s=max_duration_s)


def test_a_window_that_keeps_no_data_is_refused_not_an_empty_sequence(tmp_path: Path) -> None:
    files = kitti_files(tmp_path)
    with pytest.raises(DataError, match=r"imu.txt: max_duration_s 0.001 keeps 0 IMU rows and 0 GPS fixes after "
                                        r"fix 1 \(the next fix is 1 s later\): nothing to estimate"):
        read_kitti_imu_gps(*files, max_duration_s=1e-3)
    # 0.5 s keeps IMU rows but no fix: nothing to score against either
    with pytest.raises(DataError, match="keeps 50 IMU rows and 0 GPS fixes"):
        read_kitti_imu_gps(*files, max_duration_s=0.5)


def test_outage_windows_are_capped_before_anything_is_allocated(tmp_path: Path) -> None:
    # issue 31: outage_s 1e-9 with gap_s 0 over KITTI's 468.6 s tried to allocate 2.97 TiB
    with pytest.raises(ConfigError, match=r"outage_s 1e-09 and gap_s 0 make 4.69e\+11 GPS outage windows in "
                                          r"468.6 s; at most 10000"):
        outage_windows(0.0, 468.6, 1e-9, 0.0, 0.0)
    assert len(outage_windows(0.0, 2 * MAX_OUTAGE_WINDOWS + 1.0, 1.0, 1.0, 0.0)) == MAX_OUTAGE_WINDOWS
    with pytest.raises(ConfigError, match="GPS outage windows"):
        read_kitti_imu_gps(*kitti_files(tmp_path), outage_s=1e-9, gap_s=0.0, first_outage_after_s=0.0)
