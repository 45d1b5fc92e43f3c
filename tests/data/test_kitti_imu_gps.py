"""The KITTI IMU/GPS files of the gtsam wheel as an inertial Sequence, and GPS outage windows."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data import registry
from slamkit.data.inertial import outage_windows, setup_of, withhold_gps
from slamkit.data.sequence import Gps, Imu
from slamkit.errors import DataError

pytestmark = pytest.mark.skipif(not registry.is_available(registry.get("kitti-imu-gps")),
                                reason="gtsam wheel Data folder not found")


@pytest.fixture(scope="module")
def kitti():
    from slamkit.data.formats.kitti_imu_gps import load_kitti_imu_gps

    return load_kitti_imu_gps()


def test_counts_noise_and_start(kitti):
    """Fix 1 is the start (t = 0): 46,867 of the 46,968 IMU rows and 468 fixes follow it, over
    468.6 s; the noise is
    GTSAM's example's (accel density 0.01, gyro 1.75e-4, bias sigmas per 0.01004 s sample ->
    densities 1.667e-3 and 2.904e-5), GPS sigma sqrt(0.07) m, gravity 9.8 m/s^2."""
    imu, gps = kitti.of_type(Imu), kitti.of_type(Gps)
    assert len(imu) == 46_867 and len(gps) == 468
    assert imu[0].stamp_s > 0 and imu[-1].stamp_s == pytest.approx(468.63, abs=0.01)
    s = setup_of(kitti)
    assert s.imu_noise.accel_noise_density == 0.01 and s.imu_noise.gyro_noise_density == 1.75e-4
    assert s.imu_noise.accel_bias_random_walk == pytest.approx(1.6667e-3, rel=1e-3)
    assert s.imu_noise.gyro_bias_random_walk == pytest.approx(2.904e-5, rel=1e-3)
    assert s.gps_sigma_m == pytest.approx(np.sqrt(0.07)) and s.gravity_mps2[2] == -9.8
    # the start velocity is the central difference of fixes 0 and 2: ~7.9 m/s, heading ~61.6 deg
    assert np.linalg.norm(s.initial.world_v_body) == pytest.approx(7.97, abs=0.05)
    assert np.allclose(s.initial.world_p_body, [3.8971155, 7.5450739, 0.0247879])
    assert kitti.metadata["time_offset_s"] == pytest.approx(46537.387955333)


def test_outages_withhold_every_fix_inside_their_windows(kitti):
    """30 s windows, 60 s of GPS between them, the first after 60 s: windows start at 60, 150,
    240, 330, 420 s and hold 30 fixes each (1 Hz), 31 in the first (the receiver's stamps slip
    by 10 ms: fixes at 60.00 and 89.99 s both fall inside [60, 90))."""
    from slamkit.data.formats.kitti_imu_gps import load_kitti_imu_gps

    seq = load_kitti_imu_gps(outage_s=30.0)
    w = seq.metadata["withheld_gps"]
    np.testing.assert_allclose(w["windows_s"][:, 0], [60, 150, 240, 330, 420])
    assert np.bincount(w["window"]).tolist() == [31, 30, 30, 30, 30]
    kept = np.array([e.stamp_s for e in seq.of_type(Gps)])
    assert len(kept) + len(w["stamps_s"]) == len(kitti.of_type(Gps))
    assert not np.any((kept[:, None] >= w["windows_s"][:, 0]) & (kept[:, None] < w["windows_s"][:, 1]))
    assert seq.name == "kitti-imu-gps_outage30s"


def test_outage_windows_worked_example():
    np.testing.assert_allclose(outage_windows(0.0, 100.0, 10.0, 20.0, 5.0), [[5, 15], [35, 45], [65, 75]])
    assert outage_windows(0.0, 10.0, 30.0, 5.0, 0.0).shape == (0, 2)


def test_setup_of_a_non_inertial_sequence_is_a_data_error(kitti):
    import dataclasses

    with pytest.raises(DataError, match="not inertial"):
        setup_of(dataclasses.replace(kitti, metadata={}))
    assert withhold_gps(kitti, np.zeros((0, 2))).metadata["withheld_gps"]["stamps_s"].shape == (0,)


# --- issue 31: bad files are a DataError naming file and line (np.loadtxt let nan/inf through) ---

_IMU_HEAD = "Time dt accelX accelY accelZ omegaX omegaY omegaZ\n"
_META = ("BodyPtx BodyPty BodyPtz BodyPrx BodyPry BodyPrz AccelerometerSigma GyroscopeSigma IntegrationSigma "
         "AccelerometerBiasSigma GyroscopeBiasSigma AverageDeltaT\n0 0 0 0 0 0 0.01 0.000175 0 0.000167 2.91e-006 0.01\n")


def _files(tmp_path, imu_rows=None, gps_rows=None, meta=_META):
    """Five IMU rows 0.01 s apart and four fixes 1 s apart unless overridden (rows as text)."""
    imu_rows = imu_rows or [f"{10 + 0.01 * k} 0.01 0.1 0 9.8 0 0 0.01" for k in range(150, 155)]
    gps_rows = gps_rows or [f"{10 + k},{2.0 * k},{1.0 * k},0" for k in range(4)]
    paths = tmp_path / "imu.txt", tmp_path / "gps.txt", tmp_path / "meta.txt"
    paths[0].write_text(_IMU_HEAD + "\n".join(imu_rows) + "\n")
    paths[1].write_text("Time,X,Y,Z\n" + "\n".join(gps_rows) + "\n")
    paths[2].write_text(meta)
    return paths


def test_small_files_read(tmp_path):
    from slamkit.data.formats.kitti_imu_gps import read_kitti_imu_gps

    seq = read_kitti_imu_gps(*_files(tmp_path))
    # start at fix 1 (t = 11 s): the IMU rows at 11.5-11.54 s and fixes 2, 3 follow it
    assert [round(e.stamp_s, 6) for e in seq.of_type(Imu)] == [0.5, 0.51, 0.52, 0.53, 0.54]
    assert [e.stamp_s for e in seq.of_type(Gps)] == [1.0, 2.0]


@pytest.mark.parametrize("which, row, expected", [
    ("imu", "11.52 0.01 nan 0 9.8 0 0 0.01", r"imu\.txt:4: NaN or infinity"),
    ("imu", "11.52 0.01 0.1 0 inf 0 0 0.01", r"imu\.txt:4: NaN or infinity"),
    ("imu", "11.505 0.01 0.1 0 9.8 0 0 0.01", r"imu\.txt:4: time 11\.505 s does not follow 11\.51 s \(line 3\)"),
    ("imu", "11.52 0.01 0.1 0 9.8 0 0", r"imu\.txt:4: expected 8 numbers, got 7"),
    ("gps", "12,4.0,nan,0", r"gps\.txt:4: NaN or infinity"),
    ("gps", "10.5,4.0,2.0,0", r"gps\.txt:4: time 10\.5 s does not follow 11\.0 s \(line 3\)"),
    ("gps", "12,4.0,2.0", r"gps\.txt:4: expected 4 numbers, got 3"),
])
def test_bad_rows_name_file_and_line(tmp_path, which, row, expected):
    from slamkit.data.formats.kitti_imu_gps import read_kitti_imu_gps

    imu = [f"{10 + 0.01 * k} 0.01 0.1 0 9.8 0 0 0.01" for k in range(150, 155)]
    gps = [f"{10 + k},{2.0 * k},{1.0 * k},0" for k in range(4)]
    (imu if which == "imu" else gps)[2] = row  # line 4 of the file
    with pytest.raises(DataError, match=expected):
        read_kitti_imu_gps(*_files(tmp_path, imu, gps))


@pytest.mark.parametrize("meta, expected", [
    (_META.replace("0.000175", "inf"), r"meta\.txt:2: NaN or infinity"),
    (_META.replace("0.000175", "0"), r"meta\.txt:2: GyroscopeSigma must be > 0, got 0\.0"),
    (_META.replace(" 0.01\n", " -0.01\n"), r"meta\.txt:2: AverageDeltaT must be > 0"),
    (_META + "0 0 0 0 0 0 0.01 0.000175 0 0.000167 2.91e-006 0.01\n", r"meta\.txt:3: expected one metadata row, got 2"),
])
def test_bad_metadata_names_file_and_line(tmp_path, meta, expected):
    from slamkit.data.formats.kitti_imu_gps import read_kitti_imu_gps

    with pytest.raises(DataError, match=expected):
        read_kitti_imu_gps(*_files(tmp_path, meta=meta))


def test_non_utf8_bytes_name_the_line(tmp_path):
    from slamkit.data.formats.kitti_imu_gps import read_kitti_imu_gps

    paths = _files(tmp_path)
    paths[1].write_bytes(paths[1].read_bytes().replace(b"12,", b"1\xff2,"))
    with pytest.raises(DataError, match=r"gps\.txt:4: not a text file"):
        read_kitti_imu_gps(*paths)


def test_a_bias_random_walk_that_overflows_names_the_metadata_line(tmp_path):
    """GyroscopeBiasSigma 1e308 over AverageDeltaT 1e-10 s: before, an infinite random walk density
    reached the setup (found by the fuzzer)."""
    from slamkit.data.formats.kitti_imu_gps import read_kitti_imu_gps

    meta = _META.replace("2.91e-006", "1e308").replace(" 0.01\n", " 1e-10\n")
    with pytest.raises(DataError, match=r"meta\.txt:2: bias random walks \(inf, .*\) .* are not finite"):
        read_kitti_imu_gps(*_files(tmp_path, meta=meta))
