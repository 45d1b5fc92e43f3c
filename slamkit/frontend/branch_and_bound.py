"""Global scan-to-submap matching by branch and bound over precomputed multi-resolution max grids
(Olson, "Real-time correlative scan matching", ICRA 2009, sec. IV; Hess, Kohler, Rapp, Andor,
"Real-time loop closure in 2D LIDAR SLAM", ICRA 2016, sec. V, Algorithms 2-3): the pose of a
scan within a window of metres and tens of degrees around a guess, with no assumption that the
guess is close -- the loop-closure matcher that finds a revisit however far the estimate drifted
inside the window.

* Score of a candidate pose: the sum, over the source points, of the quantised likelihood of the
  cell the moved point falls in (the likelihood field exp(-d^2 / (2 sigma^2)) of the target's
  distance field d, as ``slamkit.frontend.correlative``, quantised to integers 0..``LEVELS``),
  reported as the mean in [0, 1]. Integer sums are exact, so "the same optimum as an exhaustive
  search" is a statement about one function, independent of summation order.
* Candidates (Hess et al. eq. 5-7): headings ``guess + k * theta_step`` within +-``window_theta``
  (the step from the scan's farthest point d_max, acos(1 - r^2 / (2 d_max^2)), so that one step
  moves no point by more than a cell, unless given), and whole-cell translations
  (dx, dy) = (i, j) * r within +-``window_xy`` of the guess: each heading is rotated once and a
  translation is an index shift.
* Bounds (Hess et al. sec. V-C, eq. 14-15): the precomputed grid of height h holds, in cell
  (y, x), the maximum of the likelihood over the 2^h x 2^h block of cells starting there. A
  node (heading, offset block of 2^h x 2^h translations) scored on it is an upper bound of the
  score of every candidate of its block.
* Search (Hess et al. Algorithm 3): depth first from the top height, children visited best bound
  first; a node is pruned when its bound is below the best score found so far (or below
  ``min_score``). The tie rule of the exhaustive reference (equal scores: the candidate closest
  to the guess, then the lowest heading, y, x index) is kept by also descending into nodes whose
  bound equals the best score when they hold a candidate closer to the guess. The result is
  therefore exactly the exhaustive search's (``exhaustive_search``, tested on real and synthetic
  scans).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from slamkit._native import load_extension
from slamkit.errors import ConfigError
from slamkit.frontend.correlative import CorrelativeResult, likelihood_field
from slamkit.frontend.icp import finite_points_xy
from slamkit.geometry.angles import wrap_angle

#: blocks of at most 2^h x 2^h candidates are scored whole at full resolution instead of descending
#: (scan-matching bench, CPU time per search: 18 ms at 0, 22 ms at 1, 20 ms at 2, 29 ms at 3)
LEAF_BLOCK_HEIGHT = 0
#: the compiled descent (``_bnbkernel.c``; the same search as ``_descend_python``)
KERNEL_MODULE = "slamkit.frontend._bnbkernel"
#: the likelihood 1.0 in the integer grids (Cartographer stores probabilities as 15-bit integers too)
LEVELS = 32767


@dataclass(frozen=True)
class BranchAndBoundConfig:
    resolution_m: float = 0.05
    #: the likelihood field's standard deviation (metres)
    sigma_m: float = 0.05
    #: translation window: dx, dy within +- this of the guess
    window_xy_m: float = 3.0
    #: heading window: dtheta within +- this of the guess
    window_theta_rad: float = float(np.deg2rad(20.0))
    #: heading step; None: from the scan's range (Hess et al. eq. 7)
    theta_step_rad: float | None = None
    #: heights of the max-grid pyramid (the top nodes are 2^(depth - 1) cells on a side)
    depth: int = 7
    #: candidates scoring below this (mean likelihood) are not returned
    min_score: float = 0.5

    def __post_init__(self) -> None:
        if not (self.resolution_m > 0 and self.sigma_m > 0):
            raise ConfigError("BranchAndBoundConfig: resolution_m and sigma_m must be > 0")
        if self.theta_step_rad is not None and not self.theta_step_rad > 0:
            raise ConfigError(f"BranchAndBoundConfig.theta_step_rad must be > 0, got {self.theta_step_rad}")
        if self.window_xy_m < 0 or not 0 <= self.window_theta_rad <= np.pi:
            raise ConfigError("BranchAndBoundConfig: window_xy_m must be >= 0 and window_theta_rad in [0, pi]")
        if not 1 <= self.depth <= 12:
            raise ConfigError(f"BranchAndBoundConfig.depth must lie in [1, 12], got {self.depth}")
        if not 0 <= self.min_score <= 1:
            raise ConfigError(f"BranchAndBoundConfig.min_score must lie in [0, 1], got {self.min_score}")


class MaxGridPyramid:
    """The target's quantised likelihood grid and its max grids of heights 0..depth-1, padded so
    that an index clipped into the array reads 0 whenever the block it stands for is off the
    grid: ``2^(depth-1)`` zero cells before the data (a block starting further out cannot reach
    it) and one after (the last cell's blocks are all zeros)."""

    def __init__(self, target_xy: np.ndarray, config: BranchAndBoundConfig = BranchAndBoundConfig()):
        self.config = config
        res = config.resolution_m
        # beyond 4 sigma the likelihood quantises to ~0: the grid need not reach further
        grid, likelihood = likelihood_field(target_xy, res, config.sigma_m, 4.0 * config.sigma_m + res,
                                            "branch-and-bound")
        origin = grid.origin_xy_m
        q = np.rint(LEVELS * likelihood).astype(np.int32)
        pad = 2 ** (config.depth - 1)
        base = np.pad(q, ((pad, 1), (pad, 1)))
        self.origin_xy_m = origin - pad * res
        self.shape = base.shape
        # every height in one (depth, H, W) array: the compiled descent reads them all
        self.stack = np.zeros((config.depth,) + base.shape, dtype=np.int32)
        self.stack[0] = base
        H, W = base.shape
        for h in range(1, config.depth):
            s = 2 ** (h - 1)
            prev = np.pad(self.stack[h - 1], ((0, s), (0, s)))
            self.stack[h] = np.maximum(np.maximum(prev[:H, :W], prev[s:s + H, :W]),
                                       np.maximum(prev[:H, s:s + W], prev[s:s + H, s:s + W]))
        self.levels = list(self.stack)
        self._flat = [lv.ravel() for lv in self.levels]

    def sums(self, height: int, iy: np.ndarray, ix: np.ndarray) -> np.ndarray:
        """Integer score sums at ``height`` of cell indices (..., N) (summed over the last axis)."""
        H, W = self.shape
        # np.minimum/np.maximum: np.clip's argument handling costs more than the lookup here
        flat = np.minimum(np.maximum(iy, 0), H - 1) * W + np.minimum(np.maximum(ix, 0), W - 1)
        return self._flat[height][flat].sum(axis=-1, dtype=np.int64)


@dataclass
class _Problem:
    """A search's discretisation: the cells of every heading's points at offset (0, 0)."""

    guess: np.ndarray
    dthetas: np.ndarray
    n: int                  # offsets -n..n cells
    k: int                  # the guess's heading index
    iy: np.ndarray          # (T, N)
    ix: np.ndarray
    min_sum: int


def theta_step_for(source_xy: np.ndarray, resolution_m: float) -> float:
    """Hess et al. eq. 7: the heading step that moves the farthest point by one cell."""
    d_max = float(np.max(np.hypot(source_xy[:, 0], source_xy[:, 1])))
    if d_max <= resolution_m:
        return float(np.pi / 8)
    return float(np.arccos(1.0 - resolution_m ** 2 / (2.0 * d_max ** 2)))


def _problem(source_xy: np.ndarray, pyramid: MaxGridPyramid, guess: np.ndarray,
             cfg: BranchAndBoundConfig) -> _Problem:
    if cfg.resolution_m != pyramid.config.resolution_m or cfg.depth > pyramid.config.depth \
            or cfg.sigma_m != pyramid.config.sigma_m:
        raise ConfigError("branch and bound: the config's resolution, sigma and depth must be the pyramid's")
    src = finite_points_xy(source_xy, "branch-and-bound source")
    g = np.asarray(guess, dtype=float).reshape(3)
    res = cfg.resolution_m
    step = cfg.theta_step_rad if cfg.theta_step_rad is not None else theta_step_for(src, res)
    k = int(np.floor(cfg.window_theta_rad / step + 1e-9))
    dthetas = np.arange(-k, k + 1) * step
    n = int(np.floor(cfg.window_xy_m / res + 1e-9))
    c, s = np.cos(g[2] + dthetas)[:, None], np.sin(g[2] + dthetas)[:, None]
    x = c * src[:, 0] - s * src[:, 1] + g[0]
    y = s * src[:, 0] + c * src[:, 1] + g[1]
    ix = np.floor((x - pyramid.origin_xy_m[0]) / res).astype(np.int64)
    iy = np.floor((y - pyramid.origin_xy_m[1]) / res).astype(np.int64)
    min_sum = int(np.ceil(cfg.min_score * LEVELS * len(src) - 1e-9))
    return _Problem(g, dthetas, n, k, iy, ix, min_sum)


def _result(p: _Problem, best: tuple[int, int, int] | None, best_sum: int, res_m: float,
            scored: int) -> CorrelativeResult | None:
    if best is None:
        return None
    t, oy, ox = best
    pose = np.array([p.guess[0] + ox * res_m, p.guess[1] + oy * res_m, wrap_angle(p.guess[2] + p.dthetas[t])])
    return CorrelativeResult(pose, best_sum / (LEVELS * p.ix.shape[1]), scored)


def _rank(t: int, oy: int, ox: int, k: int) -> tuple[int, int, int, int]:
    """The tie order among equal scores (smaller first): squared distance to the guess in steps
    and cells, then heading, y and x index."""
    return ((t - k) ** 2 + oy * oy + ox * ox, t, oy, ox)


def exhaustive_search(source_xy: np.ndarray, pyramid: MaxGridPyramid, guess: np.ndarray,
                      config: BranchAndBoundConfig | None = None) -> CorrelativeResult | None:
    """The reference: every candidate of the window scored at full resolution; the best (ties:
    ``_rank``), None when none reaches ``min_score``."""
    cfg = pyramid.config if config is None else config
    p = _problem(source_xy, pyramid, guess, cfg)
    off = np.arange(-p.n, p.n + 1)
    best, best_sum, scored = None, p.min_sum, 0
    best_rank = None
    for t in range(len(p.dthetas)):
        sums = pyramid.sums(0, p.iy[t][None, None, :] + off[:, None, None],
                            p.ix[t][None, None, :] + off[None, :, None])
        scored += sums.size
        top = int(sums.max())
        if top < best_sum:
            continue
        for a, b in zip(*np.nonzero(sums == top)):
            r = _rank(t, int(off[a]), int(off[b]), p.k)
            if top > best_sum or best_rank is None or r < best_rank:
                best, best_sum, best_rank = (t, int(off[a]), int(off[b])), top, r
    return _result(p, best, best_sum, cfg.resolution_m, scored)


def branch_and_bound_search(source_xy: np.ndarray, pyramid: MaxGridPyramid, guess: np.ndarray,
                            config: BranchAndBoundConfig | None = None) -> CorrelativeResult | None:
    """The best candidate of the window around ``guess`` (target_T_source) by depth-first branch
    and bound (module docstring): the exhaustive search's result, with ``candidates_scored``
    counting the nodes scored at every height. None when no candidate reaches ``min_score``.
    The descent runs in the compiled kernel (``_bnbkernel.c``) when it is built, else in
    :func:`_descend_python`; both visit the same nodes in the same order."""
    cfg = pyramid.config if config is None else config
    p = _problem(source_xy, pyramid, guess, cfg)
    n, top_h = p.n, cfg.depth - 1
    size = 2 ** top_h
    starts = np.arange(-n, n + 1, size)
    bounds = pyramid.sums(top_h, p.iy[:, None, None, :] + starts[None, :, None, None],
                          p.ix[:, None, None, :] + starts[None, None, :, None])      # (T, B, B)
    flat = np.argsort(-bounds, axis=None, kind="stable")
    tt, yy, xx = np.unravel_index(flat, bounds.shape)
    top_bounds = bounds[tt, yy, xx]
    keep = top_bounds >= p.min_sum
    top_bounds, tt, yy, xx = top_bounds[keep], tt[keep], starts[yy[keep]], starts[xx[keep]]
    kernel = _kernel()
    if kernel is None:
        best, best_sum, scored = _descend_python(pyramid, p, top_bounds, tt, yy, xx, top_h)
    else:
        H, W = pyramid.shape
        i64 = np.int64
        found, t, oy, ox, best_sum, scored = kernel.descend(
            pyramid.stack, cfg.depth, H, W, np.ascontiguousarray(p.iy, dtype=i64),
            np.ascontiguousarray(p.ix, dtype=i64), p.iy.shape[0], p.iy.shape[1], n, p.k, top_h,
            LEAF_BLOCK_HEIGHT, p.min_sum, np.ascontiguousarray(top_bounds, dtype=i64),
            np.ascontiguousarray(tt, dtype=i64), np.ascontiguousarray(yy, dtype=i64),
            np.ascontiguousarray(xx, dtype=i64), len(tt))
        best = (t, oy, ox) if found else None
    return _result(p, best, best_sum, cfg.resolution_m, bounds.size + scored)


def _kernel():
    """The compiled descent (``slamkit.frontend._bnbkernel``), or None: not built, or
    ``SLAMKIT_NO_NATIVE`` set."""
    return load_extension(KERNEL_MODULE)


def _descend_python(pyramid: MaxGridPyramid, p: _Problem, top_bounds: np.ndarray, tt: np.ndarray,
                    yy: np.ndarray, xx: np.ndarray, top_h: int) -> tuple[tuple[int, int, int] | None, int, int]:
    """The depth-first descent from the top-height nodes (``top_bounds`` with their heading and
    offsets, best bound first): (best (t, oy, ox) or None, its integer score sum, nodes scored
    below the top height). The reference of the compiled kernel."""
    n, k = p.n, p.k
    state = {"best": None, "sum": p.min_sum, "rank": None, "scored": 0}

    def min_rank_dist(t: int, oy: int, ox: int, h: int) -> int:
        # the smallest squared distance to the guess of any candidate in the block
        def axis(o: int) -> int:
            hi = min(o + 2 ** h - 1, n)
            return 0 if o <= 0 <= hi else min(abs(o), abs(hi))
        return (t - k) ** 2 + axis(oy) ** 2 + axis(ox) ** 2

    def worth(bound: int, t: int, oy: int, ox: int, h: int) -> bool:
        if bound > state["sum"] or (bound == state["sum"] and state["best"] is None):
            return True
        return bound == state["sum"] and min_rank_dist(t, oy, ox, h) <= state["rank"][0]

    def descend(cands: list[tuple[int, int, int, int]], h: int) -> None:
        for bound, t, oy, ox in cands:
            if bound < state["sum"]:
                return      # sorted best bound first: no later node can win
            if not worth(bound, t, oy, ox, h):
                continue
            if h <= LEAF_BLOCK_HEIGHT:
                leaves(t, oy, ox, h)
                continue
            half = 2 ** (h - 1)
            kids = [(oy + a, ox + b) for a in (0, half) for b in (0, half) if oy + a <= n and ox + b <= n]
            ky = np.array([c[0] for c in kids])
            kx = np.array([c[1] for c in kids])
            sums = pyramid.sums(h - 1, p.iy[t][None, :] + ky[:, None], p.ix[t][None, :] + kx[:, None])
            state["scored"] += len(kids)
            order = np.argsort(-sums, kind="stable")
            descend([(int(sums[i]), t, int(ky[i]), int(kx[i])) for i in order], h - 1)

    def leaves(t: int, oy: int, ox: int, h: int) -> None:
        # every candidate of a small block at full resolution in one step (fewer Python calls than
        # descending through its heights; the same candidates win)
        ys = np.arange(oy, min(oy + 2 ** h, n + 1))
        xs = np.arange(ox, min(ox + 2 ** h, n + 1))
        gy, gx = np.meshgrid(ys, xs, indexing="ij")
        gy, gx = gy.ravel(), gx.ravel()
        sums = pyramid.sums(0, p.iy[t][None, :] + gy[:, None], p.ix[t][None, :] + gx[:, None])
        state["scored"] += len(sums)
        top = int(sums.max())
        if top < state["sum"]:
            return
        for a in np.flatnonzero(sums == top):
            r = _rank(t, int(gy[a]), int(gx[a]), k)
            if top > state["sum"] or state["rank"] is None or r < state["rank"]:
                state.update(best=(t, int(gy[a]), int(gx[a])), sum=top, rank=r)

    descend([(int(b), int(t), int(y), int(x)) for b, t, y, x in zip(top_bounds, tt, yy, xx)], top_h)
    return state["best"], state["sum"], state["scored"]


def rival_search(source_xy: np.ndarray, pyramid: MaxGridPyramid, guess: np.ndarray, best_T_source: np.ndarray,
                 min_score: float, exclusion_m: float, config: BranchAndBoundConfig | None = None,
                 chunk: int = 4096) -> CorrelativeResult | None:
    """The best candidate of the window around ``guess`` (every heading) whose translation lies
    more than ``exclusion_m`` from ``best_T_source``'s and that scores at least ``min_score``, or
    None: a second place the scan fits (almost) as well as at the optimum -- the optimum is then
    one of several aliases (a row of equal doors, a corridor's repeated bays), not a place.

    Breadth first over the same max-grid bounds as :func:`branch_and_bound_search`: a node is
    dropped when its bound is below ``min_score`` or every candidate of its block lies within
    ``exclusion_m`` of the optimum; at height 0 the survivors are exactly the qualifying
    candidates (integer sums: exact, independent of order), and the best of them is returned
    (ties: ``_rank``). ``candidates_scored`` counts the nodes scored."""
    cfg = pyramid.config if config is None else config
    p = _problem(source_xy, pyramid, guess, replace(cfg, min_score=float(np.clip(min_score, 0.0, 1.0))))
    res = cfg.resolution_m
    n, top_h = p.n, cfg.depth - 1
    b = (np.asarray(best_T_source, float)[:2] - p.guess[:2]) / res
    by, bx = float(b[1]), float(b[0])
    r2 = (exclusion_m / res) ** 2
    size = 2 ** top_h
    starts = np.arange(-n, n + 1, size)
    T = len(p.dthetas)
    t, oy, ox = (a.ravel() for a in np.meshgrid(np.arange(T), starts, starts, indexing="ij"))
    scored = 0
    for h in range(top_h, -1, -1):
        s = 2 ** h
        # the block's farthest candidate from the optimum (blocks are clipped to the window)
        hy, hx = np.minimum(oy + s - 1, n), np.minimum(ox + s - 1, n)
        far_y = np.maximum(np.abs(oy - by), np.abs(hy - by))
        far_x = np.maximum(np.abs(ox - bx), np.abs(hx - bx))
        keep = far_y ** 2 + far_x ** 2 > r2
        t, oy, ox = t[keep], oy[keep], ox[keep]
        sums = np.empty(len(t), dtype=np.int64)
        for a in range(0, len(t), chunk):
            sl = slice(a, a + chunk)
            sums[sl] = pyramid.sums(h, p.iy[t[sl]] + oy[sl, None], p.ix[t[sl]] + ox[sl, None])
        scored += len(t)
        keep = sums >= p.min_sum
        t, oy, ox, sums = t[keep], oy[keep], ox[keep], sums[keep]
        if h == 0:
            keep = (oy - by) ** 2 + (ox - bx) ** 2 > r2
            t, oy, ox, sums = t[keep], oy[keep], ox[keep], sums[keep]
            break
        half = s // 2
        kids_y = np.concatenate([oy, oy, oy + half, oy + half])
        kids_x = np.concatenate([ox, ox + half, ox, ox + half])
        kids_t = np.concatenate([t, t, t, t])
        inside = (kids_y <= n) & (kids_x <= n)
        t, oy, ox = kids_t[inside], kids_y[inside], kids_x[inside]
    if len(t) == 0:
        return None
    top = int(sums.max())
    best = min((_rank(int(t[a]), int(oy[a]), int(ox[a]), p.k) for a in np.flatnonzero(sums == top)))
    return _result(p, (best[1], best[2], best[3]), top, res, scored)
