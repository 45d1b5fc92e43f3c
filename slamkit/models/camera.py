"""Pinhole camera with radial-tangential (Brown-Conrady / OpenCV "plumb bob") distortion.

Frames: the camera frame has z forward (optical axis), x right, y down (OpenCV). A point
camera_p = (X, Y, Z) with Z > 0 projects to the normalised image point (x, y) = (X/Z, Y/Z),
which is distorted (Brown, "Decentering distortion of lenses", 1966; OpenCV calib3d docs):

    r^2 = x^2 + y^2,   radial = 1 + k1 r^2 + k2 r^4 + k3 r^6
    x_d = x radial + 2 p1 x y + p2 (r^2 + 2 x^2)
    y_d = y radial + p1 (r^2 + 2 y^2) + 2 p2 x y

and mapped to pixels by K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]: u = fx x_d + cx,
v = fy y_d + cy. Distortion has no closed-form inverse; ``undistort`` uses the fixed-point
iteration of OpenCV's ``undistortPoints``: x <- (x_d - tangential(x)) / radial(x), starting
at x = x_d, which converges for the moderate distortion of real calibrated lenses.

Jacobians: d(u, v)/d(camera_p) = diag(fx, fy) D(x, y) [[1/Z, 0, -X/Z^2], [0, 1/Z, -Y/Z^2]] with
D the 2x2 distortion Jacobian. For a world point seen from ``world_T_camera`` (4x4) the pose
Jacobian uses the right perturbation world_T_camera exp(xi), xi = (rho, phi) (translation
first, as ``slamkit.geometry.se3``): d camera_p / d xi = [-I, hat(camera_p)].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.geometry import se3, so3

__all__ = ["PinholeCamera"]


@dataclass(frozen=True)
class PinholeCamera:
    fx: float
    fy: float
    cx: float
    cy: float
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    width: int = 640
    height: int = 480

    def __post_init__(self) -> None:
        if not (self.fx > 0 and self.fy > 0):
            raise ConfigError(f"PinholeCamera focal lengths must be positive, got fx={self.fx}, fy={self.fy}")
        if not (self.width > 0 and self.height > 0):
            raise ConfigError(f"PinholeCamera image size must be positive, got {self.width}x{self.height}")

    @classmethod
    def from_K(cls, K, dist=(0.0, 0.0, 0.0, 0.0, 0.0), width: int = 640, height: int = 480) -> "PinholeCamera":
        """From a 3x3 K and OpenCV's coefficient order (k1, k2, p1, p2, k3)."""
        K = np.asarray(K, dtype=float)
        k1, k2, p1, p2, k3 = (list(dist) + [0.0] * 5)[:5]
        return cls(K[0, 0], K[1, 1], K[0, 2], K[1, 2], k1, k2, k3, p1, p2, width, height)

    @classmethod
    def euroc_cam0(cls) -> "PinholeCamera":
        """The EuRoC MAV dataset's cam0 calibration (its cam0/sensor.yaml), 752 x 480."""
        return cls(458.654, 457.296, 367.215, 248.375, k1=-0.28340811, k2=0.07395907, k3=0.0,
                   p1=0.00019359, p2=1.76187114e-05, width=752, height=480)

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    # -- distortion on normalised coordinates --------------------------------------------------

    def _radial_tangential(self, xy):
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        tx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x)
        ty = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y
        return radial, tx, ty

    def distort(self, xy_normalized):
        """(..., 2) undistorted normalised points -> (..., 2) distorted normalised points."""
        xy = np.asarray(xy_normalized, dtype=float)
        radial, tx, ty = self._radial_tangential(xy)
        return np.stack([xy[..., 0] * radial + tx, xy[..., 1] * radial + ty], axis=-1)

    def distort_jacobian(self, xy_normalized):
        """(..., 2, 2) d(x_d, y_d) / d(x, y)."""
        xy = np.asarray(xy_normalized, dtype=float)
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        dradial_dr2 = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3)
        J = np.empty(xy.shape[:-1] + (2, 2))
        J[..., 0, 0] = radial + 2 * x * x * dradial_dr2 + 2 * self.p1 * y + 6 * self.p2 * x
        J[..., 0, 1] = 2 * x * y * dradial_dr2 + 2 * self.p1 * x + 2 * self.p2 * y
        J[..., 1, 0] = 2 * x * y * dradial_dr2 + 2 * self.p1 * x + 2 * self.p2 * y
        J[..., 1, 1] = radial + 2 * y * y * dradial_dr2 + 6 * self.p1 * y + 2 * self.p2 * x
        return J

    def undistort(self, xy_distorted, iterations: int = 100, tol: float = 1e-14):
        """(..., 2) distorted normalised points -> undistorted, by fixed-point iteration.

        Stops when every point moved less than ``tol`` in an iteration (or after
        ``iterations``). Check ``distort(undistort(p)) == p`` if the lens is extreme.
        """
        xd = np.asarray(xy_distorted, dtype=float)
        xy = xd.copy()
        for _ in range(iterations):  # iterations over all points at once, not per point
            radial, tx, ty = self._radial_tangential(xy)
            new = np.stack([(xd[..., 0] - tx) / radial, (xd[..., 1] - ty) / radial], axis=-1)
            step = np.max(np.abs(new - xy)) if new.size else 0.0
            xy = new
            if step < tol:
                break
        return xy

    # -- pixels ----------------------------------------------------------------------------------

    def normalized_to_pixel(self, xy_distorted):
        xy = np.asarray(xy_distorted, dtype=float)
        return np.stack([self.fx * xy[..., 0] + self.cx, self.fy * xy[..., 1] + self.cy], axis=-1)

    def pixel_to_normalized(self, uv):
        uv = np.asarray(uv, dtype=float)
        return np.stack([(uv[..., 0] - self.cx) / self.fx, (uv[..., 1] - self.cy) / self.fy], axis=-1)

    def project(self, camera_p):
        """(..., 3) points in the camera frame -> (..., 2) pixels (u, v); NaN where Z <= 0."""
        p = np.asarray(camera_p, dtype=float)
        z = np.where(p[..., 2] > 0, p[..., 2], np.nan)
        xy = np.stack([p[..., 0] / z, p[..., 1] / z], axis=-1)
        return self.normalized_to_pixel(self.distort(xy))

    def project_jacobian(self, camera_p):
        """(..., 2, 3) d(u, v) / d(camera_p)."""
        p = np.asarray(camera_p, dtype=float)
        X, Y, Z = p[..., 0], p[..., 1], p[..., 2]
        xy = np.stack([X / Z, Y / Z], axis=-1)
        dn = np.zeros(p.shape[:-1] + (2, 3))
        dn[..., 0, 0] = 1.0 / Z
        dn[..., 0, 2] = -X / Z**2
        dn[..., 1, 1] = 1.0 / Z
        dn[..., 1, 2] = -Y / Z**2
        return np.array([[self.fx, 0.0], [0.0, self.fy]]) @ self.distort_jacobian(xy) @ dn

    def unproject(self, uv, depth_m=None):
        """(..., 2) pixels -> (..., 3) camera-frame points: the ray with Z = 1, or the point at
        z-depth ``depth_m`` (broadcast over the leading axes)."""
        xy = self.undistort(self.pixel_to_normalized(uv))
        ray = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1)
        if depth_m is None:
            return ray
        return ray * np.asarray(depth_m, dtype=float)[..., None]

    def in_image(self, uv) -> np.ndarray:
        uv = np.asarray(uv, dtype=float)
        return (uv[..., 0] >= 0) & (uv[..., 0] < self.width) & (uv[..., 1] >= 0) & (uv[..., 1] < self.height)

    # -- world points seen from a camera pose ------------------------------------------------------

    def project_world(self, world_T_camera, world_p):
        """(4, 4) (or (..., 4, 4)) camera pose and (..., 3) world points -> (..., 2) pixels."""
        camera_p = se3.transform_points(se3.inverse(np.asarray(world_T_camera, float)), world_p)
        return self.project(camera_p)

    def project_world_jacobians(self, world_T_camera, world_p):
        """(J_pose (..., 2, 6), J_point (..., 2, 3)); J_pose for the right perturbation
        world_T_camera exp(xi), xi = (rho, phi)."""
        T = np.asarray(world_T_camera, dtype=float)
        camera_p = se3.transform_points(se3.inverse(T), world_p)
        Jp = self.project_jacobian(camera_p)
        R = se3.rotation(T)
        d_xi = np.concatenate([-np.broadcast_to(np.eye(3), camera_p.shape[:-1] + (3, 3)), so3.hat(camera_p)], axis=-1)
        return Jp @ d_xi, Jp @ np.swapaxes(R, -1, -2)
