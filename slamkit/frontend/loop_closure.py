"""Loop-closure candidates by distance in the current estimate, verified by ICP fitness.

Candidates (the "nearby poses" search of Gutmann & Konolige, "Incremental mapping of large
cyclic environments", CIRA 1999, and of GraphSLAM front-ends, Grisetti et al., "A tutorial on
graph-based SLAM", 2010, sec. IV): keyframe pairs (i, j), j > i + ``min_index_gap``, whose
positions in the current estimate are within ``search_radius_m`` (all pairs at once with a
KD-tree), and which are separated by at least ``min_path_gap_m`` of travelled path so that
consecutive keyframes are not re-matched. Each keyframe keeps at most
``max_candidates_per_keyframe`` (the closest).

Verification: ICP of scan j against scan i from the estimate's relative pose, first with a wide
correspondence gate (the estimate may have drifted) then refined with the normal gate; the
closure is accepted when the ICP converged, its fitness (fraction of scan j's points within
``fitness_distance_m`` of scan i) is at least ``min_fitness`` and the correction it applied to
the estimate is plausible (``max_correction_m``). Wrong closures that pass (repetitive
corridors) are the back-end's job: a robust kernel (Cauchy) bounds their influence.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree

from slamkit.errors import ConfigError
from slamkit.frontend.icp import IcpConfig, IcpResult, IcpTarget, icp
from slamkit.geometry import se2


@dataclass(frozen=True)
class LoopClosureConfig:
    search_radius_m: float = 3.0
    min_index_gap: int = 10
    min_path_gap_m: float = 5.0
    max_candidates_per_keyframe: int = 2
    coarse_correspondence_m: float = 1.5
    min_fitness: float = 0.6
    max_correction_m: float = 2.0
    icp: IcpConfig = IcpConfig()

    def __post_init__(self) -> None:
        if not self.search_radius_m > 0:
            raise ConfigError(f"LoopClosureConfig.search_radius_m must be > 0, got {self.search_radius_m}")
        if not 0 < self.min_fitness <= 1:
            raise ConfigError(f"LoopClosureConfig.min_fitness must lie in (0, 1], got {self.min_fitness}")


def loop_candidates(world_xytheta_keyframes: np.ndarray, config: LoopClosureConfig = LoopClosureConfig()
                    ) -> np.ndarray:
    """(K, 2) keyframe index pairs (i, j), i < j, sorted by j then distance."""
    poses = np.asarray(world_xytheta_keyframes, dtype=float).reshape(-1, 3)
    if len(poses) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    pairs = cKDTree(poses[:, :2]).query_pairs(config.search_radius_m, output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    pairs = np.sort(pairs, axis=1)
    path = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1))])
    ok = ((pairs[:, 1] - pairs[:, 0] >= config.min_index_gap)
          & (path[pairs[:, 1]] - path[pairs[:, 0]] >= config.min_path_gap_m))
    pairs = pairs[ok]
    dist = np.linalg.norm(poses[pairs[:, 0], :2] - poses[pairs[:, 1], :2], axis=1)
    order = np.lexsort((dist, pairs[:, 1]))
    pairs, dist = pairs[order], dist[order]
    # rank of each pair within its j group (pairs are grouped by j after the sort)
    start = np.searchsorted(pairs[:, 1], pairs[:, 1], side="left")
    rank = np.arange(len(pairs)) - start
    return pairs[rank < config.max_candidates_per_keyframe]


@dataclass(frozen=True)
class LoopClosure:
    """An accepted closure: ``i_T_j`` with its ICP result (covariance in the right tangent)."""

    i: int
    j: int
    i_T_j: np.ndarray
    result: IcpResult


def verify_loop(points_i: np.ndarray | IcpTarget, points_j: np.ndarray, guess_i_T_j: np.ndarray,
                config: LoopClosureConfig = LoopClosureConfig()) -> tuple[bool, IcpResult]:
    """ICP of scan j onto scan i from ``guess_i_T_j``; (accepted, refined result)."""
    coarse = icp(points_j, points_i, guess_i_T_j,
                 replace(config.icp, max_correspondence_m=config.coarse_correspondence_m, trim_fraction=0.8))
    fine = icp(points_j, points_i, coarse.target_T_source, config.icp)
    correction = se2.between(np.asarray(guess_i_T_j, float), fine.target_T_source)
    ok = bool(fine.converged and fine.fitness >= config.min_fitness
              and np.hypot(correction[0], correction[1]) <= config.max_correction_m)
    return ok, fine


def detect_loops(world_xytheta_keyframes: np.ndarray, keyframe_points: list[np.ndarray],
                 config: LoopClosureConfig = LoopClosureConfig(),
                 exclude: set[tuple[int, int]] | None = None) -> tuple[list[LoopClosure], int]:
    """Candidates from the current estimate, each verified by ICP; (accepted, candidates tried)."""
    poses = np.asarray(world_xytheta_keyframes, dtype=float).reshape(-1, 3)
    targets: dict[int, IcpTarget] = {}
    accepted: list[LoopClosure] = []
    tried = 0
    for i, j in loop_candidates(poses, config):
        if exclude and (int(i), int(j)) in exclude:
            continue
        if min(len(keyframe_points[i]), len(keyframe_points[j])) < config.icp.min_correspondences:
            continue
        tried += 1
        if i not in targets:
            targets[i] = IcpTarget(keyframe_points[i], config.icp.normal_neighbours, config.icp.target_voxel_m)
        ok, res = verify_loop(targets[i], keyframe_points[j], se2.between(poses[i], poses[j]), config)
        if ok:
            accepted.append(LoopClosure(int(i), int(j), res.target_T_source, res))
    return accepted, tried
