"""The gtsam wheel's EqVIO replay file (EuRoC V1_01, 30 s): counts, extrinsics, bad input."""

import numpy as np
import pytest

from slamkit.data import registry
from slamkit.data.formats.eqvio_csv import read_eqvio_csv
from slamkit.errors import DataError

#: EuRoC V1_01 cam0/sensor.yaml T_BS (body = IMU), rotation part
EUROC_CAM0_R_BS = np.array([[0.0148655429818, -0.999880929698, 0.004140296794224],
                            [0.999557249008, 0.0149672133247, 0.025715529948],
                            [-0.0257744366974, 0.00375618835797, 0.999660727178]])


@pytest.fixture(scope="module")
def data():
    return read_eqvio_csv(registry.path_of("euroc-v101-eqvio"))


def test_counts_and_rates(data):
    assert len(data.imu_stamps_s) == 6001 and len(data.frame_stamps_s) == 601
    assert data.num_features == 13316
    assert len({int(j) for ids, _ in data.frame_features for j in ids}) == 307
    assert np.allclose(np.diff(data.imu_stamps_s).mean(), 0.005, atol=1e-6)   # 200 Hz
    assert np.allclose(np.diff(data.frame_stamps_s), 0.05, atol=1e-3)         # 20 Hz
    assert data.frame_stamps_s[0] == pytest.approx(1403715273.2621431)
    # frames fall on IMU stamps (one clock)
    assert np.isin(np.round(data.frame_stamps_s, 4), np.round(data.imu_stamps_s, 4)).all()
    # at rest at the start: the specific force is gravity
    assert np.linalg.norm(data.accel_mps2[:200].mean(axis=0)) == pytest.approx(9.81, abs=0.05)


def test_extrinsics_are_euroc_cam0_T_BS(data):
    T = data.imu_T_camera
    assert np.allclose(T[:3, :3], EUROC_CAM0_R_BS, atol=1e-6)
    assert np.allclose(T[:3, 3], [-0.0216401454975, -0.064676986768, 0.00981073058949], atol=1e-9)
    assert data.camera_fx_fy_cx_cy == pytest.approx((458.654, 457.296, 367.215, 248.375))


def test_bad_input_names_file_and_line(tmp_path):
    p = tmp_path / "bad.csv"
    head = "row_type,t_abs,t_rel,seq,frame_idx,landmark_id,gx,gy,gz,ax,ay,az,bgx,bgy,bgz,bax,bay,baz,u_norm,v_norm,key,value\n"
    p.write_text(head + "imu,1.0,0,1,,,0,0,0,0,0,9.8,0,0,0,0,0,0,,,,\nvision_feature,1.0,0,2,0,1,,,,,,,,,,,,,x,0.2,,\n")
    with pytest.raises(DataError, match=r"bad.csv:3: column .u_norm. is not a number"):
        read_eqvio_csv(p)
    p.write_text(head + "odd,1.0,0,1,,,,,,,,,,,,,,,,,,\n")
    with pytest.raises(DataError, match="unknown row_type"):
        read_eqvio_csv(p)
    p.write_text(head + "imu,1.0,0,1,,,0,0,0,0,0,9.8,0,0,0,0,0,0,,,,\n")
    with pytest.raises(DataError, match="metadata lacks"):
        read_eqvio_csv(p)


# --- issue 31: non-UTF-8, missing columns, non-finite values, stamps going backwards ---------

HEAD = ("row_type,t_abs,t_rel,seq,frame_idx,landmark_id,gx,gy,gz,ax,ay,az,bgx,bgy,bgz,bax,bay,baz,u_norm,v_norm,"
        "key,value\n")
META = "".join(f"meta,,,,,,,,,,,,,,,,,,,,{k},{v}\n" for k, v in [
    ("T_ci_tx", 0.1), ("T_ci_ty", 0), ("T_ci_tz", 0), ("T_ci_qw", 1), ("T_ci_qx", 0), ("T_ci_qy", 0), ("T_ci_qz", 0),
    ("camera_fx", 400), ("camera_fy", 400), ("camera_cx", 300), ("camera_cy", 200)])


def _imu(seq: int, t: float, gz: str = "0.1") -> str:
    return f"imu,{t},0,{seq},,,0,0,{gz},0,0,9.8,0,0,0,0,0,0,,,,\n"


def _feature(frame: int, t: float, v: str = "0.2") -> str:
    return f"vision_feature,{t},0,{100 + frame},{frame},7,,,,,,,,,,,,,0.1,{v},,\n"


def test_a_small_valid_file_reads(tmp_path):
    p = tmp_path / "ok.csv"
    p.write_text(HEAD + META + _imu(1, 1.0) + _imu(2, 1.005) + _feature(0, 1.0) + _feature(1, 1.05))
    data = read_eqvio_csv(p)
    np.testing.assert_array_equal(data.imu_stamps_s, [1.0, 1.005])
    np.testing.assert_array_equal(data.frame_stamps_s, [1.0, 1.05])
    assert data.imu_T_camera[0, 3] == 0.1 and data.camera_fx_fy_cx_cy == (400.0, 400.0, 300.0, 200.0)


@pytest.mark.parametrize("body, expected", [
    # line numbers: 1 header, 2-12 meta, then the rows below
    (_imu(1, 1.0) + _imu(2, 1.005, gz="nan") + _feature(0, 1.0), r"ok\.csv:14: column 'gz' is not finite"),
    (_imu(1, 1.0) + _imu(2, 1.005, gz="inf") + _feature(0, 1.0), r"ok\.csv:14: column 'gz' is not finite"),
    (_imu(1, 1.0) + _feature(0, 1.0, v="-inf"), r"ok\.csv:14: column 'v_norm' is not finite"),
    (_imu(1, 1.0) + _imu(2, 0.995) + _feature(0, 1.0),
     r"ok\.csv:14: imu stamps must increase with seq: seq 2 at 0\.995 s follows seq 1 at 1\.0 s \(line 13\)"),
    (_imu(1, 1.0) + _imu(2, 1.005) + _feature(0, 1.0) + _feature(1, 0.95),
     r"ok\.csv:16: frame stamps must increase with frame_idx: frame 1 at 0\.95 s follows frame 0 at 1\.0 s"),
    (_imu(1, 1.0) + _imu(2, 1.005) + _feature(0, 1.0) + _feature(0, 1.05),
     r"ok\.csv:16: frame 0 at t_abs 1\.05 s, but line 15 has it at 1\.0 s"),
])
def test_impossible_values_name_file_and_line(tmp_path, body, expected):
    p = tmp_path / "ok.csv"
    p.write_text(HEAD + META + body)
    with pytest.raises(DataError, match=expected):
        read_eqvio_csv(p)


@pytest.mark.parametrize("column", ["gy", "ay", "az", "v_norm"])
def test_a_missing_column_is_named(tmp_path, column):
    names = HEAD.strip().split(",")
    k = names.index(column)
    drop = lambda line: ",".join(c for j, c in enumerate(line.rstrip("\n").split(",")) if j != k) + "\n"  # noqa: E731
    p = tmp_path / "cut.csv"
    p.write_text("".join(drop(line) for line in (HEAD + META + _imu(1, 1.0) + _feature(0, 1.0)).splitlines(True)))
    with pytest.raises(DataError, match=rf"cut\.csv:1: the header lacks columns \['{column}'\]"):
        read_eqvio_csv(p)


def test_non_utf8_bytes_name_the_line(tmp_path):
    p = tmp_path / "latin.csv"
    p.write_bytes((HEAD + META).encode() + b"meta,,,,,,,,,,,,,,,,,,,,note,caf\xe9\n" + _imu(1, 1.0).encode())
    with pytest.raises(DataError, match=r"latin\.csv:13: not a text file"):
        read_eqvio_csv(p)


def test_an_id_beyond_an_integer_names_the_line(tmp_path):
    """A landmark id of 1e20: before, an OverflowError building the id array (found by the fuzzer)."""
    p = tmp_path / "ok.csv"
    p.write_text(HEAD + META + _imu(1, 1.0) + _feature(0, 1.0).replace(",7,", ",1e20,"))
    with pytest.raises(DataError, match=r"ok\.csv:14: column 'landmark_id' is not an integer in \[0, 2\^53\)"):
        read_eqvio_csv(p)
