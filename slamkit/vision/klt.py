"""Pyramidal Lucas-Kanade feature tracking (KLT).

Lucas & Kanade, "An iterative image registration technique", IJCAI 1981; the pyramidal scheme of
J.-Y. Bouguet, "Pyramidal implementation of the Lucas Kanade feature tracker" (Intel, 2000), which
OpenCV's calcOpticalFlowPyrLK implements. For each point and pyramid level (coarsest first) the
displacement d minimising sum_w (I(x) - J(x + g + d))^2 over a window w is found by Gauss-Newton:

    G = sum_w [Ix^2, IxIy; IxIy, Iy^2],   b = sum_w (I(x) - J(x + g + d)) [Ix, Iy],   d += G^-1 b

with g the guess propagated from the coarser level (g_{L-1} = 2 (g_L + d_L)). Gradients are those
of the first image (Scharr 3x3, as OpenCV), sampled bilinearly. All points are iterated at
once (vectorised); windows overhanging the border repeat the edge pixels. A point is lost when
G's smaller eigenvalue per window pixel is below ``min_eigenvalue`` or it leaves the image.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from slamkit.errors import ConfigError
from slamkit.vision.image import bilinear, pyramid

__all__ = ["KltConfig", "track_klt"]


@dataclass(frozen=True)
class KltConfig:
    window: int = 21          #: window side in pixels (odd)
    levels: int = 3           #: pyramid levels above the image
    iterations: int = 30
    epsilon_px: float = 0.01  #: stop a point when its update is smaller
    #: smaller eigenvalue of G per window pixel, images scaled to 0..1: 1.5748e-6 is OpenCV's
    #: default minEigThreshold 1e-4 (its fixed-point gradients are 32 x 255 / 1024 times ours)
    min_eigenvalue: float = 1e-4 * 1024.0 / 255.0**2

    def __post_init__(self) -> None:
        if self.window < 3 or self.window % 2 == 0:
            raise ConfigError(f"KltConfig.window must be odd and >= 3, got {self.window}")
        if self.levels < 0 or self.iterations < 1:
            raise ConfigError("KltConfig.levels must be >= 0 and iterations >= 1")


def _scharr(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d, s = np.array([-1.0, 0.0, 1.0]), np.array([3.0, 10.0, 3.0]) / 32.0
    gx = ndimage.correlate1d(ndimage.correlate1d(image, d, axis=1, mode="mirror"), s, axis=0, mode="mirror")
    gy = ndimage.correlate1d(ndimage.correlate1d(image, d, axis=0, mode="mirror"), s, axis=1, mode="mirror")
    return gx, gy


def track_klt(image0, image1, points_uv, config: KltConfig = KltConfig(), guess_uv=None
              ) -> tuple[np.ndarray, np.ndarray]:
    """Track (N, 2) pixel positions of ``image0`` into ``image1``: ((N, 2) positions, (N,) bool
    status). ``guess_uv`` (N, 2) starts the search elsewhere than at the same pixel."""
    p0 = np.asarray(points_uv, dtype=float).reshape(-1, 2)
    n = len(p0)
    if n == 0:
        return np.empty((0, 2)), np.empty(0, dtype=bool)
    scale = 1.0 / 255.0 if np.max(image0) > 1.5 else 1.0
    pyr0 = pyramid(np.asarray(image0, float) * scale, config.levels)
    pyr1 = pyramid(np.asarray(image1, float) * scale, config.levels)
    r = config.window // 2
    oy, ox = np.mgrid[-r:r + 1, -r:r + 1].astype(float)
    ox, oy = ox.ravel(), oy.ravel()
    npix = ox.size
    top = 2.0 ** config.levels
    g = np.zeros((n, 2)) if guess_uv is None else (np.asarray(guess_uv, float).reshape(-1, 2) - p0) / top
    ok = np.ones(n, dtype=bool)
    d = np.zeros((n, 2))
    for level in range(config.levels, -1, -1):
        I, J = pyr0[level], pyr1[level]
        H, W = I.shape
        s = 2.0 ** level
        x = p0 / s
        gx, gy = _scharr(I)
        U = x[:, 0:1] + ox
        V = x[:, 1:2] + oy
        tmpl = bilinear(I, U, V, fill=None)
        Ix, Iy = bilinear(gx, U, V, fill=None), bilinear(gy, U, V, fill=None)
        gxx, gxy, gyy = (Ix * Ix).sum(1), (Ix * Iy).sum(1), (Iy * Iy).sum(1)
        det = gxx * gyy - gxy * gxy
        min_eig = 0.5 * (gxx + gyy - np.sqrt((gxx - gyy) ** 2 + 4 * gxy * gxy)) / npix
        ok &= min_eig >= config.min_eigenvalue
        safe = np.where(np.abs(det) > 1e-18, det, 1.0)
        d = np.zeros((n, 2))
        active = ok.copy()
        for _ in range(config.iterations):
            if not active.any():
                break
            idx = np.flatnonzero(active)
            pos = x[idx] + g[idx] + d[idx]
            warped = bilinear(J, pos[:, 0:1] + ox, pos[:, 1:2] + oy, fill=None)
            err = tmpl[idx] - warped
            # a window may overhang the border (edge pixels repeat); its centre may not
            inside = (pos[:, 0] >= -r) & (pos[:, 0] <= W - 1 + r) & (pos[:, 1] >= -r) & (pos[:, 1] <= H - 1 + r)
            bx, by = (Ix[idx] * err).sum(1), (Iy[idx] * err).sum(1)
            step = np.stack([(gyy[idx] * bx - gxy[idx] * by) / safe[idx],
                             (gxx[idx] * by - gxy[idx] * bx) / safe[idx]], axis=1)
            d[idx] += step
            lost = ~inside
            ok[idx[lost]] = False
            done = np.hypot(step[:, 0], step[:, 1]) < config.epsilon_px
            active[idx[done | lost]] = False
        if level > 0:
            g = 2.0 * (g + d)
    p1 = (g + d)[:, :] + p0
    Hf, Wf = pyr0[0].shape
    ok &= np.isfinite(p1).all(1) & (p1[:, 0] >= 0) & (p1[:, 0] <= Wf - 1) & (p1[:, 1] >= 0) & (p1[:, 1] <= Hf - 1)
    return p1, ok
