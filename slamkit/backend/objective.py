"""The SE-Sync objective F, so any pose-graph solution can be compared with published optima.

Rosen, Carlone, Bandeira, Leonard, "SE-Sync: A certifiably correct algorithm for synchronization
over the special Euclidean group", IJRR 38(2-3), 2019, Problem 1 / eq. (10):

    F(t, R) = sum_ij kappa_ij ||R_j - R_i R~_ij||_F^2 + tau_ij ||t_j - t_i - R_i t~_ij||_2^2

with the isotropic weights SE-Sync derives from a g2o information matrix I (``read_g2o_file``,
SE-Sync commit 9b631b6): 2D tau = 2 / tr(I_tt^-1), kappa = I_thth; 3D tau = 3 / tr(I_tt^-1),
kappa = 3 / (2 tr(I_RR^-1)), where I_tt is the translation block and I_RR the rotation block.
This is NOT GTSAM's error (1/2 chi2 with full information); for isotropic noise the two optima
nearly coincide, for anisotropic noise they differ genuinely.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.backend._convert import quat_wxyz_to_rotation
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import BackendError, NoResultError


def _rot2(theta: np.ndarray) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], axis=-1), np.stack([s, c], axis=-1)], axis=-2)


def sesync_weights(graph: PoseGraph) -> tuple[np.ndarray, np.ndarray]:
    """Per-edge ``(kappa, tau)`` as SE-Sync computes them from the information matrices."""
    info = graph.information
    if graph.dim == 2:
        tau = 2.0 / _trace_of_inverse(info[:, :2, :2])
        kappa = info[:, 2, 2].copy()
    else:
        tau = 3.0 / _trace_of_inverse(info[:, :3, :3])
        kappa = 3.0 / (2.0 * _trace_of_inverse(info[:, 3:, 3:]))
    return kappa, tau


def _trace_of_inverse(blocks: np.ndarray) -> np.ndarray:
    """tr(B^-1) per (M, d, d) block; +inf for a singular block (no information: weight 0)."""
    try:
        return np.trace(np.linalg.inv(blocks), axis1=1, axis2=2)
    except np.linalg.LinAlgError:
        out = np.empty(len(blocks))
        for k, b in enumerate(blocks):
            try:
                out[k] = np.trace(np.linalg.inv(b))
            except np.linalg.LinAlgError:
                out[k] = np.inf
        return out


@dataclass(frozen=True)
class SESyncProblem:
    """A pose graph's edges in SE-Sync's terms: rows ``i -> j`` (0-based, matching the graph's
    vertex rows), measured rotations ``rotation`` (M, d, d) and translations ``translation``
    (M, d) of ``i_T_j``, and the isotropic weights ``kappa``, ``tau`` (M,)."""

    dim: int
    num_poses: int
    i: np.ndarray
    j: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    kappa: np.ndarray
    tau: np.ndarray


def sesync_problem(graph: PoseGraph) -> SESyncProblem:
    row = graph.index_of()
    i = np.array([row[v] for v in graph.edge_from.tolist()], dtype=np.int64)
    j = np.array([row[v] for v in graph.edge_to.tolist()], dtype=np.int64)
    kappa, tau = sesync_weights(graph)
    rotation, translation = pose_arrays(graph.dim, graph.measurements)
    return SESyncProblem(graph.dim, graph.num_poses, i, j, rotation, translation, kappa, tau)


def pose_arrays(dim: int, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows in the PoseGraph layout ((N, 3) or (N, 7)) -> rotations (N, d, d), translations (N, d)."""
    poses = np.asarray(poses, dtype=float)
    if dim == 2:
        return _rot2(poses[:, 2]), poses[:, :2]
    return quat_wxyz_to_rotation(poses[:, 3:]), poses[:, :3]


def sesync_residuals(problem: SESyncProblem, R: np.ndarray, t: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Unweighted residuals ``R_j - R_i R~_ij`` (M, d, d) and ``t_j - t_i - R_i t~_ij`` (M, d)."""
    Ri = R[problem.i]
    rot_res = R[problem.j] - Ri @ problem.rotation
    trans_res = t[problem.j] - t[problem.i] - np.einsum("kab,kb->ka", Ri, problem.translation)
    return rot_res, trans_res


def sesync_value(problem: SESyncProblem, R: np.ndarray, t: np.ndarray) -> float:
    """F at rotations ``R`` (N, d, d) and translations ``t`` (N, d)."""
    rot_res, trans_res = sesync_residuals(problem, R, t)
    return float(np.sum(problem.kappa * np.sum(rot_res**2, axis=(1, 2)))
                 + np.sum(problem.tau * np.sum(trans_res**2, axis=1)))


def sesync_objective(graph: PoseGraph, poses: np.ndarray) -> float:
    """F evaluated at ``poses`` ((N, 3) or (N, 7) in the PoseGraph layout, rows matching
    ``graph.vertex_ids``)."""
    width = 3 if graph.dim == 2 else 7
    poses = np.asarray(poses, dtype=float)
    if poses.shape != (graph.num_poses, width):
        raise BackendError(f"poses must have shape ({graph.num_poses}, {width}), got {poses.shape}")
    value = sesync_value(sesync_problem(graph), *pose_arrays(graph.dim, poses))
    if not np.isfinite(value) or value < 0.0:
        # F is a weighted sum of squares: NaN, inf or a negative value means the poses or the
        # weights (information that is not positive definite) are broken, not a result
        raise NoResultError(f"{graph.name}: the SE-Sync objective is {value!r}, which a sum of squares "
                            "cannot be (non-finite poses, or information that is not positive definite)")
    return value
