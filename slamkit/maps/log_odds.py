"""Log-odds occupancy grid mapping with an inverse sensor model for 2D lidar, and map quality
against a ground-truth grid.

Mapping with known poses: Thrun, Burgard & Fox, *Probabilistic Robotics* (2005), Table 9.1
(``occupancy_grid_mapping``) and Table 9.2 (``inverse_range_sensor_model``). Each cell keeps

    l_t = l_{t-1} + inverse_sensor_model(m_i, x_t, z_t) - l_0            (eq. 9.7)

clamped to [l_min, l_max] so a cell can change its mind after a moved object (the clamping of
OctoMap, Hornung et al., Autonomous Robots 34(3), 2013, sec. 3.2).

Inverse sensor model used here (Table 9.2, with obstacle thickness alpha = one cell): along
every beam with a return, the cells the beam crosses up to ``free_margin_cells`` (one cell)
before its end point are *free* (``l_free`` < 0) and the cell just behind the end point is
*occupied* (``l_occ`` > 0). "Just behind": slamkit's lidar measures the range to the boundary
where the beam *enters* the obstacle (``slamkit.maps.raycast``), so the obstacle cell lies beyond
the end point; the hit is placed ``hit_offset_cells`` (half a cell) further along the beam, which
puts it in the right cell even with a few centimetres of range noise, and the free margin keeps
that noise from clearing the obstacle cell the beam just entered. Beams without a return (NaN) or at max range
update nothing by default: a max-range reading from the beam model's z_max mixture component
would otherwise carve free space through a wall.

Per scan a cell is updated at most once (hits take precedence over free space), so many beams
crossing the same cell near the robot do not count as many independent observations.

Vectorised over beams: the free cells are found by sampling every beam at ``sample_step_cells``
(a quarter cell) and scattering the samples' cell indices into one boolean mask per scan; no
Python loop over beams or cells. A sample step of a quarter cell misses only cells a beam clips
by less than a quarter cell at a corner, which the neighbouring beams cover.

Map quality (:func:`map_quality`): the estimated map is thresholded (occupied where
p > ``occupied_probability``), the ground truth is resampled onto the estimated map's cells
(a map cell is truly occupied when any ground-truth cell whose centre falls in it is occupied),
and both are compared *on the observed cells only* (cells whose log-odds was changed by at
least one update). Precision = TP / (TP + FP), recall = TP / (TP + FN), IoU = TP / (TP + FP + FN).
Unobserved cells (wall interiors, rooms never entered) carry no information and are excluded.
With ``tolerance_cells`` = t > 0 an occupied cell of either map counts as matched when the other
map has an occupied cell within t cells (Chebyshev distance): precision = estimated occupied cells
with a true one within t / estimated occupied cells; recall = true occupied cells with an
estimated one within t / true occupied cells; TP (in IoU) counts the matched true cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_dilation

from slamkit.errors import ConfigError, DataError
from slamkit.maps.occupancy_grid import OccupancyGrid


def probability_to_log_odds(p: np.ndarray | float) -> np.ndarray:
    p = np.asarray(p, dtype=float)
    return np.log(p / (1.0 - p))


def log_odds_to_probability(l: np.ndarray | float) -> np.ndarray:
    # 1 / (1 + exp(-l)) written so that large |l| neither overflows nor loses precision
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(l, dtype=float)))


@dataclass(frozen=True)
class LogOddsConfig:
    """Inverse-sensor-model increments (log-odds) and clamping bounds; p = 0.7 / 0.4 per hit /
    pass-through and clamping at p in [0.12, 0.97] are OctoMap's defaults."""

    resolution_m: float = 0.05
    l_occ: float = 0.85
    l_free: float = -0.4
    l_min: float = -2.0
    l_max: float = 3.5
    #: the hit is placed this many cells beyond the measured end point (see module docstring)
    hit_offset_cells: float = 0.5
    #: free space ends this many cells before the measured end point (Table 9.2's alpha / 2),
    #: so range noise does not clear the obstacle cell the beam just entered
    free_margin_cells: float = 1.0
    #: free-space samples per cell along a beam = 1 / sample_step_cells
    sample_step_cells: float = 0.25
    #: when True, NaN / max-range beams mark free space up to ``max_range_m`` (off by default)
    free_on_no_return: bool = False
    #: threshold (probability) above which a cell counts as occupied in ``occupancy_grid``
    occupied_probability: float = 0.5

    def __post_init__(self) -> None:
        if not (self.resolution_m > 0 and np.isfinite(self.resolution_m)):
            raise ConfigError(f"LogOddsConfig.resolution_m must be > 0, got {self.resolution_m}")
        if not (self.l_occ > 0 and self.l_free < 0):
            raise ConfigError(f"LogOddsConfig needs l_occ > 0 > l_free, got {self.l_occ}, {self.l_free}")
        if not (self.l_min < 0 < self.l_max):
            raise ConfigError(f"LogOddsConfig needs l_min < 0 < l_max, got {self.l_min}, {self.l_max}")
        if not (0 < self.sample_step_cells <= 1):
            raise ConfigError(f"LogOddsConfig.sample_step_cells must lie in (0, 1], got {self.sample_step_cells}")
        if not (0 < self.occupied_probability < 1):
            raise ConfigError("LogOddsConfig.occupied_probability must lie in (0, 1)")


class LogOddsMap:
    """A log-odds grid (engine: holds and mutates its cells). ``log_odds[iy, ix]``, same cell
    convention as :class:`~slamkit.maps.occupancy_grid.OccupancyGrid`."""

    def __init__(self, shape_hw: tuple[int, int], origin_xy_m=(0.0, 0.0),
                 config: LogOddsConfig = LogOddsConfig()):
        h, w = int(shape_hw[0]), int(shape_hw[1])
        if h <= 0 or w <= 0:
            raise ConfigError(f"LogOddsMap shape must be positive, got {shape_hw}")
        self.config = config
        self.resolution_m = config.resolution_m
        self.origin_xy_m = np.asarray(origin_xy_m, dtype=float).reshape(2)
        self.log_odds = np.zeros((h, w))
        self.observed = np.zeros((h, w), dtype=bool)
        self.num_scans = 0

    @classmethod
    def covering(cls, lo_xy_m, hi_xy_m, config: LogOddsConfig = LogOddsConfig()) -> "LogOddsMap":
        """A map whose cells cover the box [lo, hi] (origin snapped to the resolution)."""
        lo = np.floor(np.asarray(lo_xy_m, float) / config.resolution_m) * config.resolution_m
        hi = np.asarray(hi_xy_m, float)
        w, h = np.ceil((hi - lo) / config.resolution_m - 1e-9).astype(int)
        return cls((max(h, 1), max(w, 1)), lo, config)

    @classmethod
    def like(cls, grid: OccupancyGrid, config: LogOddsConfig = LogOddsConfig()) -> "LogOddsMap":
        """A map covering the same area as ``grid`` at ``config.resolution_m``."""
        hi = grid.origin_xy_m + np.array([grid.width, grid.height]) * grid.resolution_m
        return cls.covering(grid.origin_xy_m, hi, config)

    @property
    def shape(self) -> tuple[int, int]:
        return self.log_odds.shape

    def probability(self) -> np.ndarray:
        return log_odds_to_probability(self.log_odds)

    def occupancy_grid(self, occupied_probability: float | None = None, name: str = "log_odds_map"
                       ) -> OccupancyGrid:
        """Thresholded map (occupied where p > threshold; unknown cells count as free)."""
        p = self.config.occupied_probability if occupied_probability is None else occupied_probability
        return OccupancyGrid(self.log_odds > float(probability_to_log_odds(p)), self.resolution_m,
                             self.origin_xy_m.copy(), name=name)

    def _flat_cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points (N, 2) -> (flat index of the points inside the map, inside mask)."""
        c = np.floor((xy - self.origin_xy_m) / self.resolution_m).astype(np.int64)
        h, w = self.log_odds.shape
        ok = (c[:, 0] >= 0) & (c[:, 0] < w) & (c[:, 1] >= 0) & (c[:, 1] < h)
        return c[ok, 1] * w + c[ok, 0], ok

    def scan_cells(self, world_xytheta_sensor, angles_rad, ranges_m, max_range_m: float
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Flat indices of the (free, occupied) cells one scan updates (each cell once, hits
        take precedence). ``angles_rad`` are in the sensor frame; NaN range = no return."""
        cfg = self.config
        pose = np.asarray(world_xytheta_sensor, dtype=float).reshape(3)
        a = np.asarray(angles_rad, dtype=float).reshape(-1)
        r = np.asarray(ranges_m, dtype=float).reshape(-1)
        if a.shape != r.shape:
            raise DataError(f"scan has {len(a)} angles but {len(r)} ranges")
        hit = np.isfinite(r) & (r < max_range_m) & (r >= 0)
        margin = cfg.free_margin_cells * self.resolution_m
        free_len = np.where(hit, r - margin, max_range_m if cfg.free_on_no_return else 0.0)
        free_len = np.where(np.isfinite(free_len), free_len, 0.0)
        world_a = pose[2] + a
        d = np.column_stack([np.cos(world_a), np.sin(world_a)])
        step = cfg.sample_step_cells * self.resolution_m
        n_steps = int(np.ceil(free_len.max(initial=0.0) / step))
        # samples at t = 0, step, ... strictly before the end point, all beams at once
        t = np.arange(n_steps) * step
        keep = t[None, :] < free_len[:, None]  # (B, S)
        bi, si = np.nonzero(keep)
        pts = pose[:2] + d[bi] * t[si, None]
        free_idx, _ = self._flat_cells(pts)
        hit_pts = pose[:2] + d[hit] * (r[hit] + cfg.hit_offset_cells * self.resolution_m)[:, None]
        occ_idx, _ = self._flat_cells(hit_pts)
        size = self.log_odds.size
        occ_mask = np.zeros(size, dtype=bool)
        occ_mask[occ_idx] = True
        free_mask = np.zeros(size, dtype=bool)
        free_mask[free_idx] = True
        free_mask &= ~occ_mask
        return np.flatnonzero(free_mask), np.flatnonzero(occ_mask)

    def update(self, world_xytheta_sensor, angles_rad, ranges_m, max_range_m: float) -> None:
        """Integrate one scan taken from the sensor pose ``world_xytheta_sensor`` (eq. 9.7)."""
        cfg = self.config
        free, occ = self.scan_cells(world_xytheta_sensor, angles_rad, ranges_m, max_range_m)
        flat = self.log_odds.reshape(-1)
        flat[free] = np.maximum(flat[free] + cfg.l_free, cfg.l_min)
        flat[occ] = np.minimum(flat[occ] + cfg.l_occ, cfg.l_max)
        obs = self.observed.reshape(-1)
        obs[free] = True
        obs[occ] = True
        self.num_scans += 1

    def integrate(self, world_xytheta_sensors: np.ndarray, angles_rad: np.ndarray,
                  ranges_m: np.ndarray, max_range_m: float) -> "LogOddsMap":
        """Integrate scans (N, B) from poses (N, 3) in order; returns self."""
        poses = np.asarray(world_xytheta_sensors, dtype=float).reshape(-1, 3)
        rs = np.asarray(ranges_m, dtype=float).reshape(len(poses), -1)
        for pose, r in zip(poses, rs):  # one vectorised update per scan
            self.update(pose, angles_rad, r, max_range_m)
        return self


def build_map(world_xytheta_sensors: np.ndarray, angles_rad: np.ndarray, ranges_m: np.ndarray,
              max_range_m: float, template: OccupancyGrid | None = None,
              config: LogOddsConfig = LogOddsConfig(), margin_m: float = 1.0) -> LogOddsMap:
    """Map from known (or estimated) sensor poses. The map covers ``template``'s area when
    given, else the poses' extent grown by ``max_range_m`` and ``margin_m``."""
    poses = np.asarray(world_xytheta_sensors, dtype=float).reshape(-1, 3)
    if template is not None:
        m = LogOddsMap.like(template, config)
    else:
        reach = max_range_m + margin_m
        m = LogOddsMap.covering(poses[:, :2].min(axis=0) - reach, poses[:, :2].max(axis=0) + reach, config)
    return m.integrate(poses, angles_rad, ranges_m, max_range_m)


def resample_to(truth: OccupancyGrid, shape_hw: tuple[int, int], origin_xy_m: np.ndarray,
                resolution_m: float) -> np.ndarray:
    """(H, W) bool: a target cell is occupied when any ``truth`` cell whose centre falls in it is
    occupied (max-pooling; exact when the resolutions are integer multiples)."""
    h, w = shape_hw
    iy, ix = np.nonzero(truth.occupied)
    centres = truth.cell_to_world(np.column_stack([ix, iy]))
    c = np.floor((centres - np.asarray(origin_xy_m, float)) / resolution_m).astype(np.int64)
    ok = (c[:, 0] >= 0) & (c[:, 0] < w) & (c[:, 1] >= 0) & (c[:, 1] < h)
    out = np.zeros((h, w), dtype=bool)
    out[c[ok, 1], c[ok, 0]] = True
    return out


@dataclass(frozen=True)
class MapQuality:
    """Occupied-cell agreement on the observed cells (see the module docstring)."""

    precision: float
    recall: float
    iou: float
    true_positives: int
    false_positives: int
    false_negatives: int
    observed_cells: int

    def as_metrics(self, prefix: str = "map_") -> dict[str, float]:
        return {f"{prefix}precision": self.precision, f"{prefix}recall": self.recall,
                f"{prefix}iou": self.iou, f"{prefix}observed_cells": float(self.observed_cells)}


def map_quality(estimate: LogOddsMap, truth: OccupancyGrid,
                occupied_probability: float | None = None, tolerance_cells: int = 0) -> MapQuality:
    """Precision, recall and IoU of the thresholded ``estimate`` against ``truth`` on the cells
    ``estimate`` observed, a match allowed ``tolerance_cells`` away (see the module docstring)."""
    if tolerance_cells < 0:
        raise ConfigError(f"map_quality: tolerance_cells must be >= 0, got {tolerance_cells}")
    pred = estimate.occupancy_grid(occupied_probability).occupied
    gt = resample_to(truth, estimate.shape, estimate.origin_xy_m, estimate.resolution_m)
    obs = estimate.observed
    near_gt, near_pred = gt, pred
    if tolerance_cells:
        window = np.ones((2 * tolerance_cells + 1,) * 2, dtype=bool)
        near_gt, near_pred = binary_dilation(gt, window), binary_dilation(pred, window)
    matched_pred = int(np.sum(pred & near_gt & obs))
    tp = int(np.sum(gt & near_pred & obs))
    fp = int(np.sum(pred & ~near_gt & obs))
    fn = int(np.sum(gt & ~near_pred & obs))
    nan = float("nan")
    return MapQuality(
        precision=matched_pred / (matched_pred + fp) if matched_pred + fp else nan,
        recall=tp / (tp + fn) if tp + fn else nan,
        iou=tp / (tp + fp + fn) if tp + fp + fn else nan,
        true_positives=tp, false_positives=fp, false_negatives=fn, observed_cells=int(obs.sum()),
    )
