"""Loop-closure precision and recall against the relations of the SLAM benchmark (Kuemmerle et
al., "On measuring the accuracy of SLAM algorithms", Autonomous Robots 27(4), 2009), which hold
no list of true loop closures but many hand-verified displacements between scans taken far apart
in time -- the revisits.

* A closure (keyframes at stamps t_i < t_j, measured displacement i_T_j) is **verifiable** when a
  relation (t1 < t2) has both stamps within ``window_s`` of the closure's (the nearest such
  relation by |t1 - t_i| + |t2 - t_j|). The closure predicts that relation's displacement through
  the estimate's short pieces on either side, T(t_i)^-1 T(t1) and T(t_j)^-1 T(t2) (a few seconds
  of motion, accurate whatever the loop closures did); it is **correct** when the prediction's
  translation is within ``max_error_m`` of the relation, **wrong** otherwise. Precision =
  correct / verifiable.
* A **revisit** is a relation whose stamps are at least ``min_gap_s`` apart; it is **recalled**
  when some accepted closure has both stamps within ``window_s`` of it. Recall = recalled /
  revisits (a lower bound of the revisits found: a closure a few seconds beyond the window
  closes the same loop without counting).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import DataError
from slamkit.geometry import se2
from slamkit.metrics.relations import Relations


@dataclass(frozen=True)
class LoopClosureCounts:
    closures: int
    verifiable: int
    correct: int
    wrong: int
    revisits: int
    recalled: int
    #: (wrong,) translation error of every wrong closure's predicted relation (m)
    wrong_errors_m: tuple[float, ...] = ()

    @property
    def precision(self) -> float:
        return self.correct / self.verifiable if self.verifiable else float("nan")

    @property
    def recall(self) -> float:
        return self.recalled / self.revisits if self.revisits else float("nan")

    def to_dict(self) -> dict:
        return {"loop_closures": self.closures, "loop_closures_verifiable": self.verifiable,
                "loop_closures_correct": self.correct, "loop_closures_wrong": self.wrong,
                "loop_precision": self.precision, "revisit_relations": self.revisits,
                "revisit_relations_recalled": self.recalled, "loop_recall": self.recall}


def _at(stamps: np.ndarray, poses: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Poses at the nearest stamps (stamps sorted)."""
    idx = np.clip(np.searchsorted(stamps, query), 1, len(stamps) - 1)
    pick = np.where(np.abs(query - stamps[idx - 1]) <= np.abs(stamps[idx] - query), idx - 1, idx)
    return poses[pick]


def loop_closure_counts(closure_stamps_s: np.ndarray, closure_i_T_j: np.ndarray, stamps_s: np.ndarray,
                        world_xytheta_body: np.ndarray, relations: Relations, window_s: float = 5.0,
                        min_gap_s: float = 60.0, max_error_m: float = 0.2) -> LoopClosureCounts:
    """Precision and recall counts (module docstring) of accepted closures: ``closure_stamps_s``
    (M, 2) the stamps of their two keyframes (t_i, t_j), ``closure_i_T_j`` (M, 3) the measured pose
    of j in i's frame; ``stamps_s`` (N,) and ``world_xytheta_body`` (N, 3) the estimate (every
    scan); ``relations`` the benchmark's."""
    cs = np.asarray(closure_stamps_s, dtype=float).reshape(-1, 2)
    cT = np.asarray(closure_i_T_j, dtype=float).reshape(-1, 3)
    t = np.asarray(stamps_s, dtype=float)
    poses = np.asarray(world_xytheta_body, dtype=float)
    if len(cs) != len(cT) or poses.shape != (len(t), 3) or len(t) < 2:
        raise DataError(f"loop_closure_counts: closures {cs.shape} / {cT.shape}, estimate {t.shape} / {poses.shape}")
    if not (window_s > 0 and min_gap_s > 0 and max_error_m > 0):
        raise DataError("loop_closure_counts: window_s, min_gap_s and max_error_m must be > 0")
    order = np.argsort(t, kind="stable")
    t, poses = t[order], poses[order]
    # relations with t1 < t2 (a relation given the other way round is inverted)
    swap = relations.t1_s > relations.t2_s
    r1 = np.where(swap, relations.t2_s, relations.t1_s)
    r2 = np.where(swap, relations.t1_s, relations.t2_s)
    rd = np.where(swap[:, None], se2.inverse(relations.delta_xytheta), relations.delta_xytheta)
    # closures with t_i < t_j likewise
    cswap = cs[:, 0] > cs[:, 1]
    ci = np.where(cswap, cs[:, 1], cs[:, 0])
    cj = np.where(cswap, cs[:, 0], cs[:, 1])
    cT = np.where(cswap[:, None], se2.inverse(cT), cT)
    near = (np.abs(ci[:, None] - r1[None, :]) <= window_s) & (np.abs(cj[:, None] - r2[None, :]) <= window_s)
    # verifiable closures: the nearest relation
    verifiable = near.any(axis=1)
    cost = np.where(near, np.abs(ci[:, None] - r1[None, :]) + np.abs(cj[:, None] - r2[None, :]), np.inf)
    k = np.argmin(cost, axis=1)[verifiable]
    m = np.flatnonzero(verifiable)
    i_T_1 = se2.between(_at(t, poses, ci[m]), _at(t, poses, r1[k]))
    j_T_2 = se2.between(_at(t, poses, cj[m]), _at(t, poses, r2[k]))
    predicted = se2.compose(se2.compose(se2.inverse(i_T_1), cT[m]), j_T_2)
    err = se2.compose(se2.inverse(rd[k]), predicted)
    e_m = np.hypot(err[:, 0], err[:, 1])
    wrong = e_m > max_error_m
    revisit = (r2 - r1) >= min_gap_s
    recalled = near[:, revisit].any(axis=0)
    return LoopClosureCounts(len(cs), int(verifiable.sum()), int((~wrong).sum()), int(wrong.sum()),
                             int(revisit.sum()), int(recalled.sum()), tuple(float(e) for e in e_m[wrong]))
