"""Image basics in numpy/scipy: Gaussian smoothing, Sobel gradients, Canny edges, Harris and
Shi-Tomasi corners, image pyramids and whole-image undistortion by remapping.

Images are (H, W) float arrays (grey levels, any range); pixel (u, v) = (column, row). Borders
are reflected without repeating the edge pixel (OpenCV's default ``BORDER_REFLECT_101``, scipy's
``mode="mirror"``), so every function here agrees with its OpenCV counterpart away from rounding
(the agreement is stated in ``tests/vision/test_image.py``).

* Gaussian: separable kernel exp(-x^2 / (2 sigma^2)) normalised to sum 1, default size
  2 ceil(3 sigma) + 1 (pass ``size`` to match a given OpenCV ksize).
* Sobel: the 3x3 operator [-1 0 1] (derivative) x [1 2 1] (smoothing), Sobel & Feldman 1968.
* Canny, "A computational approach to edge detection", IEEE PAMI 8(6), 1986: Sobel gradient
  (L2 magnitude), non-maximum suppression along the gradient direction quantised to four
  sectors (0, 45, 90, 135 deg, boundaries at 22.5 deg, as OpenCV), hysteresis: pixels above
  ``high`` are edges, pixels above ``low`` are edges when 8-connected to one.
* Harris & Stephens, "A combined corner and edge detector", Alvey 1988: structure tensor
  M = sum_w [Ix^2, IxIy; IxIy, Iy^2] over a box window, response det M - k tr(M)^2.
  Shi & Tomasi, "Good features to track", CVPR 1994: the smaller eigenvalue of M.
  ``good_features_to_track`` = threshold at ``quality`` x max, 3x3 non-maximum suppression,
  strongest first with a minimum distance (OpenCV's goodFeaturesToTrack).
* Pyramid: 5-tap binomial [1 4 6 4 1] / 16 smoothing then keeping every second pixel (Burt &
  Adelson 1983; OpenCV pyrDown).
* Undistortion by remapping: every pixel of the undistorted image is mapped through the camera
  model (normalise with K_new, distort, project with K) and the source image is sampled there
  bilinearly (OpenCV initUndistortRectifyMap + remap).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from slamkit.errors import ConfigError
from slamkit.models.camera import PinholeCamera

__all__ = [
    "gaussian_kernel", "gaussian_blur", "sobel", "canny", "structure_tensor", "harris_response",
    "min_eigenvalue", "good_features_to_track", "pyr_down", "pyramid", "bilinear",
    "undistort_image", "undistortion_map",
]

_BORDER = "mirror"  # OpenCV BORDER_REFLECT_101


def _as_image(image) -> np.ndarray:
    a = np.asarray(image, dtype=float)
    if a.ndim != 2:
        raise ConfigError(f"an image is a (H, W) array, got shape {a.shape}")
    return a


def gaussian_kernel(sigma: float, size: int | None = None) -> np.ndarray:
    """1D Gaussian of standard deviation ``sigma`` (pixels), odd ``size``, normalised to sum 1."""
    if not sigma > 0:
        raise ConfigError(f"gaussian sigma must be positive, got {sigma}")
    if size is None:
        size = 2 * int(np.ceil(3.0 * sigma)) + 1
    if size < 1 or size % 2 == 0:
        raise ConfigError(f"gaussian kernel size must be odd and positive, got {size}")
    x = np.arange(size) - (size - 1) / 2.0
    k = np.exp(-x * x / (2.0 * sigma * sigma))
    return k / k.sum()


def gaussian_blur(image, sigma: float, size: int | None = None) -> np.ndarray:
    """Separable Gaussian smoothing (cv2.GaussianBlur with ksize=(size, size), sigmaX=sigma)."""
    k = gaussian_kernel(sigma, size)
    out = ndimage.correlate1d(_as_image(image), k, axis=0, mode=_BORDER)
    return ndimage.correlate1d(out, k, axis=1, mode=_BORDER)


def sobel(image) -> tuple[np.ndarray, np.ndarray]:
    """(d/du, d/dv): the 3x3 Sobel derivatives along columns (x) and rows (y) (cv2.Sobel ksize=3)."""
    a = _as_image(image)
    d, s = np.array([-1.0, 0.0, 1.0]), np.array([1.0, 2.0, 1.0])
    gx = ndimage.correlate1d(ndimage.correlate1d(a, d, axis=1, mode=_BORDER), s, axis=0, mode=_BORDER)
    gy = ndimage.correlate1d(ndimage.correlate1d(a, d, axis=0, mode=_BORDER), s, axis=1, mode=_BORDER)
    return gx, gy


def _non_maximum_suppression(mag: np.ndarray, gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """Keep pixels whose magnitude is a maximum along the quantised gradient direction (a pixel
    must be > its predecessor and >= its successor, as OpenCV, so plateaus keep one pixel)."""
    H, W = mag.shape
    pad = np.pad(mag, 1)
    c = pad[1:-1, 1:-1]

    def at(dv, du):
        return pad[1 + dv:1 + dv + H, 1 + du:1 + du + W]

    ax, ay = np.abs(gx), np.abs(gy)
    tan22 = np.tan(np.deg2rad(22.5))
    horizontal = ay <= tan22 * ax            # gradient along u: compare left/right
    vertical = ax <= tan22 * ay              # gradient along v: compare up/down
    diagonal = ~(horizontal | vertical)
    same_sign = (gx * gy) > 0                # gradient along (+u, +v): compare the main diagonal
    keep = np.zeros_like(mag, dtype=bool)
    keep |= horizontal & (c > at(0, -1)) & (c >= at(0, 1))
    keep |= vertical & (c > at(-1, 0)) & (c >= at(1, 0))
    keep |= diagonal & same_sign & (c > at(-1, -1)) & (c >= at(1, 1))
    keep |= diagonal & ~same_sign & (c > at(-1, 1)) & (c >= at(1, -1))
    return keep


def canny(image, low: float, high: float) -> np.ndarray:
    """(H, W) bool edge map: Sobel gradient (L2 magnitude), non-maximum suppression, hysteresis
    with thresholds ``low`` < ``high`` on the gradient magnitude (cv2.Canny(..., L2gradient=True);
    smooth the image first if it is noisy, as cv2.Canny also does not)."""
    if not 0 <= low <= high:
        raise ConfigError(f"canny thresholds need 0 <= low <= high, got low={low}, high={high}")
    gx, gy = sobel(image)
    mag = np.hypot(gx, gy)
    candidates = _non_maximum_suppression(mag, gx, gy) & (mag > low)
    candidates[[0, -1], :] = False
    candidates[:, [0, -1]] = False
    strong = candidates & (mag > high)
    labels, n = ndimage.label(candidates, structure=np.ones((3, 3), dtype=bool))
    if n == 0:
        return candidates
    has_strong = np.zeros(n + 1, dtype=bool)
    has_strong[np.unique(labels[strong])] = True
    has_strong[0] = False
    return has_strong[labels]


def structure_tensor(image, block_size: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Sxx, Sxy, Syy): box sums over ``block_size`` x ``block_size`` of the Sobel products,
    scaled as OpenCV's cornerEigenValsVecs (gradients divided by 4 block_size for ksize 3)."""
    gx, gy = sobel(image)
    scale = 1.0 / (4.0 * block_size)
    gx, gy = gx * scale, gy * scale
    box = np.ones(block_size)

    def boxsum(a):  # centred at index size // 2, as OpenCV's default anchor
        a = ndimage.correlate1d(a, box, axis=0, mode=_BORDER)
        return ndimage.correlate1d(a, box, axis=1, mode=_BORDER)

    return boxsum(gx * gx), boxsum(gx * gy), boxsum(gy * gy)


def harris_response(image, block_size: int = 3, k: float = 0.04) -> np.ndarray:
    """det M - k tr(M)^2 per pixel (cv2.cornerHarris(image, block_size, 3, k))."""
    sxx, sxy, syy = structure_tensor(image, block_size)
    return sxx * syy - sxy * sxy - k * (sxx + syy) ** 2


def min_eigenvalue(image, block_size: int = 3) -> np.ndarray:
    """The smaller eigenvalue of M per pixel (cv2.cornerMinEigenVal(image, block_size, 3))."""
    sxx, sxy, syy = structure_tensor(image, block_size)
    a, c = 0.5 * sxx, 0.5 * syy
    return (a + c) - np.sqrt((a - c) ** 2 + sxy * sxy)


def good_features_to_track(image, max_corners: int, quality: float = 0.01, min_distance: float = 10.0,
                           block_size: int = 3, use_harris: bool = False, k: float = 0.04,
                           mask: np.ndarray | None = None) -> np.ndarray:
    """(N, 2) corners (u, v), strongest first: Shi-Tomasi (or Harris) response above
    ``quality`` x its maximum, local maxima of a 3x3 window, greedily kept at least
    ``min_distance`` pixels apart, at most ``max_corners`` (cv2.goodFeaturesToTrack)."""
    r = harris_response(image, block_size, k) if use_harris else min_eigenvalue(image, block_size)
    if mask is not None:
        r = np.where(np.asarray(mask, dtype=bool), r, 0.0)
    peak = r.max()
    if not peak > 0:
        return np.empty((0, 2))
    local_max = r == ndimage.maximum_filter(r, size=3, mode="constant", cval=-np.inf)
    cand = local_max & (r > quality * peak)
    v, u = np.nonzero(cand)
    order = np.argsort(-r[v, u], kind="stable")
    u, v = u[order].astype(float), v[order].astype(float)
    if min_distance <= 0:
        return np.stack([u, v], axis=1)[:max_corners]
    # greedy minimum distance on a grid of cells min_distance wide (each point checks 3x3 cells)
    cell = float(min_distance)
    grid: dict[tuple[int, int], list[int]] = {}
    kept: list[int] = []
    d2 = min_distance * min_distance
    for i in range(len(u)):
        cu, cv = int(u[i] // cell), int(v[i] // cell)
        ok = True
        for du in (-1, 0, 1):
            for dv in (-1, 0, 1):
                for j in grid.get((cu + du, cv + dv), ()):
                    if (u[j] - u[i]) ** 2 + (v[j] - v[i]) ** 2 < d2:
                        ok = False
                        break
                if not ok:
                    break
            if not ok:
                break
        if ok:
            kept.append(i)
            grid.setdefault((cu, cv), []).append(i)
            if len(kept) >= max_corners:
                break
    return np.stack([u[kept], v[kept]], axis=1)


_BINOMIAL5 = np.array([1.0, 4.0, 6.0, 4.0, 1.0]) / 16.0


def pyr_down(image) -> np.ndarray:
    """Binomial 5x5 smoothing then every second pixel: size ((H + 1) // 2, (W + 1) // 2)."""
    a = ndimage.correlate1d(_as_image(image), _BINOMIAL5, axis=0, mode=_BORDER)
    a = ndimage.correlate1d(a, _BINOMIAL5, axis=1, mode=_BORDER)
    return a[::2, ::2]


def pyramid(image, levels: int) -> list[np.ndarray]:
    """[image, pyr_down(image), ...]: ``levels`` + 1 images, finest first."""
    out = [_as_image(image)]
    for _ in range(levels):
        out.append(pyr_down(out[-1]))
    return out


def bilinear(image, u, v, fill: float | None = 0.0) -> np.ndarray:
    """Image sampled at real pixel positions (u, v) (any equal shapes) by bilinear
    interpolation; ``fill`` outside the image (None: the nearest edge pixel)."""
    a = _as_image(image)
    H, W = a.shape
    if H < 2 or W < 2:
        raise ConfigError(f"bilinear sampling needs an image of at least 2 x 2 pixels, got {W} x {H}")
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    uc, vc = np.clip(np.nan_to_num(u), 0, W - 1), np.clip(np.nan_to_num(v), 0, H - 1)
    u0 = np.minimum(np.floor(uc), W - 2)
    v0 = np.minimum(np.floor(vc), H - 2)
    du, dv = uc - u0, vc - v0
    i = v0.astype(np.intp) * W + u0.astype(np.intp)
    flat = a.ravel()
    top = flat[i] * (1.0 - du) + flat[i + 1] * du
    bottom = flat[i + W] * (1.0 - du) + flat[i + W + 1] * du
    out = top * (1.0 - dv) + bottom * dv
    if fill is not None:
        out = np.where((u < 0) | (u > W - 1) | (v < 0) | (v > H - 1) | ~np.isfinite(u) | ~np.isfinite(v), fill, out)
    return out


def undistortion_map(camera: PinholeCamera, new_K=None, shape: tuple[int, int] | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(map_u, map_v): for every pixel of the undistorted image (intrinsics ``new_K``, default
    the camera's K) the position in the distorted source image."""
    H, W = shape if shape is not None else (camera.height, camera.width)
    Kn = camera.K if new_K is None else np.asarray(new_K, dtype=float)
    vv, uu = np.mgrid[0:H, 0:W].astype(float)
    xy = np.stack([(uu - Kn[0, 2]) / Kn[0, 0], (vv - Kn[1, 2]) / Kn[1, 1]], axis=-1)
    uv = camera.normalized_to_pixel(camera.distort(xy))
    return uv[..., 0], uv[..., 1]


def undistort_image(image, camera: PinholeCamera, new_K=None, fill: float = 0.0) -> np.ndarray:
    """The image as an ideal pinhole camera (``new_K``, default K) would see it (cv2.undistort)."""
    a = _as_image(image)
    map_u, map_v = undistortion_map(camera, new_K, a.shape)
    return bilinear(a, map_u, map_v, fill)
