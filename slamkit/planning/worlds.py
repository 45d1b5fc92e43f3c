"""Configuration spaces and batched collision checking for the sampling-based planners.

:class:`PointWorld`: a point robot in a rectangle among circles, polygons and/or an occupancy
grid. :class:`SE2World`: a rigid polygonal body (x, y, theta) in such a world. Both expose the
same small interface the planners need, always on batches (``(N, d)`` arrays), so one numpy call
checks a whole neighbourhood:

- ``sample_uniform(rng, n)``, ``distance(a, B)``, ``interpolate(A, B, t)``;
- ``is_valid(X) -> (N,) bool`` and ``motions_valid(A, B) -> (N,) bool`` (straight motions);
- ``clearance(X) -> (N,)`` distance (m) from the robot position to the nearest obstacle;
- ``measure`` (Lebesgue measure of the space, for the RRT* radius) and ``dim``.

Segment tests against circles and polygons are exact (closest point on a segment, orientation
tests for edge crossings); against a grid they sample the segment every ``check_step_m``
(default half a cell), the usual discretised check (it can clip a cell corner by less than a
step).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.distance import cdist

from slamkit.geometry.angles import wrap_angle
from slamkit.geometry.segments import point_segment_distance
from slamkit.errors import PlanningError
from slamkit.maps.occupancy_grid import OccupancyGrid


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def points_in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """(N,) True for points strictly inside the (K, 2) polygon (crossing-number test)."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    v0 = polygon
    v1 = np.roll(polygon, -1, axis=0)
    x, y = p[:, 0:1], p[:, 1:2]
    straddle = (v0[None, :, 1] > y) != (v1[None, :, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = v0[None, :, 0] + (y - v0[None, :, 1]) * (v1[None, :, 0] - v0[None, :, 0]) / (
            v1[None, :, 1] - v0[None, :, 1])
    hits = straddle & (x < x_cross)
    return (hits.sum(axis=1) % 2) == 1


def _segments_cross_edges(A: np.ndarray, B: np.ndarray, P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(N,) True where segment A_i B_i touches any edge P_j Q_j (orientation test; touching and
    collinear overlaps count, which errs on the safe side)."""
    if len(P) == 0:
        return np.zeros(len(A), dtype=bool)
    a, b = A[:, None, :], B[:, None, :]
    p, q = P[None], Q[None]
    d1 = _cross(q - p, a - p)
    d2 = _cross(q - p, b - p)
    d3 = _cross(b - a, p - a)
    d4 = _cross(b - a, q - a)
    return np.any((d1 * d2 <= 0) & (d3 * d4 <= 0), axis=1)


class PointWorld:
    """A point robot in the box ``bounds_m = [[xmin, ymin], [xmax, ymax]]``.

    ``circles`` (M, 3) rows (cx, cy, radius); ``polygons`` a list of (K, 2) vertex arrays;
    ``grid`` an OccupancyGrid whose occupied cells (and everything outside it) are obstacles.
    """

    dim = 2

    def __init__(self, bounds_m: np.ndarray, circles: np.ndarray | None = None,
                 polygons: list[np.ndarray] | tuple = (), grid: OccupancyGrid | None = None,
                 check_step_m: float | None = None, name: str = "world"):
        b = np.asarray(bounds_m, dtype=float).reshape(2, 2)
        if not np.all(b[1] > b[0]):
            raise PlanningError(f"bounds_m must be [[xmin, ymin], [xmax, ymax]] with max > min, got {b.tolist()}")
        self.bounds_m = b
        self.circles = np.zeros((0, 3)) if circles is None else np.asarray(circles, dtype=float).reshape(-1, 3)
        if np.any(self.circles[:, 2] <= 0):
            raise PlanningError("circle radii must be positive")
        self._r2 = self.circles[None, :, 2] ** 2
        self._cx = np.ascontiguousarray(self.circles[None, :, 0])
        self._cy = np.ascontiguousarray(self.circles[None, :, 1])
        self._circle_list = [tuple(c) for c in (self.circles[:, :2].tolist())]
        self._r2_list = (self.circles[:, 2] ** 2).tolist()
        self.polygons = [np.asarray(p, dtype=float).reshape(-1, 2) for p in polygons]
        if any(len(p) < 3 for p in self.polygons):
            raise PlanningError("every polygon needs at least 3 vertices")
        if self.polygons:
            self._edge_p = np.concatenate(self.polygons)
            self._edge_q = np.concatenate([np.roll(p, -1, axis=0) for p in self.polygons])
        else:
            self._edge_p = self._edge_q = np.zeros((0, 2))
        self.grid = grid
        if check_step_m is None:
            check_step_m = 0.5 * grid.resolution_m if grid is not None else math.inf
        self.check_step_m = float(check_step_m)
        self.name = name
        self._grid_clearance: np.ndarray | None = None

    @classmethod
    def from_grid(cls, grid: OccupancyGrid, **kw) -> "PointWorld":
        lo = grid.origin_xy_m
        hi = lo + np.array([grid.width, grid.height]) * grid.resolution_m
        return cls(np.stack([lo, hi]), grid=grid, name=kw.pop("name", grid.name), **kw)

    # -------------------------------------------------------------- space
    @property
    def measure(self) -> float:
        return float(np.prod(self.bounds_m[1] - self.bounds_m[0]))

    @property
    def extent(self) -> float:
        """Length of the box diagonal (a natural scale for step sizes)."""
        return float(np.linalg.norm(self.bounds_m[1] - self.bounds_m[0]))

    def sample_uniform(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return self.bounds_m[0] + rng.random((n, 2)) * (self.bounds_m[1] - self.bounds_m[0])

    def distance(self, a: np.ndarray, B: np.ndarray) -> np.ndarray:
        """(N,) Euclidean distance from ``a`` (2,) to each row of ``B`` (N, 2)."""
        B = np.asarray(B, dtype=float)
        if B.ndim == 2 and B.flags.c_contiguous:
            # cdist is ~5x faster than numpy arithmetic on (N, 2) rows (one C loop, no temporaries)
            return cdist(np.asarray(a, dtype=float).reshape(1, 2), B)[0]
        d = B - a
        return np.hypot(d[..., 0], d[..., 1])

    def interpolate(self, A: np.ndarray, B: np.ndarray, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return A + (t[..., None] if t.ndim else t) * (B - A)

    # -------------------------------------------------------------- collision
    def in_bounds(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float).reshape(-1, 2)
        return np.all((X >= self.bounds_m[0]) & (X <= self.bounds_m[1]), axis=1)

    def is_valid(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float).reshape(-1, 2)
        lo, hi = self.bounds_m
        ok = (X[:, 0] >= lo[0]) & (X[:, 0] <= hi[0]) & (X[:, 1] >= lo[1]) & (X[:, 1] <= hi[1])
        if len(self.circles):
            dx = X[:, 0:1] - self.circles[None, :, 0]
            dy = X[:, 1:2] - self.circles[None, :, 1]
            ok &= ~np.any(dx * dx + dy * dy <= self._r2, axis=1)
        for poly in self.polygons:
            ok &= ~points_in_polygon(X, poly)
        if self.grid is not None:
            ok &= self.grid.is_free_world(X)
        return ok

    def point_valid(self, x: np.ndarray) -> bool:
        """``is_valid`` for one point, in plain Python for circles (one point per iteration
        is the tree planners' common case, where numpy's per-call overhead dominates)."""
        px, py = float(x[0]), float(x[1])
        lo, hi = self.bounds_m
        if not (lo[0] <= px <= hi[0] and lo[1] <= py <= hi[1]):
            return False
        for (cx, cy), r2 in zip(self._circle_list, self._r2_list):
            if (px - cx) ** 2 + (py - cy) ** 2 <= r2:
                return False
        if self.polygons or self.grid is not None:
            return bool(self.is_valid(np.array([[px, py]]))[0])
        return True

    def motions_valid(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """(N,) True where the straight segment A_i -> B_i is collision-free (endpoints included)."""
        A = np.asarray(A, dtype=float).reshape(-1, 2)
        B = np.asarray(B, dtype=float).reshape(-1, 2)
        ok = self.is_valid(A) & self.is_valid(B)
        if ok.any():
            idx = np.flatnonzero(ok)
            ok[idx] = self.edges_free(A[idx], B[idx])
        return ok

    def edges_free(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(N,) segment test for segments whose endpoints are already known to be valid (the
        planners' hot path: tree vertices are valid by construction). ``b`` may be one (1, 2)
        point shared by all segments."""
        good = np.ones(len(a), dtype=bool)
        if len(self.circles):
            # closest point of each segment to each circle centre (written out: this runs once
            # per RRT* iteration, where numpy call overhead dominates)
            dx = b[:, 0:1] - a[:, 0:1]
            dy = b[:, 1:2] - a[:, 1:2]
            l2 = np.maximum(dx * dx + dy * dy, 1e-300)
            cx = self._cx - a[:, 0:1]
            cy = self._cy - a[:, 1:2]
            t = np.clip((cx * dx + cy * dy) / l2, 0.0, 1.0)
            ex = cx - t * dx
            ey = cy - t * dy
            good &= ~(ex * ex + ey * ey <= self._r2).any(1)
        if len(self._edge_p):
            good &= ~_segments_cross_edges(a, np.broadcast_to(b, a.shape), self._edge_p, self._edge_q)
        if self.grid is not None and good.any():
            b = np.broadcast_to(b, a.shape)
            g = np.flatnonzero(good)
            seg = np.linalg.norm(b[g] - a[g], axis=1)
            k = int(min(np.ceil(seg.max() / self.check_step_m), 100_000)) + 1
            t = np.linspace(0.0, 1.0, k)
            pts = a[g, None, :] + t[None, :, None] * (b[g] - a[g])[:, None, :]
            free = self.grid.is_free_world(pts.reshape(-1, 2)).reshape(len(g), k)
            good[g] = free.all(axis=1)
        return good

    def clearance(self, X: np.ndarray) -> np.ndarray:
        """(N,) distance (m) to the nearest obstacle (negative inside circles and polygons;
        grids: distance from the cell centre to the nearest occupied cell centre minus half a
        cell). ``inf`` in an obstacle-free world; the box boundary is not an obstacle here."""
        X = np.asarray(X, dtype=float).reshape(-1, 2)
        out = np.full(len(X), np.inf)
        if len(self.circles):
            d = np.linalg.norm(X[:, None, :] - self.circles[None, :, :2], axis=-1) - self.circles[None, :, 2]
            out = np.minimum(out, d.min(axis=1))
        if len(self._edge_p):
            d = point_segment_distance(X, self._edge_p, self._edge_q).min(axis=1)
            inside = np.zeros(len(X), dtype=bool)
            for poly in self.polygons:
                inside |= points_in_polygon(X, poly)
            out = np.minimum(out, np.where(inside, -d, d))
        if self.grid is not None:
            from slamkit.maps.distance_field import distance_at, distance_field_m

            if self._grid_clearance is None:
                self._grid_clearance = distance_field_m(self.grid) - 0.5 * self.grid.resolution_m
            out = np.minimum(out, distance_at(self.grid, self._grid_clearance, X, outside_m=0.0))
        return out

    def position(self, X: np.ndarray) -> np.ndarray:
        return np.asarray(X, dtype=float).reshape(-1, self.dim)[:, :2]



class SE2World:
    """A rigid body with polygonal ``footprint_m`` (K, 2) (body frame, convex or not) moving in
    a :class:`PointWorld`. States are (x, y, theta); the metric is
    ``sqrt(dx^2 + dy^2 + (angle_weight_m * wrap(dtheta))^2)`` with the footprint's circumradius
    as default weight, so a rotation counts as far as the body's farthest point moves."""

    dim = 3

    def __init__(self, base: PointWorld, footprint_m: np.ndarray, angle_weight_m: float | None = None,
                 check_step_m: float | None = None):
        self.base = base
        fp = np.asarray(footprint_m, dtype=float).reshape(-1, 2)
        if len(fp) < 3:
            raise PlanningError("footprint_m needs at least 3 vertices")
        self.footprint_m = fp
        self.radius_m = float(np.linalg.norm(fp, axis=1).max())
        self.angle_weight_m = self.radius_m if angle_weight_m is None else float(angle_weight_m)
        step = check_step_m
        if step is None:
            step = base.check_step_m if math.isfinite(base.check_step_m) else 0.25 * self.radius_m
        self.check_step_m = float(step)
        self.name = base.name
        # obstacles entirely inside the footprint cross none of its edges: test circle centres
        # and polygon vertices for containment too
        self._obstacle_pts = np.concatenate([base.circles[:, :2]] + list(base.polygons)) \
            if (len(base.circles) or base.polygons) else np.zeros((0, 2))
        # body-frame points inside the footprint: a grid cell smaller than the body can hide
        # between its edges, so grids are also checked at these points
        self._interior = np.zeros((0, 2))
        if base.grid is not None:
            h = 0.5 * base.grid.resolution_m
            lo, hi = fp.min(axis=0), fp.max(axis=0)
            xs, ys = np.arange(lo[0], hi[0] + h, h), np.arange(lo[1], hi[1] + h, h)
            lattice = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
            self._interior = lattice[points_in_polygon(lattice, fp)]

    @property
    def bounds_m(self) -> np.ndarray:
        return self.base.bounds_m

    @property
    def measure(self) -> float:
        return self.base.measure * 2 * np.pi * self.angle_weight_m

    @property
    def extent(self) -> float:
        return self.base.extent

    def sample_uniform(self, rng: np.random.Generator, n: int) -> np.ndarray:
        xy = self.base.sample_uniform(rng, n)
        return np.column_stack([xy, rng.uniform(-np.pi, np.pi, n)])

    def distance(self, a: np.ndarray, B: np.ndarray) -> np.ndarray:
        B = np.asarray(B, dtype=float)
        d = B[..., :2] - a[..., :2]
        dth = wrap_angle(B[..., 2] - a[..., 2]) * self.angle_weight_m
        return np.sqrt(np.einsum("...i,...i->...", d, d) + dth * dth)

    def interpolate(self, A: np.ndarray, B: np.ndarray, t: np.ndarray | float) -> np.ndarray:
        A = np.asarray(A, dtype=float)
        B = np.asarray(B, dtype=float)
        t = np.asarray(t, dtype=float)
        tt = t[..., None] if t.ndim else t
        xy = A[..., :2] + tt * (B[..., :2] - A[..., :2])
        th = wrap_angle(A[..., 2] + (t if t.ndim else t) * wrap_angle(B[..., 2] - A[..., 2]))
        return np.concatenate([xy, np.asarray(th)[..., None]], axis=-1)

    def _transform(self, X: np.ndarray, body_pts: np.ndarray) -> np.ndarray:
        c, s = np.cos(X[:, 2]), np.sin(X[:, 2])
        x = X[:, None, 0] + c[:, None] * body_pts[None, :, 0] - s[:, None] * body_pts[None, :, 1]
        y = X[:, None, 1] + s[:, None] * body_pts[None, :, 0] + c[:, None] * body_pts[None, :, 1]
        return np.stack([x, y], axis=-1)

    def is_valid(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float).reshape(-1, 3)
        n, k = len(X), len(self.footprint_m)
        verts = self._transform(X, self.footprint_m)            # (n, K, 2)
        nxt = np.roll(verts, -1, axis=1)
        ok = self.base.motions_valid(verts.reshape(-1, 2), nxt.reshape(-1, 2)).reshape(n, k).all(axis=1)
        base = self.base
        if len(self._obstacle_pts) and ok.any():
            idx = np.flatnonzero(ok)
            # obstacle points in each pose's body frame: (n, P, 2), tested against the footprint
            c, s = np.cos(X[idx, 2]), np.sin(X[idx, 2])
            rel = self._obstacle_pts[None, :, :] - X[idx, None, :2]
            local = np.stack([c[:, None] * rel[..., 0] + s[:, None] * rel[..., 1],
                              -s[:, None] * rel[..., 0] + c[:, None] * rel[..., 1]], axis=-1)
            inside = points_in_polygon(local.reshape(-1, 2), self.footprint_m).reshape(len(idx), -1)
            ok[idx] = ~inside.any(axis=1)
        if len(self._interior) and ok.any():
            idx = np.flatnonzero(ok)
            pts = self._transform(X[idx], self._interior).reshape(-1, 2)
            ok[idx] = base.is_valid(pts).reshape(len(idx), -1).all(axis=1)
        return ok

    def motions_valid(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        A = np.asarray(A, dtype=float).reshape(-1, 3)
        B = np.asarray(B, dtype=float).reshape(-1, 3)
        # enough intermediate poses that no footprint point moves more than check_step_m
        sweep = np.linalg.norm(B[:, :2] - A[:, :2], axis=1) + self.radius_m * np.abs(wrap_angle(B[:, 2] - A[:, 2]))
        k = int(min(np.ceil(sweep.max() / self.check_step_m), 10_000)) + 1 if len(A) else 1
        t = np.linspace(0.0, 1.0, max(k, 2))
        poses = self.interpolate(A[:, None, :], B[:, None, :], t[None, :])
        return self.is_valid(poses.reshape(-1, 3)).reshape(len(A), -1).all(axis=1)

    def edges_free(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        A = np.asarray(A, dtype=float).reshape(-1, 3)
        return self.motions_valid(A, np.broadcast_to(np.asarray(B, dtype=float).reshape(-1, 3), A.shape))

    def point_valid(self, x: np.ndarray) -> bool:
        return bool(self.is_valid(np.asarray(x, dtype=float)[None])[0])

    def clearance(self, X: np.ndarray) -> np.ndarray:
        return self.base.clearance(np.asarray(X, dtype=float).reshape(-1, 3)[:, :2])

    def position(self, X: np.ndarray) -> np.ndarray:
        return np.asarray(X, dtype=float).reshape(-1, 3)[:, :2]


def as_world(world) -> PointWorld | SE2World:
    """Accept an OccupancyGrid where a continuous world is expected (point robot on the grid)."""
    if isinstance(world, (PointWorld, SE2World)):
        return world
    if isinstance(world, OccupancyGrid):
        return PointWorld.from_grid(world)
    raise PlanningError(f"sampling planners need a PointWorld, SE2World or OccupancyGrid, got {type(world).__name__}")
