"""Pinhole camera with radial-tangential distortion, and rectified stereo depth."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import ConfigError
from slamkit.models.camera import PinholeCamera
from slamkit.models.stereo import StereoCamera, depth_from_disparity, depth_sigma

EUROC = PinholeCamera.euroc_cam0()


def test_pinhole_worked_example():
    cam = PinholeCamera(500.0, 500.0, 320.0, 240.0)
    np.testing.assert_allclose(cam.project([1.0, 0.5, 5.0]), [420.0, 290.0], atol=1e-12)
    np.testing.assert_allclose(cam.unproject([420.0, 290.0], 5.0), [1.0, 0.5, 5.0], atol=1e-12)
    np.testing.assert_allclose(cam.K, [[500, 0, 320], [0, 500, 240], [0, 0, 1]])
    assert np.all(np.isnan(cam.project([1.0, 0.5, -5.0])))  # behind the camera


def test_distortion_worked_example():
    cam = PinholeCamera(1, 1, 0, 0, k1=0.1, k2=0.01, k3=0.001, p1=0.001, p2=0.002)
    # r^2 = 0.05, radial = 1 + 0.005 + 0.000025 + 0.000000125 = 1.005025125
    # x_d = 0.1 radial + 2 p1 x y + p2 (r^2 + 2 x^2) = 0.1005025125 + 0.00004 + 0.00014
    # y_d = 0.2 radial + p1 (r^2 + 2 y^2) + 2 p2 x y = 0.201005025 + 0.00013 + 0.00008
    np.testing.assert_allclose(cam.distort([0.1, 0.2]), [0.1006825125, 0.201215025], atol=1e-15)
    np.testing.assert_allclose(cam.undistort([0.1006825125, 0.201215025]), [0.1, 0.2], atol=1e-14)


def test_from_K_uses_opencv_coefficient_order():
    cam = PinholeCamera.from_K(EUROC.K, (EUROC.k1, EUROC.k2, EUROC.p1, EUROC.p2, EUROC.k3), 752, 480)
    assert cam == EUROC
    with pytest.raises(ConfigError):
        PinholeCamera(0.0, 1.0, 0.0, 0.0)


@settings(max_examples=300, deadline=None)
@given(st.floats(0.0, 751.99), st.floats(0.0, 479.99), st.floats(0.2, 50.0))
def test_euroc_round_trip_over_the_whole_image(u, v, depth):
    """Every pixel of the EuRoC cam0 image unprojects and reprojects to itself (1e-6 px)."""
    p = EUROC.unproject([u, v], depth)
    assert p[2] == pytest.approx(depth)
    np.testing.assert_allclose(EUROC.project(p), [u, v], atol=1e-6)


@settings(max_examples=300, deadline=None)
@given(st.floats(-0.8, 0.8), st.floats(-0.55, 0.55))
def test_undistort_inverts_distort(x, y):
    np.testing.assert_allclose(EUROC.undistort(EUROC.distort([x, y])), [x, y], atol=1e-10)


def test_batch_round_trip_and_in_image():
    uv = np.stack(np.meshgrid(np.arange(0, 752, 47.0), np.arange(0, 480, 40.0)), -1).reshape(-1, 2)
    back = EUROC.project(EUROC.unproject(uv, np.full(len(uv), 3.0)))
    assert np.max(np.abs(back - uv)) < 1e-6
    assert EUROC.in_image(uv).all() and not EUROC.in_image([752.0, 10.0])


def test_stereo_worked_example():
    # f = 700 px, b = 0.12 m: a 42 px disparity is 2 m away
    assert depth_from_disparity(42.0, 700.0, 0.12) == pytest.approx(2.0)
    # sigma_Z = Z^2 sigma_d / (f b): 0.5 px gives 2.38 cm at 2 m and 2.38 m at 20 m
    assert depth_sigma(2.0, 700.0, 0.12, 0.5) == pytest.approx(4 * 0.5 / 84.0)
    assert depth_sigma(20.0, 700.0, 0.12, 0.5) == pytest.approx(2.380952381, rel=1e-9)
    assert np.isnan(depth_from_disparity(0.0, 700.0, 0.12))


def test_stereo_round_trip_and_monte_carlo_depth_sigma():
    st_cam = StereoCamera(700.0, 700.0, 320.0, 240.0, 0.12, sigma_disparity_px=0.5)
    p = np.array([[0.3, -0.2, 2.0], [-1.0, 0.5, 7.5]])
    np.testing.assert_allclose(st_cam.triangulate(st_cam.project(p)), p, atol=1e-12)
    rng = np.random.default_rng(11)
    z = st_cam.measure(rng, np.tile([0.0, 0.0, 2.0], (100000, 1)), sigma_pixel_px=0.0)
    depths = st_cam.triangulate(z)[:, 2]
    # first-order sigma 0.0238 m; the SE of the std estimate at n = 1e5 is 0.2 %, the
    # second-order term (3 (sigma_d/d)^2 = 4e-4 relative) is far below the 2 % tolerance
    assert depths.std() == pytest.approx(st_cam.depth_sigma(2.0), rel=0.02)
    cov = st_cam.point_covariance(st_cam.project(p[0]), sigma_pixel_px=0.0)
    assert np.sqrt(cov[2, 2]) == pytest.approx(st_cam.depth_sigma(2.0), rel=1e-12)


@settings(max_examples=150, deadline=None)
@given(st.floats(-0.7, 0.7), st.floats(-0.5, 0.5), st.floats(0.3, 30.0))
def test_project_jacobian_matches_finite_differences_over_the_view(x, y, depth):
    p = np.array([x * depth, y * depth, depth])
    J = EUROC.project_jacobian(p)
    h = 1e-6 * max(1.0, depth)
    num = np.stack([(EUROC.project(p + e) - EUROC.project(p - e)) / (2 * h) for e in np.eye(3) * h], axis=-1)
    np.testing.assert_allclose(J, num, rtol=1e-5, atol=1e-4)
