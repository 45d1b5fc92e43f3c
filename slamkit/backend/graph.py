"""Factor graph of a pose-graph problem: one BetweenFactor per edge plus a gauge prior.

Pose-graph SLAM as nonlinear least squares (Grisetti, Kuemmerle, Stachniss, Burgard, "A Tutorial
on Graph-Based SLAM", IEEE ITS Magazine 2010, eq. 3): minimise
sum_ij e_ij^T Omega_ij e_ij with e_ij = Log(Z_ij^-1 X_i^-1 X_j). GTSAM's ``error()`` is half that
sum. The first pose is pinned by a tight prior because the objective is invariant to a global
rigid motion (gauge freedom). Robust kernels (Huber, Cauchy) wrap each edge's Gaussian noise model
in ``noiseModel.Robust`` (Zhang, "Parameter estimation techniques", IVC 1997, Table 1), which
GTSAM solves by iteratively re-weighted least squares.
"""

from __future__ import annotations

import itertools
from typing import Literal

import gtsam
import numpy as np

from slamkit.backend._convert import check_vertex_ids, permute_information, pose_key, to_pose
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import BackendError, ConfigError, DataError

RobustKind = Literal["none", "huber", "cauchy", "dcs"]
ROBUST_KINDS = ("none", "huber", "cauchy", "dcs")


# ---- named noise helpers -------------------------------------------------------------------

def smoother_config(owner: str, config_class: type, config):
    """``config``, or ``config_class()`` when None; a ConfigError naming ``owner`` when it is a
    config of another kind (the smoother classes share constructors through ``config_class``)."""
    config = config_class() if config is None else config
    if not isinstance(config, config_class):
        raise ConfigError(f"{owner} is configured by {config_class.__name__}, not {type(config).__name__}")
    return config


def gaussian_from_information(information: np.ndarray) -> gtsam.noiseModel.Base:
    """Gaussian noise model with the given information matrix (in GTSAM tangent order).

    ``Information(..., smart=True)`` turns a diagonal matrix into a Diagonal model, exactly as
    ``gtsam.readG2o`` does, so errors agree with a raw GTSAM load to the last bit."""
    return gtsam.noiseModel.Gaussian.Information(np.asarray(information, dtype=float))


def isotropic(dim: int, sigma: float) -> gtsam.noiseModel.Base:
    return gtsam.noiseModel.Isotropic.Sigma(dim, float(sigma))


#: default kernel widths (whitened units): Huber 95% efficiency, Cauchy 95% efficiency; DCS's
#: Phi (Agarwal, Tipaldi, Spinello, Stachniss, Burgard, "Robust map optimization using dynamic
#: covariance scaling", ICRA 2013: the closed-form switch of switchable constraints, scale
#: s = min(1, 2 Phi / (Phi + chi2))) = 10: the paper's Phi = 1 also switches off true loop
#: closures far from the odometry initial guess (ring + 100 random outliers: 26 of 334 true loop
#: closures rejected with Phi = 1, none with Phi = 10 or 100; all 100 outliers rejected in each case)
DEFAULT_ROBUST_K = {"huber": 1.345, "cauchy": 2.3849, "dcs": 10.0}


def robust(base: gtsam.noiseModel.Base, kind: RobustKind, k: float | None = None,
           ) -> gtsam.noiseModel.Base:
    """Wrap ``base`` in an M-estimator; ``k`` is the kernel width in whitened units (sigmas),
    ``None`` for the kernel's 95%-efficiency default (``DEFAULT_ROBUST_K``)."""
    if kind != "none" and k is None:
        k = DEFAULT_ROBUST_K[kind]
    if kind == "none":
        return base
    if kind == "huber":
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(k), base)
    if kind == "cauchy":
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy.Create(k), base)
    if kind == "dcs":
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.DCS.Create(k), base)
    raise ConfigError(f"robust must be one of {ROBUST_KINDS}, got {kind!r}")


def gauge_prior(dim: int, vertex_id: int, pose_row: np.ndarray, sigma: float):
    """Prior pinning one pose (the gauge) with an isotropic ``sigma`` in every tangent direction."""
    if dim == 2:
        return gtsam.PriorFactorPose2(pose_key(vertex_id), to_pose(2, pose_row), isotropic(3, sigma))
    return gtsam.PriorFactorPose3(pose_key(vertex_id), to_pose(3, pose_row), isotropic(6, sigma))


# ---- graph -----------------------------------------------------------------------------------

def build_graph(graph: PoseGraph, robust_kind: RobustKind = "none", robust_k: float | None = None,
                prior_sigma: float = 1e-6, with_prior: bool = True,
                robust_mask: np.ndarray | None = None,
                ) -> tuple[gtsam.NonlinearFactorGraph, dict[int, int]]:
    """Build ``(NonlinearFactorGraph, {vertex_id: key})`` for ``graph``.

    Factor ``k`` (0-based) is edge ``k``; with ``with_prior`` the gauge prior on the first vertex
    is appended last, at index ``num_edges``. ``robust_k`` (whitened units) defaults to the
    kernel's 95%-efficiency constant (Huber 1.345, Cauchy 2.3849). ``prior_sigma`` is in metres
    and radians. ``robust_mask`` (M,) limits the kernel to the edges marked True (e.g. the loop
    closures, with the odometry trusted); None applies it to every edge.
    """
    if robust_kind not in ROBUST_KINDS:
        raise ConfigError(f"robust must be one of {ROBUST_KINDS}, got {robust_kind!r}")
    if robust_k is not None and (not np.isfinite(robust_k) or robust_k <= 0):
        raise ConfigError(f"robust_k must be a positive number, got {robust_k!r}")
    if not np.isfinite(prior_sigma) or prior_sigma <= 0:
        raise ConfigError(f"prior_sigma must be a positive number, got {prior_sigma!r}")
    check_vertex_ids(graph.vertex_ids)
    src = graph.source or graph.name
    known = np.isin(graph.edge_from, graph.vertex_ids) & np.isin(graph.edge_to, graph.vertex_ids)
    if not known.all():
        bad = np.union1d(graph.edge_from[~known], graph.edge_to[~known])
        bad = bad[~np.isin(bad, graph.vertex_ids)]
        raise BackendError(f"{src}: edges refer to unknown vertex ids {bad[:5].tolist()}")
    if not (np.all(np.isfinite(graph.measurements)) and np.all(np.isfinite(graph.information))):
        raise BackendError(f"{src}: measurements or information contain NaN/inf")
    # X(id) is ('x' << 56) | id: compute every key at once instead of one Symbol per edge
    base = pose_key(0)
    key_of = dict(zip(graph.vertex_ids.tolist(), (base + graph.vertex_ids).tolist()))
    keys_from = (base + graph.edge_from).tolist()
    keys_to = (base + graph.edge_to).tolist()

    info = graph.information if graph.dim == 2 else permute_information(graph.information)
    # Many datasets share one information matrix across edges (w10000: all identity): build one
    # noise model per distinct matrix instead of re-factorising the same matrix M times.
    m, width = len(info), info.shape[1] if info.ndim == 3 else (3 if graph.dim == 2 else 6)
    flat = info.reshape(m, width * width)
    if robust_mask is not None and robust_kind != "none":
        # the robust flag is part of a model's identity: one more column to make models distinct by
        flat = np.column_stack([flat, np.asarray(robust_mask, dtype=float).reshape(m)])
    if m and np.all(flat == flat[0]):
        unique, which = flat[:1], np.zeros(m, dtype=np.int64)
    else:
        unique, which = np.unique(flat, axis=0, return_inverse=True)
    models = []
    for k, u in enumerate(unique):
        try:
            robust_here = robust_kind if len(u) == width * width or u[-1] else "none"
            models.append(robust(gaussian_from_information(u[:width * width].reshape(width, width)),
                                 robust_here, robust_k))
        except (ValueError, RuntimeError) as exc:  # GTSAM refuses e.g. a negative diagonal
            e = int(np.flatnonzero(np.reshape(which, -1) == k)[0])
            raise DataError(  # the file's fault, not a failed solve: bad input (exit 2)
                f"edge {e} ({int(graph.edge_from[e])} -> {int(graph.edge_to[e])}) has an information "
                f"matrix GTSAM cannot use ({exc}); read the file with policy 'repair' or 'reject'", src) from None
    # one shared model (w10000, most files): repeat it instead of a 64k-entry list
    model_of = (itertools.repeat(models[0], m) if len(models) == 1
                else [models[w] for w in which.reshape(-1).tolist()])
    fg = gtsam.NonlinearFactorGraph()
    add = fg.add
    if graph.dim == 2:
        Between, Pose = gtsam.BetweenFactorPose2, gtsam.Pose2
        # per-column lists: no inner list per edge to build and unpack (~10% of this loop)
        xs, ys, ths = graph.measurements.T.tolist()
        for i, j, x, y, th, model in zip(keys_from, keys_to, xs, ys, ths, model_of):
            add(Between(i, j, Pose(x, y, th), model))
    else:
        for k, (i, j, model) in enumerate(zip(keys_from, keys_to, model_of)):
            add(gtsam.BetweenFactorPose3(i, j, to_pose(3, graph.measurements[k]), model))
    if with_prior:
        fg.add(gauge_prior(graph.dim, int(graph.vertex_ids[0]), graph.poses[0], prior_sigma))
    return fg, key_of
