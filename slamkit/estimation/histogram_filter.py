"""Grid (histogram) Bayes filter for planar localization on a landmark map.

Thrun, Burgard & Fox, *Probabilistic Robotics*, Table 4.1 (discrete Bayes filter) and section
8.2 (grid localization). The belief is a probability per cell of an (x, y, theta) grid.

* Predict = deterministic shift + blur. The odometry since the last grid update is composed
  into one relative motion delta (exact arc of ``slamkit.models.diff_drive``); every target cell
  T takes the (trilinearly interpolated) mass of its source pose T o delta^-1 in one
  ``scipy.ndimage.map_coordinates`` call over the whole grid (the heading axis padded for
  wrap-around), then a separable Gaussian blur (``scipy.ndimage.gaussian_filter``) spreads it
  by the accumulated velocity noise. Small motions are accumulated until they move the belief
  by half a cell (or a measurement arrives), which keeps interpolation smearing down --
  Probabilistic Robotics section 8.2.4 discusses exactly this failure of fine-step updates.
* Update = multiply by the measurement likelihood evaluated at every cell centre at once. Range
  and absolute bearing do not depend on the heading, so they are computed on the (x, y) plane
  and the heading enters only through bearing = absolute bearing - theta. The noise is
  widened by the cell size (a cell centre is up to half a cell from the pose it stands for).

Memory and time are O(cells) per step; there is no per-cell Python.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy.ndimage import gaussian_filter, map_coordinates

from slamkit.data.estimate import Prior
from slamkit.data.sequence import Odometry, RangeBearing
from slamkit.errors import ConfigError
from slamkit.estimation._common import (
    FilterBase,
    NoiseParams,
    landmark_array,
    observation_rows,
    weighted_pose_mean_cov,
)
from slamkit.geometry import se2
from slamkit.geometry.angles import wrap_angle
from slamkit.models import diff_drive, range_bearing


_TWO_PI = 2.0 * np.pi
_SUPPORT_FLOOR = 1e-12


@dataclass(frozen=True)
class HistogramFilterConfig:
    resolution_m: float = 0.25
    n_headings: int = 36
    #: grid = landmark bounding box grown by this margin, unless bounds_xy_m is given
    map_margin_m: float = 2.0
    #: (x_min, y_min, x_max, y_max)
    bounds_xy_m: tuple[float, float, float, float] | None = None
    #: uniform initial belief instead of the prior
    global_init: bool = False
    #: shift the grid once the pending motion reaches this many cells (or half a heading bin)
    min_shift_cells: float = 0.5

    def __post_init__(self) -> None:
        if not self.resolution_m > 0 or self.n_headings < 4:
            raise ConfigError(f"need resolution_m > 0 and n_headings >= 4, got {self.resolution_m}, "
                              f"{self.n_headings}")


class HistogramFilter(FilterBase):
    """Grid localization (registry name ``histogram``) on a known landmark map."""

    name = "histogram"

    def __init__(self, world_p_landmarks: Mapping[int, np.ndarray], noise: NoiseParams = NoiseParams(),
                 config: HistogramFilterConfig = HistogramFilterConfig()) -> None:
        super().__init__()
        self.landmark_ids, self.landmarks = landmark_array(world_p_landmarks)
        if len(self.landmark_ids) == 0:
            raise ConfigError("histogram filter needs a non-empty landmark map")
        self._index = {int(i): k for k, i in enumerate(self.landmark_ids)}
        self.noise, self.config = noise, config
        res = config.resolution_m
        if config.bounds_xy_m is not None:
            x0, y0, x1, y1 = config.bounds_xy_m
        else:
            (x0, y0), (x1, y1) = (self.landmarks.min(0) - config.map_margin_m,
                                  self.landmarks.max(0) + config.map_margin_m)
        self.origin = np.array([x0, y0])
        self.nx, self.ny = int(np.ceil((x1 - x0) / res)), int(np.ceil((y1 - y0) / res))
        self.nth = config.n_headings
        self.bin_rad = 2 * np.pi / self.nth
        self.xs = x0 + (np.arange(self.nx) + 0.5) * res
        self.ys = y0 + (np.arange(self.ny) + 0.5) * res
        self.thetas = -np.pi + (np.arange(self.nth) + 0.5) * self.bin_rad
        X, Y, TH = np.meshgrid(self.xs, self.ys, self.thetas, indexing="ij")
        self.cell_poses = np.stack([X, Y, TH], axis=-1)                  # (nx, ny, nth, 3)
        xy0 = np.stack([X[..., 0], Y[..., 0], np.zeros_like(X[..., 0])], axis=-1)
        # range and absolute bearing (pose heading 0) of every landmark from every (x, y) cell
        # centre: fixed for a fixed map, so computed once
        self._plane = np.asarray(range_bearing.observe(xy0[:, :, None, :], self.landmarks[None, None]),
                                 dtype=float)                              # (nx, ny, L, 2)
        # discretisation variance of a uniform position inside a cell / heading inside a bin
        self._cell_var = res**2 / 12.0
        self._bin_var = self.bin_rad**2 / 12.0

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.nx, self.ny, self.nth

    # -- filter steps ------------------------------------------------------------------------
    def _reset(self, prior: Prior) -> None:
        if self.config.global_init:
            bel = np.ones(self.shape)
        else:
            cov = prior.covariance + np.diag([self._cell_var, self._cell_var, self._bin_var])
            d = self.cell_poses - prior.world_xytheta_body
            d[..., 2] = wrap_angle(d[..., 2])
            bel = np.exp(-0.5 * np.einsum("...i,ij,...j->...", d, np.linalg.inv(cov), d))
            if bel.sum() == 0:
                raise ConfigError("histogram filter: the prior lies outside the grid")
        self.belief = bel / bel.sum()
        self._delta = np.zeros(3)          # motion not yet applied to the grid (body frame)
        self._var_v = 0.0                  # accumulated velocity-noise variance of that motion
        self._var_w = 0.0

    def _predict(self, odometry: Odometry) -> None:
        u = np.array([odometry.v_mps, odometry.omega_radps])
        self._delta = np.asarray(diff_drive.motion(self._delta, u, odometry.dt_s), dtype=float)
        self._var_v += (self.noise.sigma_v_mps * odometry.dt_s) ** 2
        self._var_w += (self.noise.sigma_omega_radps * odometry.dt_s) ** 2
        shift_cells = np.hypot(*self._delta[:2]) / self.config.resolution_m
        if shift_cells >= self.config.min_shift_cells or abs(self._delta[2]) >= 0.5 * self.bin_rad:
            self._apply_motion()

    def _apply_motion(self) -> None:
        if not np.any(self._delta) and self._var_v == 0.0:
            return
        res = self.config.resolution_m
        # T o delta^-1 for every cell: the offset depends on the cell's heading only, so compose
        # once per heading bin and broadcast over (x, y)
        heading_poses = np.column_stack([np.zeros((self.nth, 2)), self.thetas])
        offsets = se2.compose(heading_poses, se2.inverse(self._delta))           # (nth, 3)
        fx = ((self.xs[:, None, None] + offsets[None, None, :, 0]) - self.origin[0]) / res - 0.5
        fy = ((self.ys[None, :, None] + offsets[None, None, :, 1]) - self.origin[1]) / res - 0.5
        ft = (offsets[:, 2] + np.pi) / self.bin_rad - 0.5 + 1.0                  # +1: padded axis
        fx, fy, ft = np.broadcast_arrays(fx, fy, np.broadcast_to(ft, (1, 1, self.nth)))
        padded = np.concatenate([self.belief[..., -1:], self.belief, self.belief[..., :1]], axis=2)
        moved = map_coordinates(padded, [fx, fy, ft], order=1, mode="constant", cval=0.0)
        # Blur by the velocity noise of the accumulated motion: along-track sigma_v dt per step,
        # across-track the heading noise times the distance travelled.
        dist = np.hypot(*self._delta[:2])
        sigma_xy = np.sqrt(self._var_v + 0.5 * dist**2 * self._var_w) / res
        sigma_th = np.sqrt(self._var_w) / self.bin_rad
        if max(sigma_xy, sigma_th) > 0.05:
            moved = gaussian_filter(moved, sigma=(sigma_xy, sigma_xy, sigma_th),
                                    mode=("constant", "constant", "wrap"), truncate=3.0)
        total = moved.sum()
        # all mass left the grid: keep the old belief rather than divide by zero
        self.belief = moved / total if total > 0 else self.belief
        self._delta = np.zeros(3)
        self._var_v = self._var_w = 0.0

    def _update(self, observation: RangeBearing) -> None:
        ids, zs = observation_rows(observation)
        self._apply_motion()
        plane = self._plane
        var_r = self.noise.sigma_range_m**2 + 2 * self._cell_var
        # Evaluate the likelihood only on the belief's support (cells above a 1e-12 relative
        # floor, the rest are set to zero): after convergence that is a few percent of the grid.
        support = self.belief > _SUPPORT_FLOOR * self.belief.max()
        ixy = np.flatnonzero(support.any(axis=2))                 # (x, y) columns with mass
        ix, iy = np.unravel_index(ixy, (self.nx, self.ny))
        plane = plane[ix, iy]                                      # (C, L, 2)
        log_lik = np.zeros((len(ixy), self.nth))
        used = 0
        prior_w = self.belief[ix, iy]                             # (C, nth)
        prior_w = prior_w / prior_w.sum()
        for lid, z in zip(ids.tolist(), zs):
            if lid >= 0:
                k = self._index.get(lid)
                if k is None:
                    continue
                log_lik += self._log_likelihood(plane[:, k], z, var_r)
                self._record_predictive_nis(plane[:, k], z, prior_w)
            else:
                # unknown correspondence: most likely landmark per cell
                per_lm = np.stack([self._log_likelihood(plane[:, k], z, var_r)
                                   for k in range(len(self.landmarks))])
                log_lik += per_lm.max(axis=0)
            used += 1
        if used == 0:
            return
        posterior = np.zeros(self.shape)
        posterior[ix, iy] = self.belief[ix, iy] * np.exp(log_lik - log_lik.max())
        total = posterior.sum()
        if total > 0:
            self.belief = posterior / total

    def _log_likelihood(self, plane_k: np.ndarray, z: np.ndarray, var_r: float) -> np.ndarray:
        """(C, nth) log-likelihood of one measurement of one landmark at C (x, y) columns."""
        r, b_abs = plane_k[..., 0], plane_k[..., 1]
        var_b = (self.noise.sigma_bearing_rad**2 + self._bin_var
                 + 2 * self._cell_var / np.maximum(r, self.config.resolution_m) ** 2)
        lr = -0.5 * (z[0] - r) ** 2 / var_r
        d = (z[1] - b_abs)[..., None] + self.thetas           # z - (b_abs - theta)
        # only the square of the wrapped residual matters, so the floor form (3x cheaper than
        # the canonical [-pi, pi) wrap on this hot path) is enough
        d -= _TWO_PI * np.floor((d + np.pi) / _TWO_PI)
        lb = -0.5 * d * d / var_b[..., None] - 0.5 * np.log(var_b)[..., None]
        return lr[..., None] + lb

    def _record_predictive_nis(self, plane_k: np.ndarray, z: np.ndarray, w: np.ndarray) -> None:
        """NIS of z under the belief's predictive distribution of the measurement (moments over
        cells, circular on the bearing, plus the measurement noise)."""
        r = np.broadcast_to(plane_k[:, 0, None], w.shape)
        b = plane_k[:, 1, None] - self.thetas
        r_mean = float(np.sum(w * r))
        b_mean = float(np.arctan2(np.sum(w * np.sin(b)), np.sum(w * np.cos(b))))
        dr = r - r_mean
        db = b - b_mean
        db -= _TWO_PI * np.floor((db + np.pi) / _TWO_PI)
        S = np.array([[np.sum(w * dr * dr), np.sum(w * dr * db)],
                      [np.sum(w * dr * db), np.sum(w * db * db)]]) + self.noise.range_bearing_cov
        nu = np.array([z[0] - r_mean, wrap_angle(z[1] - b_mean)])
        self._record_nis(nu, S)

    def _pose_and_covariance(self) -> tuple[np.ndarray, np.ndarray]:
        w = self.belief.reshape(-1)
        keep = w > 1e-12 * w.max()  # the statistics only need cells with mass
        mean, cov = weighted_pose_mean_cov(self.cell_poses.reshape(-1, 3)[keep], w[keep])
        cov = cov + np.diag([self._cell_var, self._cell_var, self._bin_var])
        if np.any(self._delta):
            mean = se2.compose(mean, self._delta)
        return mean, cov
