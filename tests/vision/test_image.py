"""slamkit.vision image basics against OpenCV on real KITTI frames (cv2 is the reference here, as
a test dependency only). The agreements are stated as numbers:

* Gaussian (9x9, sigma 1.5): max |difference| < 1e-3 grey levels (float32 rounding in OpenCV);
* Sobel 3x3: identical (max |difference| 0);
* Canny (50/150, L2 gradient): >= 99.9 % of pixels identical, >= 99.5 % of OpenCV's edge pixels
  found (measured 99.96 % and 99.7 %);
* Harris and Shi-Tomasi responses: max relative difference < 1e-5 (block 2, 3, 4);
* goodFeaturesToTrack (500, 0.01, 10 px): >= 97 % of OpenCV's corners at the same pixel (98.4 %);
* pyramidal LK (21 px window, 3 levels) on two consecutive frames: >= 95 % of the points OpenCV
  tracks are tracked, median difference < 0.01 px, >= 97 % within 0.5 px (measured 449 / 468,
  7e-5 px, 98.7 %);
* undistortion by remapping (EuRoC cam0 lens on a KITTI frame): median |difference| < 0.5 grey
  levels, 99th percentile < 3 (OpenCV's remap quantises positions to 1/32 pixel).
"""

from __future__ import annotations

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")

from slamkit.data.formats.image import read_image  # noqa: E402
from slamkit.models.camera import PinholeCamera  # noqa: E402
from slamkit.vision import image as im  # noqa: E402
from slamkit.vision.klt import KltConfig, track_klt  # noqa: E402


@pytest.fixture(scope="module")
def frames(shared_datasets):
    folder = shared_datasets / "vision" / "kitti_vo_a" / "image_l"
    return read_image(folder / "000000.png"), read_image(folder / "000001.png")


def test_gaussian_and_sobel_match_opencv(frames):
    a = frames[0]
    af = a.astype(np.float32)
    assert np.abs(im.gaussian_blur(a, 1.5, 9) - cv2.GaussianBlur(af, (9, 9), 1.5)).max() < 1e-3
    gx, gy = im.sobel(a)
    assert np.array_equal(gx, cv2.Sobel(af, cv2.CV_32F, 1, 0, ksize=3))
    assert np.array_equal(gy, cv2.Sobel(af, cv2.CV_32F, 0, 1, ksize=3))
    assert im.gaussian_kernel(1.0).sum() == pytest.approx(1.0) and len(im.gaussian_kernel(1.0)) == 7


def test_canny_matches_opencv(frames):
    a = frames[0]
    mine = im.canny(a, 50, 150)
    ref = cv2.Canny(a.astype(np.uint8), 50, 150, L2gradient=True) > 0
    assert (mine == ref).mean() >= 0.999
    assert (mine & ref).sum() / ref.sum() >= 0.995
    assert ref.sum() > 10_000  # a real test: tens of thousands of edge pixels


def test_canny_worked_example_step_edge():
    """A vertical step 0 -> 100: Sobel magnitude 400 on the two columns beside the step; NMS
    keeps one (the first strictly greater than its left neighbour), hysteresis keeps the line."""
    img = np.zeros((20, 20))
    img[:, 10:] = 100.0
    edges = im.canny(img, 100, 300)
    cols = np.flatnonzero(edges.any(axis=0))
    assert cols.tolist() == [9]
    assert edges[1:-1, 9].all()


@pytest.mark.parametrize("block", [2, 3, 4])
def test_harris_and_min_eigenvalue_match_opencv(frames, block):
    af = frames[0].astype(np.float32)
    h = im.harris_response(frames[0], block, 0.04)
    hc = cv2.cornerHarris(af, block, 3, 0.04)
    assert np.abs(h - hc).max() / np.abs(hc).max() < 1e-5
    m = im.min_eigenvalue(frames[0], block)
    mc = cv2.cornerMinEigenVal(af, block, 3)
    assert np.abs(m - mc).max() / np.abs(mc).max() < 1e-5


def test_good_features_to_track_matches_opencv(frames):
    mine = im.good_features_to_track(frames[0], 500, 0.01, 10)
    ref = cv2.goodFeaturesToTrack(frames[0].astype(np.float32), 500, 0.01, 10).reshape(-1, 2)
    d = np.linalg.norm(mine[None, :, :] - ref[:, None, :], axis=2).min(axis=1)
    assert len(mine) == len(ref) == 500
    assert (d < 0.5).mean() >= 0.97
    gaps = np.linalg.norm(mine[None] - mine[:, None], axis=2) + np.eye(len(mine)) * 1e9
    assert gaps.min() >= 10.0


def test_pyramidal_lk_matches_opencv(frames):
    a, b = frames
    pts = cv2.goodFeaturesToTrack(a.astype(np.float32), 500, 0.01, 10).reshape(-1, 2)
    mine, ok = track_klt(a, b, pts, KltConfig(window=21, levels=3))
    ref, st, _ = cv2.calcOpticalFlowPyrLK(a.astype(np.uint8), b.astype(np.uint8), pts.astype(np.float32), None,
                                          winSize=(21, 21), maxLevel=3)
    st = st.ravel() > 0
    both = ok & st
    assert both.sum() >= 0.95 * st.sum()
    diff = np.linalg.norm(mine[both] - ref[both], axis=1)
    assert np.median(diff) < 0.01
    assert (diff < 0.5).mean() >= 0.97


def test_lk_recovers_a_known_subpixel_shift():
    """A texture of Gaussian blobs drawn exactly shifted by (3.4, -1.7) px: the tracker finds the
    shift to 0.03 px (bilinear interpolation of the window limits it)."""
    rng = np.random.default_rng(0)
    centres, weights = rng.uniform(0, 120, (80, 2)), rng.uniform(50, 150, 80)

    def texture(du, dv):
        v, u = np.mgrid[0:100, 0:120].astype(float)
        d2 = (u[..., None] - du - centres[:, 0]) ** 2 + (v[..., None] - dv - centres[:, 1]) ** 2
        return (weights * np.exp(-d2 / (2 * 4.0**2))).sum(-1)

    a, b = texture(0.0, 0.0), texture(3.4, -1.7)
    pts = np.array([[40.0, 40.0], [60.0, 50.0], [80.0, 60.0]])
    p1, ok = track_klt(a, b, pts, KltConfig(window=15, levels=2, epsilon_px=1e-3))
    assert ok.all()
    np.testing.assert_allclose(p1 - pts, np.tile([3.4, -1.7], (3, 1)), atol=0.03)


def test_undistortion_by_remapping_matches_opencv(frames):
    a = frames[0]
    H, W = a.shape
    cam = PinholeCamera(700.0, 700.0, W / 2, H / 2, k1=-0.28, k2=0.074, p1=2e-4, p2=2e-5, width=W, height=H)
    mine = im.undistort_image(a, cam)
    ref = cv2.undistort(a.astype(np.float32), cam.K, np.array([cam.k1, cam.k2, cam.p1, cam.p2, cam.k3]))
    inner = np.zeros_like(a, dtype=bool)
    inner[5:-5, 5:-5] = True
    inner &= (ref > 0) & (mine > 0)
    diff = np.abs(mine - ref)[inner]
    assert inner.mean() > 0.8
    assert np.median(diff) < 0.5 and np.percentile(diff, 99) < 3.0
    # and the map sends undistorted pixels to where the camera model projects them
    mu, mv = im.undistortion_map(cam, shape=(H, W))
    ray = cam.unproject(np.stack([mu[100, 200], mv[100, 200]]))
    np.testing.assert_allclose(cam.K[:2, :2] @ ray[:2] + cam.K[:2, 2], [200, 100], atol=1e-6)
