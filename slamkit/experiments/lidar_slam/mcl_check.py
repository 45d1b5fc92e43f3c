"""Global localization on a map the pipeline built (``mcl:``): MCL from a uniform prior on a
second tour through the same world, over several filter seeds (:class:`~.config.MclCheckConfig`)."""

from __future__ import annotations

import numpy as np

from slamkit.data.estimate import Prior
from slamkit.data.sequence import Scan, Sequence
from slamkit.errors import ConfigError
from slamkit.estimation._common import NoiseParams
from slamkit.estimation.lidar_mcl import LidarMCL
from slamkit.experiments.lidar_slam.config import MclCheckConfig
from slamkit.experiments.lidar_slam.slam import LidarSlamResult
from slamkit.geometry import se2


def localize_on_map(result: LidarSlamResult, sequence: Sequence, config: MclCheckConfig = MclCheckConfig()
                    ) -> dict[str, float]:
    """Run :class:`slamkit.estimation.lidar_mcl.LidarMCL` on ``result.map`` along ``sequence``
    once per filter seed (see :class:`MclCheckConfig`); ``mcl_success_rate``: the fraction of
    runs that end localized and stay so (within ``max_updates``); ``mcl_converged_after_updates``:
    the median, over those runs, of the number of scan updates after which the estimate stays
    localized (NaN if none); ``mcl_final_error_m``: the median final position error;
    ``mcl_updates``: updates scored per run; ``mcl_runs``. Scoring stops where the true robot
    leaves the part of the world the map observed (a map cannot localize a robot in rooms it
    never saw); the filter starts, from the uniform prior, at the first scan taken inside it."""
    if sequence.ground_truth is None:
        raise ConfigError("localize_on_map needs a sequence with ground truth")
    runs = np.array([_localize_once(result, sequence, config, config.filter_seed + k)
                     for k in range(config.filter_seeds)])
    after, final_m, updates = runs.T
    ok = np.isfinite(after)
    return {"mcl_success_rate": float(ok.mean()),
            "mcl_converged_after_updates": float(np.median(after[ok])) if ok.any() else float("nan"),
            "mcl_final_error_m": float(np.median(final_m)), "mcl_updates": float(updates.max()),
            "mcl_runs": float(len(runs))}


def _localize_once(result: LidarSlamResult, sequence: Sequence, config: MclCheckConfig, filter_seed: int
                   ) -> tuple[float, float, float]:
    """One MCL run: (updates until it stays localized or NaN, final position error (m), updates)."""
    mcl = LidarMCL(result.map.occupancy_grid(), NoiseParams.from_metadata(sequence.metadata),
                   rng=np.random.default_rng(filter_seed), free_mask=result.map.observed)
    mcl.reset(Prior(np.zeros(3), np.eye(3)))
    gt = sequence.ground_truth
    known = result.map.observed & ~result.map.occupancy_grid().occupied
    good: list[bool] = []
    err = np.full(3, np.nan)
    started = False
    for ev in sequence:
        if isinstance(ev, Scan):
            truth = gt.xytheta()[min(np.searchsorted(gt.stamps_s, ev.stamp_s - 1e-9), len(gt) - 1)]
            cell = np.floor((truth[:2] - result.map.origin_xy_m) / result.map.resolution_m).astype(int)
            inside = 0 <= cell[0] < known.shape[1] and 0 <= cell[1] < known.shape[0]
            if inside and known[cell[1], cell[0]]:
                started = True  # the uniform prior starts here: odometry before it is moot
            elif started:
                break
        if not started:
            continue
        mcl.step(ev)
        if isinstance(ev, Scan):
            err = se2.between(truth, mcl.estimate().trajectory.xytheta()[-1])
            good.append(bool(np.hypot(err[0], err[1]) < config.position_tol_m
                             and abs(err[2]) < config.heading_tol_rad))
            if len(good) >= config.max_updates:
                break
    ok = np.array(good, dtype=bool)
    bad = np.flatnonzero(~ok)
    after = float("nan") if (len(ok) == 0 or not ok[-1]) else float(bad[-1] + 1 if len(bad) else 0)
    return after, float(np.hypot(err[0], err[1])), float(len(ok))
