"""Relation error (Kuemmerle et al., "On measuring the accuracy of SLAM algorithms", Autonomous
Robots 27(4), 2009): SLAM scored by relative displacements that the benchmark's authors verified
by hand, instead of a global ground truth.

For every relation (t1, t2, delta*) -- delta* the pose at t2 expressed in the frame at t1 -- the
estimate's displacement is delta = T(t1)^-1 T(t2), and the error is delta* ^-1 delta (the paper's
delta (-) delta*). Reported: mean and standard deviation of its translational part |t| (m) and
rotational part |theta| (deg), the same for the squared errors (the paper's Table 2 lists both),
and how many relations found estimate poses at both stamps (nearest stamp within
``tolerance_s``; the relation stamps are the FLASER ipc timestamps, and an estimate written at
those stamps matches to < 0.1 ms, so 1 ms is the default).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from slamkit._text import number_rows
from slamkit.errors import DataError
from slamkit.geometry import se2
from slamkit.metrics.stats import ErrorStats

DEFAULT_TOLERANCE_S = 1e-3


@dataclass(frozen=True)
class Relations:
    """(K,) t1, t2 and (K, 3) displacements (x, y, yaw) of the pose at t2 in the frame at t1."""

    t1_s: np.ndarray
    t2_s: np.ndarray
    delta_xytheta: np.ndarray


@dataclass(frozen=True)
class RelationErrors:
    translation_m: ErrorStats
    rotation_deg: ErrorStats
    translation_sq_m2: ErrorStats
    rotation_sq_deg2: ErrorStats
    matched: int
    unmatched: int
    errors_m: np.ndarray
    errors_deg: np.ndarray
    #: which relation each error belongs to (indices into the Relations scored)
    index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    def to_dict(self) -> dict:
        return {"relation_trans_mean_m": self.translation_m.mean, "relation_trans_std_m": self.translation_m.std,
                "relation_rot_mean_deg": self.rotation_deg.mean, "relation_rot_std_deg": self.rotation_deg.std,
                "relation_trans_sq_mean_m2": self.translation_sq_m2.mean,
                "relation_trans_sq_std_m2": self.translation_sq_m2.std,
                "relation_rot_sq_mean_deg2": self.rotation_sq_deg2.mean,
                "relation_rot_sq_std_deg2": self.rotation_sq_deg2.std,
                "relation_count": self.matched, "relation_unmatched": self.unmatched}


def read_relations(path: str | Path) -> Relations:
    """The benchmark's relations file: ``t1 t2 x y z roll pitch yaw`` per line (z, roll, pitch
    are 0 for the planar logs; a non-zero one is a DataError naming the line)."""
    lines, rows = number_rows(path, 8, "no relations in the file")
    off = np.abs(rows[:, 4:7]).max(axis=1) > 1e-9
    if off.any():
        k = int(np.flatnonzero(off)[0])
        raise DataError("z, roll and pitch must be 0 for a planar relation", path, int(lines[k]))
    return Relations(rows[:, 0], rows[:, 1], rows[:, [2, 3, 7]])


def _nearest(stamps: np.ndarray, query: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    idx = np.clip(np.searchsorted(stamps, query), 1, len(stamps) - 1)
    left = stamps[idx - 1]
    right = stamps[idx]
    pick = np.where(np.abs(query - left) <= np.abs(right - query), idx - 1, idx)
    return pick, np.abs(stamps[pick] - query)


def relation_errors(stamps_s: np.ndarray, world_xytheta_body: np.ndarray, relations: Relations,
                    tolerance_s: float = DEFAULT_TOLERANCE_S) -> RelationErrors:
    """Score a planar trajectory ((N,) stamps in any order, (N, 3) poses) on ``relations``."""
    t = np.asarray(stamps_s, dtype=float)
    poses = np.asarray(world_xytheta_body, dtype=float)
    if len(t) < 2 or poses.shape != (len(t), 3):
        raise DataError(f"need at least 2 stamped poses (N,) and (N, 3), got {t.shape} and {poses.shape}")
    order = np.argsort(t, kind="stable")
    t, poses = t[order], poses[order]
    i1, d1 = _nearest(t, relations.t1_s)
    i2, d2 = _nearest(t, relations.t2_s)
    ok = (d1 <= tolerance_s) & (d2 <= tolerance_s)
    if not ok.any():
        raise DataError(f"no relation has estimate poses within {tolerance_s} s of both its stamps")
    delta = se2.between(poses[i1[ok]], poses[i2[ok]])
    err = se2.compose(se2.inverse(relations.delta_xytheta[ok]), delta)
    e_m = np.hypot(err[:, 0], err[:, 1])
    e_deg = np.abs(np.rad2deg(err[:, 2]))
    return RelationErrors(ErrorStats.from_errors(e_m), ErrorStats.from_errors(e_deg),
                          ErrorStats.from_errors(e_m**2), ErrorStats.from_errors(e_deg**2),
                          int(ok.sum()), int((~ok).sum()), e_m, e_deg, np.flatnonzero(ok))


def evaluate_relations(trajectory, relations_path: str | Path,
                       tolerance_s: float = DEFAULT_TOLERANCE_S) -> RelationErrors:
    """Relation errors of a :class:`~slamkit.data.trajectory.Trajectory` (e.g. a TUM file
    stamped with the scans' ipc timestamps) on the relations file at ``relations_path``."""
    return relation_errors(trajectory.stamps_s, trajectory.xytheta(), read_relations(relations_path), tolerance_s)
