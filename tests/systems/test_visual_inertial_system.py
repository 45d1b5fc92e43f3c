"""Visual-inertial odometry on real EuRoC V1_01 (the gtsam wheel's 30 s of IMU and tracked
features), scored against the EuRoC ground truth beside OpenVINS on the same stamps."""

import numpy as np
import pytest

from slamkit.errors import ConfigError, EstimationError
from slamkit.systems.visual_inertial import VioConfig, VisualInertialOdometry

from peer_comparison import load_euroc_v101, vio_euroc_v101


def test_static_initialisation_gravity_and_gyro_bias():
    data = load_euroc_v101()
    vio = VisualInertialOdometry(data.imu_T_camera)
    i = 0
    results = []
    for t, (ids, xy) in zip(data.frame_stamps_s[:30], data.frame_features[:30]):
        while data.imu_stamps_s[i] <= t + 1e-9:
            vio.step_imu(data.imu_stamps_s[i], data.accel_mps2[i], data.gyro_radps[i])
            i += 1
        results.append(vio.step_frame(t, ids, xy))
    # 1 s of IMU before the first state: frames 0..19 wait, frame 20 is state 0
    assert [r.index for r in results[:21]] == [-1] * 20 + [0]
    est = vio.estimate()
    # gravity along world -z: the mean specific force of the window maps to +z
    R0 = est.world_T_body[0, :3, :3]
    f = data.accel_mps2[:201].mean(axis=0)
    assert np.allclose(R0 @ f / np.linalg.norm(f), [0, 0, 1], atol=1e-3)
    # the platform is at rest: every frame after state 0 is stationary, the pose stays put
    assert all(r.stationary for r in results[21:])
    assert np.abs(est.world_T_body[:, :3, 3]).max() < 5e-3
    # gyro bias: the mean rate at rest (EuRoC V1_01's is about (-0.002, 0.021, 0.077) rad/s)
    assert np.allclose(est.bias[-1, 3:], [-0.0013, 0.0201, 0.0789], atol=2e-3)


def test_bad_input():
    data = load_euroc_v101()
    vio = VisualInertialOdometry(data.imu_T_camera)
    with pytest.raises(EstimationError, match="not initialised"):
        vio.estimate()
    with pytest.raises(EstimationError, match="not finite"):
        vio.step_imu(0.0, [0, 0, np.nan], [0, 0, 0])
    with pytest.raises(EstimationError, match="pair up"):
        vio.step_frame(0.0, [1, 2], np.zeros((3, 2)))
    with pytest.raises(ConfigError):
        VioConfig(static_init_s=0.0)


def test_first_ten_seconds_beside_openvins():
    """10 s of the file: OpenVINS starts at 5.6 s, so 4.4 s (89 poses, ~1.5 m flown) are scored.
    Measured: VIO SE(3) ATE 0.0052 m, OpenVINS 0.0127 m."""
    report = vio_euroc_v101(until_s=10.0)
    assert report.num_poses == 89
    vio, ov = report.metrics["vio"], report.metrics["openvins"]
    assert ov["ate_rmse_m"] == pytest.approx(0.0127, abs=5e-4)   # OpenVINS' own number on this window
    assert vio["ate_rmse_m"] < 0.01
    assert vio["ate_rmse_m"] <= 2.0 * ov["ate_rmse_m"]
    assert report.estimate.stationary_frames == 78


@pytest.mark.slow
def test_thirty_seconds_within_twice_openvins():
    """The issue's goal on the whole file: VIO SE(3) ATE within 2x of OpenVINS' on the same stamps."""
    report = vio_euroc_v101()
    vio, ov = report.metrics["vio"], report.metrics["openvins"]
    assert report.num_poses >= 480
    assert ov["ate_rmse_m"] == pytest.approx(0.0127, abs=5e-4)
    assert vio["ate_rmse_m"] <= 2.0 * ov["ate_rmse_m"]
    assert vio["ate_rmse_m"] < 0.025
