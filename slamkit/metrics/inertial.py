"""Inertial-navigation scores: position error at withheld GPS fixes (drift during outages) and
the IMU bias estimation error against the simulator's true biases.

GPS outages (the usual way to score GPS/INS without independent ground truth; e.g. Groves,
*Principles of GNSS, Inertial, and Multisensor Integrated Navigation Systems*, 2nd ed., sec. 14.4):
the fixes inside each window were removed from the sequence (``slamkit.data.inertial.withhold_gps``)
and the estimate, linearly interpolated to each withheld fix's stamp, is compared with that fix.
The fix's own error (sigma ~ 0.26 m on KITTI) is part of the number.

Bias consistency: at every estimate stamp, each of the six bias components' error against the
truth divided by the estimator's sigma; ``bias_within_3sigma_fraction`` is the fraction of
(stamp, component) pairs with |error| <= 3 sigma (about 0.997 when consistent).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from slamkit.data.trajectory import Trajectory


def position_at(trajectory: Trajectory, stamps_s: np.ndarray) -> np.ndarray:
    """(K, 3) positions linearly interpolated at ``stamps_s`` (held constant outside the span)."""
    t = np.asarray(stamps_s, dtype=float)
    p = trajectory.world_t_body
    return np.column_stack([np.interp(t, trajectory.stamps_s, p[:, i]) for i in range(3)])


def withheld_fix_errors(trajectory: Trajectory, withheld: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """(K,) position errors (m) at the withheld fixes and (K,) their window index."""
    stamps = np.asarray(withheld["stamps_s"], dtype=float)
    if not len(stamps):
        return np.zeros(0), np.zeros(0, dtype=int)
    fixes = np.asarray(withheld["world_p_body"], dtype=float).reshape(-1, 3)
    err = np.linalg.norm(position_at(trajectory, stamps) - fixes, axis=1)
    return err, np.asarray(withheld["window"], dtype=int)


def outage_metrics(trajectory: Trajectory, withheld: Mapping[str, Any]) -> dict[str, float]:
    """``outage_rmse_m`` over every withheld fix, ``outage_end_error_mean_m`` the mean over
    windows of the error at each window's last withheld fix (the drift at the end of the
    outage), ``outage_max_error_m``, ``outage_windows``."""
    err, window = withheld_fix_errors(trajectory, withheld)
    if not len(err):
        return {}
    ends = [err[np.flatnonzero(window == w)[-1]] for w in np.unique(window)]
    return {"outage_rmse_m": float(np.sqrt(np.mean(err**2))), "outage_end_error_mean_m": float(np.mean(ends)),
            "outage_max_error_m": float(np.max(err)), "outage_windows": float(len(ends))}


def bias_metrics(stamps_s: np.ndarray, bias: np.ndarray, bias_sigma: np.ndarray | None,
                 truth: Mapping[str, Any]) -> dict[str, float]:
    """Errors of (N, 6) bias estimates (accel, gyro) at ``stamps_s`` against the truth
    (``stamps_s``, ``accel_mps2`` (M, 3), ``gyro_radps`` (M, 3)) taken at the nearest earlier
    true stamp: the final errors, their RMS over the second half, and the 3-sigma fraction."""
    t_true = np.asarray(truth["stamps_s"], dtype=float)
    true = np.column_stack([np.asarray(truth["accel_mps2"]), np.asarray(truth["gyro_radps"])])
    stamps = np.asarray(stamps_s, dtype=float)
    keep = stamps >= t_true[0]
    if not keep.any():
        return {}
    idx = np.clip(np.searchsorted(t_true, stamps[keep], side="right") - 1, 0, len(t_true) - 1)
    err = np.asarray(bias, dtype=float)[keep] - true[idx]
    half = err[len(err) // 2:]
    out = {"accel_bias_final_error_mps2": float(np.linalg.norm(err[-1, :3])),
           "gyro_bias_final_error_radps": float(np.linalg.norm(err[-1, 3:])),
           "accel_bias_rmse_mps2": float(np.sqrt(np.mean(np.sum(half[:, :3] ** 2, axis=1)))),
           "gyro_bias_rmse_radps": float(np.sqrt(np.mean(np.sum(half[:, 3:] ** 2, axis=1))))}
    if bias_sigma is not None:
        sigma = np.asarray(bias_sigma, dtype=float)[keep]
        ok = sigma > 0
        out["bias_within_3sigma_fraction"] = float(np.mean(np.abs(err[ok]) <= 3.0 * sigma[ok]))
    return out


def inertial_metrics(estimate, metadata: Mapping[str, Any]) -> dict[str, float]:
    """Outage metrics when the sequence withheld GPS, bias metrics when it knows the true biases."""
    out: dict[str, float] = {}
    if metadata.get("withheld_gps") is not None:
        out.update(outage_metrics(estimate.trajectory, metadata["withheld_gps"]))
    extras = estimate.extras or {}
    if metadata.get("true_imu_bias") is not None and extras.get("bias") is not None:
        out.update(bias_metrics(extras["bias_stamps_s"], extras["bias"], extras.get("bias_sigma"),
                                metadata["true_imu_bias"]))
    return out
