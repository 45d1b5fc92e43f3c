"""Rectified stereo pair: depth from disparity and its uncertainty.

For a rectified pair with focal length f (pixels) and baseline b (metres) a point at depth Z
appears with disparity d = u_left - u_right = f b / Z, so (Szeliski, *Computer Vision:
Algorithms and Applications*, 1st ed., sec. 11.1):

    Z = f b / d,     X = (u - c_x) Z / f_x,     Y = (v - c_y) Z / f_y

First-order error propagation gives the depth uncertainty

    sigma_Z = |dZ/dd| sigma_d = Z^2 / (f b) sigma_d

which grows with the square of the depth. ``triangulate_jacobian`` gives the full 3x3
d(X, Y, Z)/d(u, v, d) so a point covariance is J diag(sigma_u^2, sigma_v^2, sigma_d^2) J^T.
Rectified stereo images are undistorted, so no lens distortion appears here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError

__all__ = ["StereoCamera", "depth_from_disparity", "disparity_from_depth", "depth_sigma"]


def depth_from_disparity(disparity_px, focal_px: float, baseline_m: float):
    """Z = f b / d; NaN where the disparity is not positive (no valid match / at infinity)."""
    d = np.asarray(disparity_px, dtype=float)
    return focal_px * baseline_m / np.where(d > 0, d, np.nan)


def disparity_from_depth(depth_m, focal_px: float, baseline_m: float):
    return focal_px * baseline_m / np.asarray(depth_m, dtype=float)


def depth_sigma(depth_m, focal_px: float, baseline_m: float, sigma_disparity_px: float):
    """sigma_Z = Z^2 sigma_d / (f b)."""
    z = np.asarray(depth_m, dtype=float)
    return z * z * sigma_disparity_px / (focal_px * baseline_m)


@dataclass(frozen=True)
class StereoCamera:
    """Rectified stereo: left-camera intrinsics (no distortion), baseline, disparity noise."""

    fx: float
    fy: float
    cx: float
    cy: float
    baseline_m: float
    sigma_disparity_px: float = 0.5

    def __post_init__(self) -> None:
        if not (self.fx > 0 and self.fy > 0 and self.baseline_m > 0 and self.sigma_disparity_px >= 0):
            raise ConfigError(f"StereoCamera needs positive focal lengths and baseline, got {self}")

    def project(self, camera_p):
        """(..., 3) points in the left camera frame -> (..., 3) (u_left, v, disparity)."""
        p = np.asarray(camera_p, dtype=float)
        X, Y, Z = p[..., 0], p[..., 1], p[..., 2]
        return np.stack([self.fx * X / Z + self.cx, self.fy * Y / Z + self.cy, self.fx * self.baseline_m / Z], -1)

    def project_jacobian(self, camera_p):
        """(..., 3, 3) d(u, v, d) / d(X, Y, Z)."""
        p = np.asarray(camera_p, dtype=float)
        X, Y, Z = p[..., 0], p[..., 1], p[..., 2]
        J = np.zeros(p.shape[:-1] + (3, 3))
        J[..., 0, 0] = self.fx / Z
        J[..., 0, 2] = -self.fx * X / Z**2
        J[..., 1, 1] = self.fy / Z
        J[..., 1, 2] = -self.fy * Y / Z**2
        J[..., 2, 2] = -self.fx * self.baseline_m / Z**2
        return J

    def triangulate(self, uvd):
        """(..., 3) (u_left, v, disparity) -> (..., 3) point in the left camera frame."""
        m = np.asarray(uvd, dtype=float)
        Z = depth_from_disparity(m[..., 2], self.fx, self.baseline_m)
        return np.stack([(m[..., 0] - self.cx) * Z / self.fx, (m[..., 1] - self.cy) * Z / self.fy, Z], -1)

    def triangulate_jacobian(self, uvd):
        """(..., 3, 3) d(X, Y, Z) / d(u, v, d)."""
        m = np.asarray(uvd, dtype=float)
        u, v, d = m[..., 0], m[..., 1], m[..., 2]
        fb = self.fx * self.baseline_m
        Z = fb / d
        dZ = -fb / d**2
        J = np.zeros(m.shape[:-1] + (3, 3))
        J[..., 0, 0] = Z / self.fx
        J[..., 0, 2] = (u - self.cx) * dZ / self.fx
        J[..., 1, 1] = Z / self.fy
        J[..., 1, 2] = (v - self.cy) * dZ / self.fy
        J[..., 2, 2] = dZ
        return J

    def depth_sigma(self, depth_m):
        return depth_sigma(depth_m, self.fx, self.baseline_m, self.sigma_disparity_px)

    def point_covariance(self, uvd, sigma_pixel_px: float = 0.5):
        """(..., 3, 3) first-order covariance of the triangulated point for pixel noise
        sigma_pixel on u and v and ``sigma_disparity_px`` on the disparity."""
        J = self.triangulate_jacobian(uvd)
        S = np.diag([sigma_pixel_px**2, sigma_pixel_px**2, self.sigma_disparity_px**2])
        return J @ S @ np.swapaxes(J, -1, -2)

    def measure(self, rng: np.random.Generator, camera_p, sigma_pixel_px: float = 0.5):
        """Noisy (u_left, v, disparity) for (..., 3) points (Gaussian pixel/disparity noise)."""
        z = self.project(camera_p)
        sig = np.array([sigma_pixel_px, sigma_pixel_px, self.sigma_disparity_px])
        return z + rng.standard_normal(z.shape) * sig
