"""Planar segments: the distance of points to line segments (the planners' polygon edges, the
obstacle tracker's lanes, yielding's seen spans)."""

from __future__ import annotations

import numpy as np


def point_segment_distance(X: np.ndarray, P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(N, E) distance from points X (N, 2) to the segments P_e Q_e (E, 2)."""
    d = Q - P
    l2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    t = np.clip(np.einsum("nej,ej->ne", X[:, None, :] - P[None], d) / l2, 0.0, 1.0)
    closest = P[None] + t[..., None] * d[None]
    return np.linalg.norm(X[:, None, :] - closest, axis=-1)


__all__ = ["point_segment_distance"]
