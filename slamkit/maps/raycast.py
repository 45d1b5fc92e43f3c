"""Ray casting on an occupancy grid, vectorised over every beam of every pose.

The traversal is the exact voxel walk of Amanatides and Woo, "A fast voxel traversal algorithm
for ray tracing", Eurographics 1987: along a ray ``p(t) = p0 + t d`` the grid-line crossings in
x happen at ``tx0 + i * tdx`` and in y at ``ty0 + j * tdy`` (``tdx = 1 / |dx|`` in cell units);
merging the two arithmetic sequences by time gives every cell the ray enters, in order.

Vectorisation: instead of one Python iteration per cell and ray, every still-active ray
generates its next ``chunk`` x-crossings and ``chunk`` y-crossings at once; a row-wise sort of
those ``2 * chunk`` times yields the next ``chunk`` cells exactly (among the first ``chunk``
merged events there are at most ``chunk`` of either kind, so none is missing). Occupancy of all
those cells is looked up with one fancy-index, the first hit per ray is found with ``argmax``,
and rays that hit, leave the maximum range or leave the grid for good drop out of the active
set. Ties (a ray through a cell corner) step in x first, as :func:`cast_ray_loop` does, so the
vectorised and the per-beam reference agree to the last bit.

Compiled core: when a C compiler is available, :class:`RayCaster` walks each beam in
``_raycast.c`` (built when slamkit is installed, loaded by :mod:`slamkit._native`): the same per-beam walk as
:func:`cast_ray_loop`, with the same float operations on the same numpy-computed origins and
directions, so it returns the same bits as both Python paths without needing the distance field.
The vectorised numpy walk above is the fallback (``SLAMKIT_NO_NATIVE=1``, no compiler, or an
origin 2^52 cells or more away); ``RayCaster.last_path`` says which one ran.

Conventions: the range is measured from the ray origin to the boundary where the ray enters the
first occupied cell (0 if the origin's own cell is occupied); beams that hit nothing within
``max_range_m`` return ``no_hit`` (NaN by default, the ``Scan`` convention). Cells outside the
grid are free space: rays may start outside and enter it.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
from scipy import ndimage

from slamkit._native import load_extension
from slamkit.errors import DataError
from slamkit.maps.occupancy_grid import OccupancyGrid


def _prepare(grid: OccupancyGrid, origins_xy_m: np.ndarray, angles_rad: np.ndarray):
    o = np.asarray(origins_xy_m, dtype=float).reshape(-1, 2)
    a = np.asarray(angles_rad, dtype=float).reshape(-1)
    if len(o) != len(a):
        raise DataError(f"cast_rays needs one angle per origin, got {len(o)} origins and {len(a)} angles")
    if not (np.all(np.isfinite(o)) and np.all(np.isfinite(a))):
        raise DataError("cast_rays got NaN or infinite origins or angles")
    return o, a


RAYCAST_MODULE = "slamkit.maps._raycast"


def native_raycast():
    """The compiled walk (``_raycast.c``), or None: then :class:`RayCaster` runs its numpy walk
    with the same results (``SLAMKIT_NO_NATIVE=1`` forces that)."""
    return load_extension(RAYCAST_MODULE)


class RayCaster:
    """Ray caster bound to one grid. Build once per map and cast repeatedly.

    With the compiled core each beam is walked cell by cell in C (``chunk`` and
    ``min_leap_cells`` then do not matter). The numpy fallback holds the grid's distance field
    (in cells, built with the caster when the compiled core is unavailable, else on the
    first numpy cast) so that rays can leap through open space (sphere
    tracing, Hart 1996) before walking the last cells exactly: every iteration, each active ray
    either leaps by the clearance of its current cell (which cannot skip an obstacle, see
    ``_tables``) when that is at least ``min_leap_cells``, or walks ``chunk`` exact cell steps."""

    def __init__(self, grid: OccupancyGrid, chunk: int = 8, min_leap_cells: float = 2.0):
        self.grid = grid
        self.chunk = max(1, int(chunk))
        self.min_leap_cells = float(min_leap_cells)
        #: "native" or "numpy": the walk the last :meth:`cast` used (None before the first)
        self.last_path: str | None = None
        # the compiled walk reads the grid as bytes (bool is one byte, 0 or 1)
        self._occ_bytes = memoryview(np.ascontiguousarray(grid.occupied).view(np.uint8)).cast("B")
        if native_raycast() is None:
            self._tables  # the numpy walk will need them: pay at build time, not in a cast

    @cached_property
    def _tables(self) -> tuple[np.ndarray, np.ndarray]:
        # Built on first use by the numpy walk only: the compiled walk needs no distance field.
        grid = self.grid
        occ = grid.occupied
        height, width = occ.shape
        if occ.any():
            clearance = ndimage.distance_transform_edt(~occ)
        else:
            # no obstacle anywhere: a finite leap past the grid diagonal keeps the counts finite
            clearance = np.full(occ.shape, float(2 * (height + width)))
        # A point anywhere in a cell is at most sqrt(2)/2 from its centre, and an occupied
        # cell reaches sqrt(2)/2 beyond its centre, so a ray that starts in a cell whose centre
        # is D cells from the nearest occupied centre cannot enter an obstacle before D - sqrt(2).
        # Both lookup tables get a one-cell free border so out-of-grid cells can be looked up
        # by clipping the index instead of masking (cells outside the grid are free; the leap
        # there is 0 because the field is unknown).
        leap = np.zeros((height + 2, width + 2))
        leap[1:-1, 1:-1] = np.maximum(clearance - math.sqrt(2.0) - 1e-9, 0.0)
        occ_pad = np.zeros((height + 2, width + 2), dtype=bool)
        occ_pad[1:-1, 1:-1] = occ
        return occ_pad.ravel(), leap.ravel()

    def cast(self, origins_xy_m: np.ndarray, angles_rad: np.ndarray, max_range_m: float,
             no_hit: float = np.nan) -> np.ndarray:
        """(N,) range in metres of N rays from ``origins_xy_m`` (N, 2) along world ``angles_rad``."""
        grid = self.grid
        origins, angles = _prepare(grid, origins_xy_m, angles_rad)
        n = len(origins)
        res = grid.resolution_m
        height, width = grid.occupied.shape
        max_t = float(max_range_m) / res  # the walk runs in cell units
        # both walks start from these doubles, so they agree bit for bit
        g = (origins - grid.origin_xy_m) / res
        dx, dy = np.cos(angles), np.sin(angles)
        if n == 0:
            return np.full(0, float(no_hit))
        native = native_raycast()
        if native is not None:
            d = np.column_stack([dx, dy])
            # ufunc results keep the input's memory order: a Fortran-ordered origins array
            # gives a Fortran-ordered g, so make it C-contiguous for the buffer (same values)
            g_c = np.ascontiguousarray(g)
            ranges = native.cast(self._occ_bytes, height, width, memoryview(g_c).cast("B"),
                                 memoryview(d).cast("B"), max_t, res, float(no_hit))
            if ranges is not None:
                self.last_path = "native"
                return np.frombuffer(ranges, dtype=np.float64)
        self.last_path = "numpy"
        out = np.full(n, float(no_hit))
        stride = width + 2
        occ_pad, leap_pad = self._tables
        ix0 = np.floor(g[:, 0]).astype(np.int64)
        iy0 = np.floor(g[:, 1]).astype(np.int64)
        stepx = np.where(dx > 0, 1, -1)
        stepy = np.where(dy > 0, 1, -1)
        with np.errstate(divide="ignore", invalid="ignore"):
            # A zero direction component never crosses a grid line: its crossings stay at +inf
            # (tdx = 0 keeps inf + n * tdx from turning into inf * 0 = NaN).
            tdx = np.where(dx != 0, 1.0 / np.abs(dx), 0.0)
            tdy = np.where(dy != 0, 1.0 / np.abs(dy), 0.0)
            tx0 = np.where(dx > 0, (ix0 + 1 - g[:, 0]) / dx,
                           np.where(dx < 0, (g[:, 0] - ix0) / -dx, np.inf))
            ty0 = np.where(dy > 0, (iy0 + 1 - g[:, 1]) / dy,
                           np.where(dy < 0, (g[:, 1] - iy0) / -dy, np.inf))
        # Leaving the grid for good: below/left of it moving away, or above/right moving away.
        x_lo_gone, x_hi_gone = dx <= 0, dx >= 0
        y_lo_gone, y_hi_gone = dy <= 0, dy >= 0

        def flat(ix, iy):
            # minimum/maximum rather than np.clip: clip's Python wrapper costs more than the
            # arithmetic on these array sizes
            return ((np.minimum(np.maximum(iy, -1), height) + 1) * stride
                    + np.minimum(np.maximum(ix, -1), width) + 1)

        start_hit = occ_pad[flat(ix0, iy0)]
        out[start_hit] = 0.0
        keep = ~start_hit & (max_t >= 0)
        # Compact per-ray state of the active rays: the walk is described by how many x and y
        # grid lines each ray has crossed (nx, ny) and the time of its last crossing (t_now).
        idx = np.nonzero(keep)[0]
        st = [arr[idx] for arr in (ix0, iy0, stepx, stepy, tx0, ty0, tdx, tdy,
                                   x_lo_gone, x_hi_gone, y_lo_gone, y_hi_gone)]
        nx = np.zeros(len(idx), dtype=np.int64)
        ny = np.zeros(len(idx), dtype=np.int64)
        t_now = np.zeros(len(idx))

        while idx.size:
            # Few stragglers (rays grazing walls) are better served by long walks: the cost of
            # an iteration is then numpy call overhead, not elements.
            k = self.chunk if len(idx) > 2048 else (4 * self.chunk if len(idx) > 256 else 16 * self.chunk)
            steps = np.arange(k)
            (ix0_, iy0_, sx_, sy_, tx0_, ty0_, tdx_, tdy_, xlo_, xhi_, ylo_, yhi_) = st
            # Rays with clearance leap (to the first crossing after t_now + clearance; counts can
            # only grow); the others walk k exact cells. One or the other per iteration: walking
            # right after a leap would mostly step through free cells.
            s = leap_pad[flat(ix0_ + sx_ * nx, iy0_ + sy_ * ny)]
            leaping = s >= self.min_leap_cells
            go_on = np.ones(len(idx), dtype=bool)
            if leaping.any():
                L = np.nonzero(leaping)[0]
                sL = s[L]
                for _ in range(4):  # a few leaps in a row: open space needs several
                    t_new = t_now[L] + sL
                    with np.errstate(invalid="ignore", divide="ignore"):
                        cx = np.where(tdx_[L] > 0, np.ceil((t_new - tx0_[L]) / tdx_[L]), 0.0)
                        cy = np.where(tdy_[L] > 0, np.ceil((t_new - ty0_[L]) / tdy_[L]), 0.0)
                    nx[L] = np.maximum(nx[L], cx.astype(np.int64))
                    ny[L] = np.maximum(ny[L], cy.astype(np.int64))
                    t_now[L] = t_new
                    beyond = t_new > max_t
                    go_on[L[beyond]] = False  # leapt past the maximum range: no hit
                    L = L[~beyond]
                    sL = leap_pad[flat(ix0_[L] + sx_[L] * nx[L], iy0_[L] + sy_[L] * ny[L])]
                    more = sL >= self.min_leap_cells
                    if not more.any():
                        break
                    L, sL = L[more], sL[more]
            W = ~leaping
            if W.any():
                nxw, nyw = nx[W], ny[W]
                tx = tx0_[W, None] + (nxw[:, None] + steps) * tdx_[W, None]
                ty = ty0_[W, None] + (nyw[:, None] + steps) * tdy_[W, None]
                times = np.concatenate([tx, ty], axis=1)
                order = np.argsort(times, axis=1, kind="stable")[:, :k]
                t_enter = np.take_along_axis(times, order, axis=1)
                is_x = order < k
                cx = nxw[:, None] + np.cumsum(is_x, axis=1)
                cy = nyw[:, None] + np.cumsum(~is_x, axis=1)
                ix = ix0_[W, None] + sx_[W, None] * cx
                iy = iy0_[W, None] + sy_[W, None] * cy
                hit = occ_pad[flat(ix, iy)] & (t_enter <= max_t)
                any_hit = hit.any(axis=1)
                rows = np.nonzero(any_hit)[0]
                w_idx = idx[W]
                out[w_idx[rows]] = t_enter[rows, np.argmax(hit[rows], axis=1)] * res
                lx, ly = ix[:, -1], iy[:, -1]
                gone = (((lx < 0) & xlo_[W]) | ((lx >= width) & xhi_[W])
                        | ((ly < 0) & ylo_[W]) | ((ly >= height) & yhi_[W]))
                go_on[W] = ~(any_hit | (t_enter[:, -1] > max_t) | gone)
                nx[W], ny[W], t_now[W] = cx[:, -1], cy[:, -1], t_enter[:, -1]
            idx = idx[go_on]
            st = [arr[go_on] for arr in st]
            nx, ny, t_now = nx[go_on], ny[go_on], t_now[go_on]
        return out

    def scan(self, world_xytheta_body: np.ndarray, body_angles_rad: np.ndarray,
             max_range_m: float, no_hit: float = np.nan,
             body_p_sensor_xy_m: np.ndarray | None = None) -> np.ndarray:
        """(P, B) ranges of B beams (angles in the body frame) from each of P poses (P, 3).

        ``body_p_sensor_xy_m`` offsets the sensor from the body origin (beams stay aligned with
        the body axes)."""
        poses = np.asarray(world_xytheta_body, dtype=float).reshape(-1, 3)
        beams = np.asarray(body_angles_rad, dtype=float).reshape(-1)
        origins = poses[:, :2].copy()
        if body_p_sensor_xy_m is not None:
            off = np.asarray(body_p_sensor_xy_m, dtype=float).reshape(2)
            c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
            origins += np.column_stack([c * off[0] - s * off[1], s * off[0] + c * off[1]])
        p, b = len(poses), len(beams)
        angles = (poses[:, 2:3] + beams[None, :]).reshape(-1)
        ranges = self.cast(np.repeat(origins, b, axis=0), angles, max_range_m, no_hit=no_hit)
        return ranges.reshape(p, b)


def cast_rays(grid: OccupancyGrid, origins_xy_m: np.ndarray, angles_rad: np.ndarray,
              max_range_m: float, no_hit: float = np.nan) -> np.ndarray:
    """One-off convenience: ``RayCaster(grid).cast(...)`` (build a RayCaster to cast repeatedly)."""
    return RayCaster(grid).cast(origins_xy_m, angles_rad, max_range_m, no_hit=no_hit)


def cast_scan(grid: OccupancyGrid, world_xytheta_body: np.ndarray, body_angles_rad: np.ndarray,
              max_range_m: float, no_hit: float = np.nan,
              body_p_sensor_xy_m: np.ndarray | None = None) -> np.ndarray:
    """One-off convenience: ``RayCaster(grid).scan(...)``."""
    return RayCaster(grid).scan(world_xytheta_body, body_angles_rad, max_range_m, no_hit,
                                body_p_sensor_xy_m)


def scan_endpoints(world_xytheta_body: np.ndarray, body_angles_rad: np.ndarray,
                   ranges_m: np.ndarray) -> np.ndarray:
    """(P, B, 2) world coordinates of beam end points (NaN where the range is NaN)."""
    poses = np.asarray(world_xytheta_body, dtype=float).reshape(-1, 3)
    r = np.asarray(ranges_m, dtype=float).reshape(len(poses), -1)
    ang = poses[:, 2:3] + np.asarray(body_angles_rad, dtype=float).reshape(1, -1)
    return np.stack([poses[:, 0:1] + r * np.cos(ang), poses[:, 1:2] + r * np.sin(ang)], axis=-1)


def cast_ray_loop(grid: OccupancyGrid, origin_xy_m: np.ndarray, angle_rad: float,
                  max_range_m: float, no_hit: float = np.nan) -> float:
    """One ray, one Python iteration per cell: the textbook Amanatides-Woo walk.

    The reference ``slamkit bench raycast`` compares against, and the oracle of the tests. It
    computes crossing times as ``t0 + n * dt`` (not by accumulation) and steps x first on ties,
    exactly as :func:`cast_rays`, so both return identical floats."""
    res = grid.resolution_m
    occ = grid.occupied
    height, width = occ.shape
    gx = (float(origin_xy_m[0]) - grid.origin_xy_m[0]) / res
    gy = (float(origin_xy_m[1]) - grid.origin_xy_m[1]) / res
    dx, dy = math.cos(angle_rad), math.sin(angle_rad)
    ix, iy = math.floor(gx), math.floor(gy)
    ix0, iy0 = ix, iy
    stepx = 1 if dx > 0 else -1
    stepy = 1 if dy > 0 else -1
    tdx = 1.0 / abs(dx) if dx != 0 else 0.0
    tdy = 1.0 / abs(dy) if dy != 0 else 0.0
    tx0 = (ix0 + 1 - gx) / dx if dx > 0 else ((gx - ix0) / -dx if dx < 0 else math.inf)
    ty0 = (iy0 + 1 - gy) / dy if dy > 0 else ((gy - iy0) / -dy if dy < 0 else math.inf)
    max_t = max_range_m / res
    nx = ny = 0
    t = 0.0
    while True:
        if 0 <= ix < width and 0 <= iy < height:
            if occ[iy, ix]:
                return t * res
        elif (ix < 0 and dx <= 0) or (ix >= width and dx >= 0) or (iy < 0 and dy <= 0) \
                or (iy >= height and dy >= 0):
            return float(no_hit)
        tx = tx0 + nx * tdx
        ty = ty0 + ny * tdy
        if tx <= ty:
            t = tx
            nx += 1
            ix = ix0 + stepx * nx
        else:
            t = ty
            ny += 1
            iy = iy0 + stepy * ny
        if t > max_t:
            return float(no_hit)


def cast_circles(origins_xy_m: np.ndarray, angles_rad: np.ndarray, centers_xy_m: np.ndarray,
                 radii_m: np.ndarray, max_range_m: float, no_hit: float = np.nan) -> np.ndarray:
    """(N,) range of N rays to the nearest of K discs (moving obstacles), vectorised over N x K.

    Solves |o + t d - c|^2 = R^2 for the smaller root t = b - sqrt(b^2 - |o - c|^2 + R^2) with
    b = d . (c - o); a ray starting inside a disc has range 0. Combine with the grid's ranges by
    ``np.fmin`` (NaN means no hit in either)."""
    origins = np.asarray(origins_xy_m, float).reshape(-1, 2)
    angles = np.asarray(angles_rad, float).reshape(-1)
    if len(origins) != len(angles):
        raise DataError(f"cast_circles needs one angle per origin, got {len(origins)} and {len(angles)}")
    c = np.asarray(centers_xy_m, float).reshape(-1, 2)
    r = np.asarray(radii_m, float).reshape(-1)
    out = np.full(len(origins), float(no_hit))
    if len(c) == 0 or len(origins) == 0:
        return out
    d = np.column_stack([np.cos(angles), np.sin(angles)])
    oc = c[None, :, :] - origins[:, None, :]                    # (N, K, 2)
    b = np.einsum("nkj,nj->nk", oc, d)
    q = np.einsum("nkj,nkj->nk", oc, oc) - r[None, :] ** 2      # > 0 outside the disc
    disc = b * b - q
    with np.errstate(invalid="ignore"):
        t = np.where(q <= 0, 0.0, b - np.sqrt(disc))
    valid = (q <= 0) | ((disc >= 0) & (t >= 0))
    t = np.where(valid & (t <= max_range_m), t, np.inf)
    best = t.min(axis=1)
    hit = np.isfinite(best)
    out[hit] = best[hit]
    return out
