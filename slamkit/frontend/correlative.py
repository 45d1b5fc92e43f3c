"""Correlative scan matching (Olson, "Real-time correlative scan matching", ICRA 2009): an
exhaustive search over a window of (dx, dy, dtheta) around a guess, scoring every candidate pose
by how well the moved scan points land on a likelihood grid of the target, so it finds the
global optimum of that window instead of the local one ICP converges to. Used as ICP's initial
guess when the prediction is poor (lidar only: a robot that turned 30-50 deg between two scans).

* Likelihood grid: the target points are rasterised at ``resolution_m`` (``slamkit.maps``
  occupancy grid), the Euclidean distance field d of that grid (``slamkit.maps.distance_field``)
  gives every cell the likelihood exp(-d^2 / (2 sigma^2)) of a return there (the likelihood-field
  model; Olson sec. III). The grid extends ``margin_m`` beyond the target so that moved points
  within the window stay on it; points that leave it score 0.
* Score of a candidate: the mean likelihood of the cells its moved source points fall in (1: every
  point on a target point's cell, 0: none near).
* Candidates: headings ``guess + k * theta_step_rad`` within +- ``window_theta_rad``; for each, the
  source is rotated once and translated by whole cells (dx, dy = i * resolution_m within
  +- ``window_xy_m``), so a translation is an index shift (Olson sec. IV-A), vectorised with numpy
  over every heading and offset.
* Multi-resolution (Olson sec. IV-B): a low-resolution grid whose cell (iy, ix) holds the maximum
  likelihood of the ``coarse_factor`` x ``coarse_factor`` block of fine cells starting there. A
  coarse candidate (heading, block of offsets) scored on it bounds the score of every fine
  candidate of its block from above, so the blocks are visited best bound first, each searched
  exhaustively at full resolution, until the next bound is no better than the best fine score:
  the result is the exhaustive optimum over the whole candidate set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.frontend.icp import finite_points_xy
from slamkit.geometry.angles import wrap_angle
from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.occupancy_grid import OccupancyGrid


#: the correlative search's translation window, cells each side of the guess (at most)
MAX_WINDOW_CELLS = 200


@dataclass(frozen=True)
class CorrelativeConfig:
    resolution_m: float = 0.05
    #: the likelihood's standard deviation (metres)
    sigma_m: float = 0.05
    #: translation window: dx, dy within +- this of the guess
    window_xy_m: float = 0.5
    #: heading window: dtheta within +- this of the guess
    window_theta_rad: float = float(np.deg2rad(45.0))
    theta_step_rad: float = float(np.deg2rad(0.5))
    #: fine cells per coarse cell along each axis (1: a single exhaustive level)
    coarse_factor: int = 4

    def __post_init__(self) -> None:
        if not (self.resolution_m > 0 and self.sigma_m > 0 and self.theta_step_rad > 0):
            raise ConfigError("CorrelativeConfig: resolution_m, sigma_m and theta_step_rad must be > 0")
        if self.window_xy_m < 0 or not 0 <= self.window_theta_rad <= np.pi:
            raise ConfigError("CorrelativeConfig: window_xy_m must be >= 0 and window_theta_rad in [0, pi]")
        if self.window_xy_m > MAX_WINDOW_CELLS * self.resolution_m:
            # the search scores every cell of the window at every heading: 10 m at 5 cm is
            # already 1.6e5 offsets a heading
            raise ConfigError(f"CorrelativeConfig: window_xy_m {self.window_xy_m:g} m is more than "
                              f"{MAX_WINDOW_CELLS} cells of {self.resolution_m:g} m each side")
        if self.coarse_factor < 1:
            raise ConfigError(f"CorrelativeConfig.coarse_factor must be >= 1, got {self.coarse_factor}")


@dataclass(frozen=True)
class CorrelativeResult:
    """The best candidate ``target_T_source`` and its score (mean likelihood, in [0, 1])."""

    target_T_source: np.ndarray
    score: float
    candidates_scored: int


def likelihood_field(target_xy: np.ndarray, resolution_m: float, sigma_m: float, margin_m: float,
                     what: str = "scan-matching") -> tuple[OccupancyGrid, np.ndarray]:
    """The target points rasterised at ``resolution_m`` (cell boundaries on multiples of it, the
    grid reaching ``margin_m`` beyond the points) and the likelihood field exp(-d^2 / 2 sigma^2)
    of a return in every cell, d its distance to the nearest target cell (Olson sec. III).
    Non-finite points are dropped; no finite point is a DataError naming ``what``."""
    pts = finite_points_xy(target_xy, f"{what} target")
    res = resolution_m
    origin = np.floor((pts.min(axis=0) - margin_m) / res) * res
    size = np.ceil((pts.max(axis=0) + margin_m - origin) / res).astype(np.int64) + 1
    occ = np.zeros((size[1], size[0]), dtype=bool)
    cells = OccupancyGrid(occ, res, origin).world_to_cell(pts)
    occ[cells[:, 1], cells[:, 0]] = True
    grid = OccupancyGrid(occ, res, origin)
    return grid, np.exp(-0.5 * (distance_field_m(grid) / sigma_m) ** 2)


class CorrelativeGrid:
    """The likelihood grid of a target point set (and its max-pooled coarse level)."""

    def __init__(self, target_xy: np.ndarray, config: CorrelativeConfig = CorrelativeConfig(),
                 margin_m: float | None = None):
        self.config = config
        margin = (config.window_xy_m + 4.0 * config.sigma_m + config.resolution_m if margin_m is None
                  else margin_m)
        self.grid, self.likelihood = likelihood_field(target_xy, config.resolution_m, config.sigma_m,
                                                      margin, "correlative")
        f = config.coarse_factor
        padded = np.pad(self.likelihood, ((0, f - 1), (0, f - 1)))
        h, w = self.likelihood.shape
        self.coarse = np.max([padded[a:a + h, b:b + w] for a in range(f) for b in range(f)], axis=0)


def _lookup(table: np.ndarray, iy: np.ndarray, ix: np.ndarray) -> np.ndarray:
    h, w = table.shape
    ok = (iy >= 0) & (iy < h) & (ix >= 0) & (ix < w)
    return np.where(ok, table[np.clip(iy, 0, h - 1), np.clip(ix, 0, w - 1)], 0.0)


def correlative_search(source_xy: np.ndarray, grid: CorrelativeGrid, guess: np.ndarray,
                       config: CorrelativeConfig | None = None) -> CorrelativeResult:
    """The candidate of the window around ``guess`` (target_T_source, (3,)) with the highest
    score (see the module docstring); ties go to the candidate closest to the guess."""
    cfg = grid.config if config is None else config
    if cfg.resolution_m != grid.config.resolution_m or cfg.coarse_factor != grid.config.coarse_factor:
        raise ConfigError("correlative_search: the config's resolution and coarse factor must be the grid's")
    src = finite_points_xy(source_xy, "correlative source")
    g = np.asarray(guess, dtype=float).reshape(3)
    res, f = cfg.resolution_m, cfg.coarse_factor
    k = int(np.floor(cfg.window_theta_rad / cfg.theta_step_rad + 1e-9))
    dthetas = np.arange(-k, k + 1) * cfg.theta_step_rad
    n = int(np.floor(cfg.window_xy_m / res + 1e-9))
    # every heading's source points in the target's cells at offset (0, 0): (T, N)
    c, s = np.cos(g[2] + dthetas)[:, None], np.sin(g[2] + dthetas)[:, None]
    x = c * src[:, 0] - s * src[:, 1] + g[0]
    y = s * src[:, 0] + c * src[:, 1] + g[1]
    ix = np.floor((x - grid.grid.origin_xy_m[0]) / res).astype(np.int64)
    iy = np.floor((y - grid.grid.origin_xy_m[1]) / res).astype(np.int64)
    # coarse level: blocks of f x f offsets starting at -n, -n + f, ... (T, B, B)
    starts = np.arange(-n, n + 1, f)
    upper = _lookup(grid.coarse, iy[:, :, None, None] + starts[None, None, :, None],
                    ix[:, :, None, None] + starts[None, None, None, :]).mean(axis=1)
    order = np.argsort(-upper, axis=None, kind="stable")
    fine = np.arange(f)
    best_score, best, scored = -1.0, (k, n, n), upper.size
    for flat in order:
        t, by, bx = np.unravel_index(flat, upper.shape)
        if upper[t, by, bx] < best_score:
            break
        oy, ox = starts[by] + fine, starts[bx] + fine
        oy, ox = oy[oy <= n], ox[ox <= n]
        scores = _lookup(grid.likelihood, iy[t][:, None, None] + oy[None, :, None],
                         ix[t][:, None, None] + ox[None, None, :]).mean(axis=0)
        scored += scores.size
        # the best of the block, the one closest to the guess among equals
        dist = (t - k) ** 2 + oy[:, None] ** 2 + ox[None, :] ** 2
        j = np.lexsort((dist.ravel(), -scores.ravel()))[0]
        sc = float(scores.ravel()[j])
        cand = (int(t), int(oy[j // len(ox)]), int(ox[j % len(ox)]))
        if sc > best_score or (sc == best_score and _closer(cand, best, k)):
            best_score, best = sc, cand
    t, oy, ox = best
    pose = np.array([g[0] + ox * res, g[1] + oy * res, wrap_angle(g[2] + dthetas[t])])
    return CorrelativeResult(pose, best_score, scored)


def _closer(a: tuple[int, int, int], b: tuple[int, int, int], k: int) -> bool:
    return (a[0] - k) ** 2 + a[1] ** 2 + a[2] ** 2 < (b[0] - k) ** 2 + b[1] ** 2 + b[2] ** 2
