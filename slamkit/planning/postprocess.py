"""Path post-processing (shortcutting, smoothing) and the path-quality metrics of the benchmark.

- :func:`shortcut`: random shortcutting (Geraerts & Overmars, "Creating High-quality Paths for
  Motion Planning", IJRR 26(8), 2007): pick two vertices, replace what lies between by the
  straight motion if it is collision-free.
- :func:`smooth`: Chaikin corner cutting (Chaikin 1974) with a collision check per cut: each
  corner is replaced by the points 1/4 and 3/4 along its two segments when the cut is free,
  otherwise it is kept - so the path stays collision-free and converges towards a quadratic
  B-spline where there is room.
- :func:`path_length`, :func:`smoothness` (OMPL ``PathGeometric::smoothness``: sum over interior
  vertices of the squared turning angle; 0 for a straight line), :func:`min_clearance`.
"""

from __future__ import annotations

import numpy as np

from slamkit.planning.worlds import as_world


def path_length(world, path: np.ndarray) -> float:
    """Length under the world's metric (Euclidean for points, weighted SE(2) otherwise)."""
    path = np.asarray(path, dtype=float)
    if len(path) < 2:
        return 0.0
    world = as_world(world)
    return float(sum(world.distance(path[i], path[i + 1][None])[0] for i in range(len(path) - 1)))


def shortcut(world, path: np.ndarray, rng: np.random.Generator, iterations: int = 100) -> np.ndarray:
    world = as_world(world)
    p = np.asarray(path, dtype=float).copy()
    for _ in range(iterations):
        if len(p) < 3:
            break
        i, j = np.sort(rng.choice(len(p), 2, replace=False))
        if j - i < 2:
            continue
        if world.motions_valid(p[i][None], p[j][None])[0]:
            p = np.vstack([p[:i + 1], p[j:]])
    return p


def smooth(world, path: np.ndarray, iterations: int = 3) -> np.ndarray:
    world = as_world(world)
    p = np.asarray(path, dtype=float)
    for _ in range(iterations):
        if len(p) < 3:
            break
        q = 0.75 * p[:-1] + 0.25 * p[1:]     # 1/4 along each segment
        r = 0.25 * p[:-1] + 0.75 * p[1:]     # 3/4 along each segment
        if world.dim == 3:                   # interpolate headings on the circle
            q = world.interpolate(p[:-1], p[1:], 0.25)
            r = world.interpolate(p[:-1], p[1:], 0.75)
        # corner k (vertex k, 1 <= k <= n-2) is cut by the segment r[k-1] -> q[k]
        cut_ok = world.motions_valid(r[:-1], q[1:])
        out = [p[0]]
        for k in range(1, len(p) - 1):
            if cut_ok[k - 1]:
                out += [r[k - 1], q[k]]
            else:
                out += [r[k - 1], p[k], q[k]]  # keep the corner: these lie on the old path
        out.append(p[-1])
        p = np.asarray(out)
    return p


def smoothness(path: np.ndarray) -> float:
    path = np.asarray(path, dtype=float)[:, :2]
    if len(path) < 3:
        return 0.0
    a = np.diff(path, axis=0)
    a = a[np.linalg.norm(a, axis=1) > 1e-12]
    if len(a) < 2:
        return 0.0
    u, v = a[:-1], a[1:]
    cos = np.einsum("ij,ij->i", u, v) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
    turn = np.arccos(np.clip(cos, -1.0, 1.0))
    return float(np.sum(turn ** 2))


def min_clearance(world, path: np.ndarray, step_m: float | None = None) -> float:
    """Smallest obstacle clearance (m) along the path, sampled every ``step_m`` (default 1% of
    the world's extent)."""
    world = as_world(world)
    path = np.asarray(path, dtype=float)
    if len(path) == 0:
        return float("nan")
    xy = path[:, :2]
    step = step_m or 0.01 * world.extent
    pts = [xy[:1]]
    for a, b in zip(xy[:-1], xy[1:]):
        k = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        pts.append(a + np.linspace(0.0, 1.0, k + 1)[1:, None] * (b - a))
    base = world.base if hasattr(world, "base") else world
    return float(base.clearance(np.vstack(pts)).min())
