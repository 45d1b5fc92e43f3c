"""Relative pose error (RPE) with evo's semantics.

Sturm et al., IROS 2012, sec. V-A, eq. 1: for index pairs (i, j) the error pose is
E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) with Q the reference and P the estimate; the translation
error is ||t(E_ij)|| and the rotation error the angle of R(E_ij). Pairs are chosen as in
``evo.core.filters``:

* ``delta_unit='frames'``: consecutive pairs (0, d), (d, 2d), ... or with ``all_pairs`` every
  (i, i + d);
* ``delta_unit='m'``: consecutive pairs where the travelled path first reaches ``delta`` metres
  (counted from zero after each pair), or with ``all_pairs`` for every i the j > i whose path
  length from i is closest to ``delta``, kept if within ``rel_delta_tol * delta``.

Paths are measured on the (aligned) estimate, as evo does by default, or on the reference with
``pairs_from_reference=True``. Alignment only matters for ``sim3`` (scale) and path-based pairs;
it is applied first, as ``evo_rpe --align`` does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.geometry import se3, so3
from slamkit.metrics.alignment import AlignMode, AlignmentResult, align
from slamkit.metrics.stats import ErrorStats

DeltaUnit = Literal["frames", "m"]
DELTA_UNITS = ("frames", "m")


@dataclass(frozen=True)
class RpeResult:
    translation_m: ErrorStats
    rotation_rad: ErrorStats
    rotation_deg: ErrorStats
    errors_m: np.ndarray
    errors_rad: np.ndarray
    pairs: np.ndarray  # (K, 2) index pairs (i, j)
    delta: float
    delta_unit: str
    all_pairs: bool
    alignment: AlignmentResult

    @property
    def num_pairs(self) -> int:
        return len(self.pairs)


def pairs_by_index(n: int, delta: int, all_pairs: bool = False) -> np.ndarray:
    """Index pairs ``delta`` frames apart (evo ``filter_pairs_by_index``)."""
    if all_pairs:
        i = np.arange(max(n - delta, 0))
        return np.column_stack([i, i + delta]).astype(np.int64)
    ids = np.arange(0, n, delta)
    return np.column_stack([ids[:-1], ids[1:]]).astype(np.int64)


def pairs_by_path(positions: np.ndarray, delta_m: float, tol_m: float = 0.0,
                  all_pairs: bool = False) -> np.ndarray:
    """Index pairs ``delta_m`` metres of travelled path apart (evo ``filter_pairs_by_path``)."""
    positions = np.asarray(positions, dtype=float)
    n = len(positions)
    if n < 2:
        return np.zeros((0, 2), np.int64)
    steps = np.linalg.norm(positions[:-1] - positions[1:], axis=1)
    if not all_pairs:
        # The running sum restarts at each chosen pose, so this is inherently sequential; it is
        # one float add per pose.
        ids = [0]
        current = 0.0
        for k, step in enumerate(steps.tolist(), start=1):
            current += step
            if current >= delta_m:
                ids.append(k)
                current = 0.0
        ids_arr = np.asarray(ids, dtype=np.int64)
        return np.column_stack([ids_arr[:-1], ids_arr[1:]])
    cum = np.concatenate([[0.0], np.cumsum(steps)])
    i = np.arange(n - 1)
    # evo: argmin over j > i of |cum[j] - cum[i] - delta| (first minimum). cum is sorted, so
    # the minimum is at the first index >= the target or at the first index of the value just
    # below it.
    target = cum[i] + delta_m
    upper = np.clip(np.searchsorted(cum, target, side="left"), i + 1, n - 1)
    below = np.maximum(upper - 1, i + 1)
    below = np.maximum(np.searchsorted(cum, cum[below], side="left"), i + 1)
    err_upper = np.abs(cum[upper] - cum[i] - delta_m)
    err_below = np.abs(cum[below] - cum[i] - delta_m)
    j = np.where(err_below <= err_upper, below, upper)
    err = np.minimum(err_below, err_upper)
    keep = err <= tol_m
    return np.column_stack([i[keep], j[keep]]).astype(np.int64)


def relative_errors(ref: Trajectory, est: Trajectory, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Translation (m) and rotation (rad) of E_ij for every pair."""
    Q, P = ref.matrices(), est.matrices()
    i, j = pairs[:, 0], pairs[:, 1]
    E = se3.between(se3.between(Q[i], Q[j]), se3.between(P[i], P[j]))
    return np.linalg.norm(E[:, :3, 3], axis=1), so3.angle(E[:, :3, :3])


def rpe(ref: Trajectory, est: Trajectory, delta: float = 1, delta_unit: DeltaUnit = "frames",
        all_pairs: bool = False, align_mode: AlignMode = "none", n_first: int | None = None,
        rel_delta_tol: float = 0.1, pairs_from_reference: bool = False) -> RpeResult:
    """RPE of ``est`` against ``ref`` (associated, same length)."""
    if delta_unit not in DELTA_UNITS:
        raise DataError(f"unknown delta unit {delta_unit!r}; use one of {DELTA_UNITS}")
    if delta <= 0:
        raise DataError(f"delta must be positive, got {delta}")
    alignment = align(est, ref, align_mode, n_first)
    aligned = alignment.aligned
    if delta_unit == "frames":
        if float(delta) != int(delta):
            raise DataError(f"delta must be an integer number of frames, got {delta}")
        pairs = pairs_by_index(len(ref), int(delta), all_pairs)
    else:
        source = ref if pairs_from_reference else aligned
        pairs = pairs_by_path(source.world_t_body, float(delta), float(delta) * rel_delta_tol, all_pairs)
    if len(pairs) == 0:
        raise DataError(f"delta = {delta} {delta_unit} produced no pose pairs among {len(ref)} poses; "
                        "use a smaller delta")
    e_m, e_rad = relative_errors(ref, aligned, pairs)
    return RpeResult(
        translation_m=ErrorStats.from_errors(e_m), rotation_rad=ErrorStats.from_errors(e_rad),
        rotation_deg=ErrorStats.from_errors(np.rad2deg(e_rad)), errors_m=e_m, errors_rad=e_rad,
        pairs=pairs, delta=float(delta), delta_unit=delta_unit, all_pairs=all_pairs,
        alignment=alignment,
    )
