"""Initial estimates for pose-graph optimisation.

* ``file``: the poses stored with the problem.
* ``odometry``: compose measurements along a spanning tree rooted at the first vertex that uses as
  few non-consecutive (loop-closure) edges as possible (0-1 BFS), i.e. dead reckoning along the
  odometry chain, bridging gaps (cubicle lacks edge 14-15) through the fewest loop closures.
* ``lago``: LAGO, linear approximation of 2D pose-graph optimisation (Carlone, Aragues, Castellanos,
  Bona, "A fast and accurate approximation for planar pose graph optimization", IJRR 33(7), 2014):
  orientations from a linear least-squares problem on the cycle basis, then positions. GTSAM's
  implementation accepts only diagonal noise models, so it is run on a copy of the graph whose
  edges carry the marginal standard deviations ``sqrt(diag(Omega^-1))``; the result only seeds the
  full-information optimisation.
* ``chordal``: chordal relaxation for the rotations followed by one Gauss-Newton step on full
  poses (Carlone, Tron, Daniilidis, Dellaert, "Initialization techniques for 3D SLAM: a survey on
  rotation estimation and its use in pose graph optimization", ICRA 2015), via
  ``gtsam.InitializePose3``. When the chordal linear system is singular (cubicle) it falls back
  to ``odometry`` and records a warning.

Every method returns poses expressed in the frame of the first vertex's file pose, so the gauge
prior holds at the start.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Literal

import gtsam
import numpy as np

from slamkit.backend._convert import pose_key, poses_from_values, to_pose, values_from_poses
from slamkit.backend.graph import build_graph, gauge_prior
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import BackendError, ConfigError

InitMethod = Literal["file", "odometry", "lago", "chordal"]
INIT_METHODS = ("file", "odometry", "lago", "chordal")


@dataclass(frozen=True)
class InitialEstimate:
    """``poses`` in the PoseGraph layout (rows match ``vertex_ids``), the same as GTSAM Values,
    the method actually used (``chordal`` may fall back to ``odometry``) and warnings."""

    poses: np.ndarray
    values: gtsam.Values
    method: str
    warnings: tuple[str, ...] = ()


def is_indeterminant(exc: BaseException) -> bool:
    """GTSAM's IndeterminantLinearSystemException reaches Python as a RuntimeError whose message
    says "Indeterminate linear system" (older releases: "Indeterminant")."""
    return isinstance(exc, RuntimeError) and "indetermina" in str(exc).lower()


def initial_values(graph: PoseGraph, method: InitMethod = "file", prior_sigma: float = 1e-6,
                   factor_graph: gtsam.NonlinearFactorGraph | None = None) -> InitialEstimate:
    """Initial estimate for ``graph`` by ``method`` (see module docstring).

    ``factor_graph`` may pass the already-built graph of ``build_graph`` (with its gauge prior)
    for ``chordal`` to avoid building it twice. Raises ConfigError for an unknown method or one
    that does not apply to the graph's dimension."""
    if method not in INIT_METHODS:
        raise ConfigError(f"init must be one of {INIT_METHODS}, got {method!r}")
    if method == "lago" and graph.dim != 2:
        raise ConfigError(f"init 'lago' is a planar (2D) method; {graph.name} is 3D: use 'chordal'")
    if method == "chordal" and graph.dim != 3:
        raise ConfigError(f"init 'chordal' is for 3D pose graphs; {graph.name} is 2D: use 'lago'")
    if method == "file":
        return InitialEstimate(np.array(graph.poses),
                               values_from_poses(graph.dim, graph.vertex_ids, graph.poses), "file")
    if method == "odometry":
        return _odometry(graph)
    if method == "lago":
        return _lago(graph, prior_sigma)
    return _chordal(graph, prior_sigma, factor_graph)


def spanning_tree(graph: PoseGraph) -> tuple[np.ndarray, np.ndarray]:
    """0-1 BFS from the first vertex: consecutive-id edges cost 0, others 1.

    Returns ``(order, parent_edge)``: vertex rows in visiting order (each after its parent) and,
    per row, the edge index that reaches it (-1 for the root). Raises BackendError when some
    vertex is not connected to the first."""
    n = graph.num_poses
    row = graph.index_of()
    src = np.array([row[int(v)] for v in graph.edge_from.tolist()], dtype=np.int64)
    dst = np.array([row[int(v)] for v in graph.edge_to.tolist()], dtype=np.int64)
    odo = graph.is_odometry()
    adjacency: list[list[tuple[int, int, int]]] = [[] for _ in range(n)]
    for k, (a, b, c) in enumerate(zip(src.tolist(), dst.tolist(), (~odo).astype(int).tolist())):
        adjacency[a].append((b, k, c))
        adjacency[b].append((a, k, c))
    dist = np.full(n, np.iinfo(np.int64).max)
    parent = np.full(n, -1, dtype=np.int64)
    done = np.zeros(n, dtype=bool)
    dist[0] = 0
    queue: deque[int] = deque([0])
    order: list[int] = []
    while queue:
        u = queue.popleft()
        if done[u]:
            continue
        done[u] = True
        order.append(u)
        for v, k, c in adjacency[u]:
            if not done[v] and dist[u] + c < dist[v]:
                dist[v] = dist[u] + c
                parent[v] = k
                (queue.appendleft if c == 0 else queue.append)(v)
    if len(order) != n:
        lost = graph.vertex_ids[~done][:5].tolist()
        raise BackendError(f"{graph.source or graph.name}: pose graph is disconnected; "
                           f"{n - len(order)} vertices (e.g. ids {lost}) cannot be reached "
                           f"from vertex {int(graph.vertex_ids[0])}")
    return np.array(order, dtype=np.int64), parent


def _odometry(graph: PoseGraph) -> InitialEstimate:
    order, parent = spanning_tree(graph)
    row = graph.index_of()
    poses: list = [None] * graph.num_poses
    poses[0] = to_pose(graph.dim, graph.poses[0])
    for u in order[1:].tolist():
        k = int(parent[u])
        z = to_pose(graph.dim, graph.measurements[k])
        a, b = row[int(graph.edge_from[k])], row[int(graph.edge_to[k])]
        # the edge measures from_T_to: walk it forwards or backwards depending on the side reached
        poses[u] = poses[a].compose(z) if b == u else poses[b].compose(z.inverse())
    values = gtsam.Values()
    for vid, p in zip(graph.vertex_ids.tolist(), poses):
        values.insert(pose_key(vid), p)
    return InitialEstimate(poses_from_values(graph.dim, graph.vertex_ids, values), values,
                           "odometry")


def _anchor(graph: PoseGraph, values: gtsam.Values) -> gtsam.Values:
    """Re-express ``values`` so that the first vertex sits at its file pose (the gauge prior)."""
    key0 = pose_key(int(graph.vertex_ids[0]))
    at = values.atPose2 if graph.dim == 2 else values.atPose3
    correction = to_pose(graph.dim, graph.poses[0]).compose(at(key0).inverse())
    out = gtsam.Values()
    for vid in graph.vertex_ids.tolist():
        key = pose_key(vid)
        out.insert(key, correction.compose(at(key)))
    return out


def _lago(graph: PoseGraph, prior_sigma: float) -> InitialEstimate:
    cov = np.linalg.inv(graph.information)
    sigmas = np.sqrt(np.abs(np.diagonal(cov, axis1=1, axis2=2)))
    fg = gtsam.NonlinearFactorGraph()
    for k, (i, j) in enumerate(zip(graph.edge_from.tolist(), graph.edge_to.tolist())):
        fg.add(gtsam.BetweenFactorPose2(pose_key(i), pose_key(j),
                                        to_pose(2, graph.measurements[k]),
                                        gtsam.noiseModel.Diagonal.Sigmas(sigmas[k])))
    fg.add(gauge_prior(2, int(graph.vertex_ids[0]), graph.poses[0], prior_sigma))
    try:
        values = gtsam.lago.initialize(fg)
    except (RuntimeError, ValueError) as exc:
        raise BackendError(f"LAGO initialisation failed on {graph.name}: {exc}") from exc
    values = _anchor(graph, values)
    return InitialEstimate(poses_from_values(2, graph.vertex_ids, values), values, "lago")


def _chordal(graph: PoseGraph, prior_sigma: float,
             factor_graph: gtsam.NonlinearFactorGraph | None) -> InitialEstimate:
    fg = factor_graph if factor_graph is not None else build_graph(graph, prior_sigma=prior_sigma)[0]
    try:
        values = gtsam.InitializePose3.initialize(fg)
    except RuntimeError as exc:
        if not is_indeterminant(exc):
            raise BackendError(f"chordal initialisation failed on {graph.name}: {exc}") from exc
        fallback = _odometry(graph)
        msg = (f"chordal initialisation hit an indeterminant linear system on {graph.name} "
               f"(a singular rotation sub-problem); fell back to odometry chaining")
        return InitialEstimate(fallback.poses, fallback.values, "odometry", (msg,))
    values = _anchor(graph, values)
    return InitialEstimate(poses_from_values(3, graph.vertex_ids, values), values, "chordal")
