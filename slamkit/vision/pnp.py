"""Perspective-n-point: the pose of a calibrated camera from 3D points and their images.

* Linear: the direct linear transform for the 3x4 matrix [R | t] from >= 6 points in normalised
  image coordinates (Hartley & Zisserman, *Multiple View Geometry*, 2nd ed., sec. 7.1), the
  rotation block projected onto SO(3) (SVD) and the scale taken from it.
* Refinement: Gauss-Newton on the reprojection error in normalised coordinates over the left
  perturbation camera_T_world <- exp(xi) camera_T_world, xi = (rho, phi) (translation first, as
  ``slamkit.geometry.se3``): d camera_p / d xi = [I, -hat(camera_p)].
* RANSAC over minimal 6-point samples with the adaptive iteration count of
  :func:`slamkit.vision.two_view.ransac_iterations` (hypotheses solved and scored in blocks of
  32 as one batched linear-algebra call; the count is checked between blocks), then refinement
  on the inliers (twice, with the inlier set recomputed in between).

Poses are ``camera_T_world`` (4x4): camera_p = R world_p + t, as OpenCV's solvePnP (rvec, tvec).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.geometry import se3, so3
from slamkit.vision.two_view import ransac_iterations

__all__ = ["pnp_dlt", "refine_pose", "reprojection_errors", "PnpResult", "pnp_ransac"]

_SAMPLE = 6
#: RANSAC hypotheses generated and scored at once
_BLOCK = 32


def _dlt_batch(X: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(B, 4, 4) camera_T_world from B point sets (B, n, 3) and their images (B, n, 2)."""
    c = X.mean(axis=1, keepdims=True)
    scale = np.sqrt(((X - c) ** 2).sum(axis=2)).mean(axis=1)
    scale = np.where(scale > 0, scale, 1.0)
    Xn = (X - c) / scale[:, None, None]  # conditioning; undone below
    Xh = np.concatenate([Xn, np.ones(Xn.shape[:2] + (1,))], axis=2)
    B, n = X.shape[:2]
    A = np.zeros((B, 2 * n, 12))
    A[:, 0::2, 0:4] = Xh
    A[:, 0::2, 8:12] = -x[:, :, 0:1] * Xh
    A[:, 1::2, 4:8] = Xh
    A[:, 1::2, 8:12] = -x[:, :, 1:2] * Xh
    if 2 * n < 12:
        A = np.concatenate([A, np.zeros((B, 12 - 2 * n, 12))], axis=1)
    _, _, Vt = np.linalg.svd(A)
    P = Vt[:, -1].reshape(B, 3, 4)
    U, sv, Wt = np.linalg.svd(P[:, :, :3])
    R = U @ Wt
    k = sv.mean(axis=1)
    # P was found up to sign: det(P[:, :3]) < 0 means a negative scale
    flip = np.where(np.linalg.det(R) < 0, -1.0, 1.0)
    R = R * flip[:, None, None]
    t = P[:, :, 3] / (k * flip)[:, None]
    # camera_p ~ R (X - c) / scale + t, and the projection ignores the overall scale
    T = np.zeros((B, 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = scale[:, None] * t - np.einsum("bij,bj->bi", R, c[:, 0])
    T[:, 3, 3] = 1.0
    return T


def pnp_dlt(world_p, x) -> np.ndarray:
    """camera_T_world (4x4) from >= 6 world points (N, 3) and normalised image points (N, 2)."""
    X = np.asarray(world_p, dtype=float).reshape(-1, 3)
    x = np.asarray(x, dtype=float).reshape(-1, 2)
    if len(X) < _SAMPLE or len(X) != len(x):
        raise ConfigError(f"pnp_dlt needs >= {_SAMPLE} matching points, got {len(X)} and {len(x)}")
    return _dlt_batch(X[None], x[None])[0]


def _errors_batch(T: np.ndarray, X: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(B, N) reprojection errors of B hypotheses (inf behind the camera)."""
    p = np.einsum("bij,nj->bni", T[:, :3, :3], X) + T[:, None, :3, 3]
    z = p[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.hypot(p[..., 0] / z - x[:, 0], p[..., 1] / z - x[:, 1])
    return np.where(z > 1e-9, err, np.inf)


def reprojection_errors(camera_T_world, world_p, x) -> np.ndarray:
    """(N,) distance between the projection of each point and its image point (normalised
    units; inf behind the camera)."""
    p = se3.transform_points(np.asarray(camera_T_world, float), np.asarray(world_p, float))
    with np.errstate(divide="ignore", invalid="ignore"):
        proj = p[:, :2] / p[:, 2:3]
    err = np.linalg.norm(proj - np.asarray(x, float), axis=1)
    return np.where(p[:, 2] > 1e-9, err, np.inf)


def refine_pose(camera_T_world, world_p, x, iterations: int = 10) -> np.ndarray:
    """Gauss-Newton on the reprojection error of all given points (use inliers only)."""
    T = np.asarray(camera_T_world, dtype=float).copy()
    X = np.asarray(world_p, dtype=float)
    x = np.asarray(x, dtype=float)
    for _ in range(iterations):
        p = se3.transform_points(T, X)
        z = p[:, 2]
        if np.any(z <= 1e-9):
            front = z > 1e-9
            p, z, xs = p[front], z[front], x[front]
        else:
            xs = x
        if len(p) < 3:
            break
        r = (p[:, :2] / z[:, None] - xs).ravel()
        Jproj = np.zeros((len(p), 2, 3))
        Jproj[:, 0, 0] = 1 / z
        Jproj[:, 0, 2] = -p[:, 0] / z**2
        Jproj[:, 1, 1] = 1 / z
        Jproj[:, 1, 2] = -p[:, 1] / z**2
        dp = np.concatenate([np.broadcast_to(np.eye(3), (len(p), 3, 3)), -so3.hat(p)], axis=2)
        J = (Jproj @ dp).reshape(-1, 6)
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        T = se3.exp(step) @ T
        if np.linalg.norm(step) < 1e-10:
            break
    return T


@dataclass(frozen=True)
class PnpResult:
    camera_T_world: np.ndarray
    inliers: np.ndarray
    iterations: int


def pnp_ransac(world_p, x, threshold: float, confidence: float = 0.999, max_iterations: int = 500,
               rng: np.random.Generator | None = None) -> PnpResult:
    """camera_T_world by RANSAC over 6-point DLT samples; inliers have a reprojection error
    below ``threshold`` (normalised units: pixels / focal)."""
    X = np.asarray(world_p, dtype=float).reshape(-1, 3)
    x = np.asarray(x, dtype=float).reshape(-1, 2)
    n = len(X)
    if n < _SAMPLE or n != len(x):
        raise ConfigError(f"pnp_ransac needs >= {_SAMPLE} matching points, got {n} and {len(x)}")
    rng = np.random.default_rng(0) if rng is None else rng
    best_T, best_in, best_count = None, np.zeros(n, dtype=bool), -1
    needed, it = max_iterations, 0
    while it < needed:
        # hypotheses in blocks (one batched DLT and scoring), the adaptive count checked between
        block = min(_BLOCK, needed - it)
        it += block
        idx = np.argsort(rng.random((block, n)), axis=1)[:, :_SAMPLE]
        T = _dlt_batch(X[idx], x[idx])
        ok = np.isfinite(T).all(axis=(1, 2))
        if not ok.any():
            continue
        T = T[ok]
        inl = _errors_batch(T, X, x) < threshold
        counts = inl.sum(axis=1)
        k = int(np.argmax(counts))
        if counts[k] > best_count:
            best_T, best_in, best_count = T[k], inl[k], int(counts[k])
            needed = max(it, min(needed, ransac_iterations(best_count / n, _SAMPLE, confidence, max_iterations)))
    if best_T is None or best_count < _SAMPLE:
        raise ConfigError(f"PnP RANSAC found no pose with >= {_SAMPLE} inliers among {n} points")
    T, inl = best_T, best_in
    for _ in range(2):
        T = refine_pose(T, X[inl], x[inl])
        new = reprojection_errors(T, X, x) < threshold
        if new.sum() < _SAMPLE:
            break
        inl = new
    return PnpResult(T, inl, it)
