"""Where on the global path a local controller should aim: the nearest point, a carrot
``lookahead_m`` further along (pure-pursuit style, Coulter 1992), and an arc-length resampling of
the path ahead for MPC references. All vectorised over path segments."""

from __future__ import annotations

import numpy as np


def arc_length_m(path_xy_m: np.ndarray) -> np.ndarray:
    """(N,) the arc length at each vertex of the polyline (N, 2), 0 at the first."""
    seg = np.linalg.norm(np.diff(path_xy_m, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)])


def project_on_path(path_xy_m: np.ndarray, xy_m: np.ndarray) -> float:
    """Arc length s of the point of the polyline nearest to ``xy_m``."""
    path = np.asarray(path_xy_m, dtype=float)
    if len(path) == 1:
        return 0.0
    a, b = path[:-1], path[1:]
    ab = b - a
    den = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
    t = np.clip(np.einsum("ij,ij->i", np.asarray(xy_m, float)[None, :] - a, ab) / den, 0.0, 1.0)
    proj = a + t[:, None] * ab
    i = int(np.argmin(np.linalg.norm(proj - xy_m, axis=1)))
    s = arc_length_m(path)
    return float(s[i] + t[i] * np.sqrt(den[i]))


def project_many(path_xy_m: np.ndarray, xy_m: np.ndarray) -> np.ndarray:
    """Arc lengths (K,) of the projections of (K, 2) points, vectorised over points x segments."""
    path = np.asarray(path_xy_m, dtype=float)
    pts = np.asarray(xy_m, dtype=float).reshape(-1, 2)
    if len(path) == 1:
        return np.zeros(len(pts))
    a, ab = path[:-1], np.diff(path, axis=0)
    den = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
    t = np.clip(np.einsum("kij,ij->ki", pts[:, None, :] - a, ab) / den, 0.0, 1.0)  # (K, S)
    proj = a + t[..., None] * ab
    i = np.argmin(np.linalg.norm(proj - pts[:, None, :], axis=2), axis=1)
    s = arc_length_m(path)
    return s[i] + t[np.arange(len(pts)), i] * np.sqrt(den[i])


def crop(path_xy_m: np.ndarray, s_lo_m: float, s_hi_m: float) -> np.ndarray:
    """The vertices of the polyline spanning arc lengths [s_lo, s_hi] (one extra vertex each
    side), so per-candidate projections only look at the nearby part of a long path."""
    path = np.asarray(path_xy_m, dtype=float)
    s = arc_length_m(path)
    lo = max(int(np.searchsorted(s, s_lo_m, side="right")) - 1, 0)
    hi = min(int(np.searchsorted(s, s_hi_m, side="left")) + 1, len(path))
    return path[lo:max(hi, lo + 1)]


def point_at(path_xy_m: np.ndarray, s_m: np.ndarray) -> np.ndarray:
    """Points at arc lengths ``s_m`` (...,) (clamped to the path) -> (..., 2)."""
    path = np.asarray(path_xy_m, dtype=float)
    s_query = np.asarray(s_m, dtype=float)
    if len(path) == 1:
        return np.broadcast_to(path[0], s_query.shape + (2,)).copy()
    s = arc_length_m(path)
    q = np.clip(s_query, 0.0, s[-1])
    return np.stack([np.interp(q, s, path[:, 0]), np.interp(q, s, path[:, 1])], axis=-1)


def lookahead_point(path_xy_m: np.ndarray, xy_m: np.ndarray, lookahead_m: float) -> np.ndarray:
    """The carrot: the path point ``lookahead_m`` beyond the projection of ``xy_m``."""
    return point_at(path_xy_m, project_on_path(path_xy_m, xy_m) + lookahead_m)


def path_reference(path_xy_m: np.ndarray, xy_m: np.ndarray, spacing_m: float, n: int,
                   heading_rad: float) -> np.ndarray:
    """(n, 3) reference poses ``spacing_m`` apart along the path ahead of ``xy_m``; the heading
    of each is the path tangent, unwrapped to start near ``heading_rad`` so a quadratic heading
    cost never sees a 2 pi jump. Beyond the goal the reference stays at the goal."""
    path = np.asarray(path_xy_m, dtype=float)
    s0 = project_on_path(path, xy_m)
    s = s0 + spacing_m * np.arange(1, n + 1)
    pts = point_at(path, s)
    ahead = point_at(path, s + 0.05)
    behind = point_at(path, s - 0.05)
    tangent = ahead - behind
    theta = np.arctan2(tangent[:, 1], tangent[:, 0])
    # where the path has collapsed to the goal, keep the last defined heading
    flat = np.linalg.norm(tangent, axis=1) < 1e-9
    if np.all(flat):
        d = pts[0] - np.asarray(xy_m, float)
        theta[:] = np.arctan2(d[1], d[0]) if np.linalg.norm(d) > 1e-9 else heading_rad
    else:
        idx = np.where(~flat, np.arange(n), 0)
        idx = np.maximum.accumulate(idx)
        first = int(np.argmax(~flat))
        idx[:first] = first
        theta = theta[idx]
    theta = np.unwrap(np.concatenate([[heading_rad], theta]))[1:]
    return np.column_stack([pts, theta])
