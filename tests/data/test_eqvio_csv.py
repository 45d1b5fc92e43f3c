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
