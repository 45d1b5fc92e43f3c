"""iSAM2 replay of a pose graph: the problem solved incrementally, one update per new pose.

iSAM2 (Kaess, Johannsson, Roberts, Ila, Leonard, Dellaert, "iSAM2: Incremental smoothing and
mapping using the Bayes tree", IJRR 31(2), 2012, Alg. 1 and 2) keeps a Bayes tree of the
linearised problem and only re-eliminates the cliques touched by new factors, relinearising
variables whose delta exceeds a threshold (fluid relinearisation).

Replay order: edges are taken in file order. When an edge brings in a vertex not yet in the
estimate, the factors gathered so far are handed to ``ISAM2.update`` (one update per new pose)
and the new vertex is initialised as the current estimate of its known neighbour composed with
the edge's measurement (or its inverse when the new vertex is the edge's ``from``). The first
vertex enters at its file pose with the gauge prior. An edge between two vertices not yet placed
(intel_g2o_943 lists some edges before their vertices are reachable) waits until one of them is.
After the last edge, empty updates are repeated until fluid relinearisation has nothing left to
relinearise (at most ``final_updates``), because iSAM2 takes one Gauss-Newton step per update.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import gtsam
import numpy as np

from slamkit.backend._convert import pose_key, poses_from_values, to_pose
from slamkit.backend.graph import ROBUST_KINDS, gauge_prior, gaussian_from_information, robust
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import BackendError
from slamkit.geometry import se2


@dataclass(frozen=True)
class Isam2Params:
    """GTSAM's ISAM2Params defaults: Gauss-Newton steps, relinearise when a variable's delta
    exceeds ``relinearize_threshold`` (tangent units), check every ``relinearize_skip`` updates."""

    relinearize_threshold: float = 0.1
    relinearize_skip: int = 10
    factorization: str = "cholesky"  # 'cholesky' | 'qr'
    #: empty updates after the replay, until no variable is relinearised (see isam2_replay)
    final_updates: int = 10

    def to_gtsam(self) -> gtsam.ISAM2Params:
        p = gtsam.ISAM2Params()
        p.setRelinearizeThreshold(float(self.relinearize_threshold))
        p.relinearizeSkip = int(self.relinearize_skip)
        if self.factorization == "qr":
            p.setFactorization("QR")
        return p


def isam2_replay(graph: PoseGraph, factor_graph: gtsam.NonlinearFactorGraph,
                 params: Isam2Params = Isam2Params(),
                 on_update: Callable[[int, float, np.ndarray], None] | None = None,
                 ) -> tuple[gtsam.Values, int]:
    """Replay ``graph`` through iSAM2; returns ``(final estimate, number of updates)``.

    ``factor_graph`` is ``build_graph(graph)``'s output: factor ``k`` is edge ``k`` and the last
    factor the gauge prior. An edge whose two vertices are both still unknown waits until one of
    them is placed. ``on_update(update, error, poses)`` (optional, costs a full estimate per
    update) sees the error of the factors added so far and (N, width) poses with NaN rows for
    vertices not yet added. Raises RuntimeError (GTSAM's IndeterminantLinearSystem) when the
    factorisation fails; ``optimize`` then retries with QR."""
    dim = graph.dim
    n, m = graph.num_poses, graph.num_edges
    if factor_graph.size() != m + 1:
        raise BackendError("isam2_replay needs build_graph's output with its gauge prior")
    row = graph.index_of()
    ef = [row[v] for v in graph.edge_from.tolist()]
    et = [row[v] for v in graph.edge_to.tolist()]
    keys = [pose_key(v) for v in graph.vertex_ids.tolist()]
    estimate_of = (lambda isam, key: isam.calculateEstimatePose2(key)) if dim == 2 else \
        (lambda isam, key: isam.calculateEstimatePose3(key))
    z_of = graph.measurements.tolist() if dim == 2 else graph.measurements

    isam = gtsam.ISAM2(params.to_gtsam())
    known = np.zeros(n, dtype=bool)
    new_factors = gtsam.NonlinearFactorGraph()
    new_values = gtsam.Values()
    new_values.insert(keys[0], to_pose(dim, graph.poses[0]))
    new_factors.add(factor_graph.at(m))
    known[0] = True
    seen = gtsam.NonlinearFactorGraph() if on_update is not None else None
    waiting: dict[int, list[int]] = {}
    added: set[int] = set()
    updates = 0

    def report(est: gtsam.Values) -> None:
        poses = np.full((n, 3 if dim == 2 else 7), np.nan)
        poses[known] = poses_from_values(dim, graph.vertex_ids[known], est)
        on_update(updates, seen.error(est), poses)

    def flush() -> None:
        nonlocal new_factors, new_values, updates
        isam.update(new_factors, new_values)
        updates += 1
        if seen is not None:
            seen.push_back(new_factors)
            report(isam.calculateEstimate())
        new_factors = gtsam.NonlinearFactorGraph()
        new_values = gtsam.Values()

    for first in range(m):
        stack = [first]
        while stack:
            k = stack.pop()
            a, b = ef[k], et[k]
            if not (known[a] or known[b]):
                waiting.setdefault(a, []).append(k)
                waiting.setdefault(b, []).append(k)
                continue
            if known[a] and known[b]:
                if k not in added:
                    new_factors.add(factor_graph.at(k))
                    added.add(k)
                continue
            flush()
            z = to_pose(dim, z_of[k])
            if known[a]:
                new, pose = b, estimate_of(isam, keys[a]).compose(z)
            else:
                new, pose = a, estimate_of(isam, keys[b]).compose(z.inverse())
            new_values.insert(keys[new], pose)
            known[new] = True
            new_factors.add(factor_graph.at(k))
            added.add(k)
            # edges that were waiting for this vertex can go in now (reverse: keep file order)
            stack.extend(reversed(waiting.pop(new, [])))
    flush()
    if not known.all():
        lost = graph.vertex_ids[~known][:5].tolist()
        raise BackendError(f"{graph.source or graph.name}: vertices {lost} cannot be reached "
                           f"from vertex {int(graph.vertex_ids[0])}; iSAM2 replay cannot place them")
    # iSAM2 takes one Gauss-Newton step per update and relinearises lazily, so right after the
    # last update the estimate can still be far from the optimum (M3500: error 1.9e5 vs 69).
    # Empty updates let fluid relinearisation finish; stop once no variable was relinearised.
    for _ in range(params.final_updates):
        # force: with relinearize_skip > 1 an ordinary empty update may skip the check
        relinearised = isam.update(force_relinearize=True).getVariablesRelinearized()
        updates += 1
        if seen is not None:
            report(isam.calculateEstimate())
        if relinearised == 0:
            break
    return isam.calculateEstimate(), updates


class Isam2PoseGraph:
    """A planar pose graph grown and solved online with iSAM2 (an engine: holds the Bayes tree).

    ``add_pose(i, world_xytheta)`` brings in vertex ``i`` at an initial guess (the first one
    gets the gauge prior); ``add_edge(i, j, i_xytheta_j, information, robust_edge)`` a
    BetweenFactor (``robust_edge`` wraps its noise in the kernel ``robust_kind``); ``update()`` hands
    what was added to ``ISAM2.update`` (one Gauss-Newton step with fluid relinearisation,
    Kaess et al. 2012, Alg. 1) and ``poses()`` returns the current estimate of every vertex, in
    the order they were added, as (N, 3). Edges are also kept as a :class:`PoseGraph` (``graph()``)
    for a final batch solve."""

    def __init__(self, robust_kind: str = "cauchy", robust_k: float | None = None,
                 params: Isam2Params = Isam2Params(), prior_sigma: float = 1e-6, name: str = "online"):
        if robust_kind not in ROBUST_KINDS:
            raise BackendError(f"robust must be one of {ROBUST_KINDS}, got {robust_kind!r}")
        self.robust_kind, self.robust_k, self.prior_sigma, self.name = robust_kind, robust_k, prior_sigma, name
        self._isam = gtsam.ISAM2(params.to_gtsam())
        self._factors = gtsam.NonlinearFactorGraph()
        self._values = gtsam.Values()
        self._ids: list[int] = []
        self._initial: list[np.ndarray] = []
        self._edges: list[tuple[int, int, np.ndarray, np.ndarray]] = []
        self._poses = np.zeros((0, 3))

    @property
    def num_poses(self) -> int:
        return len(self._ids)

    def add_pose(self, vertex_id: int, world_xytheta: np.ndarray) -> None:
        row = np.asarray(world_xytheta, dtype=float).reshape(3)
        if not self._ids:
            self._factors.add(gauge_prior(2, int(vertex_id), row, self.prior_sigma))
        self._values.insert(pose_key(vertex_id), to_pose(2, row))
        self._ids.append(int(vertex_id))
        self._initial.append(row.copy())
        self._poses = np.vstack([self._poses, row[None]])

    def add_edge(self, i: int, j: int, i_xytheta_j: np.ndarray, information: np.ndarray,
                 robust_edge: bool = True) -> None:
        z = np.asarray(i_xytheta_j, dtype=float).reshape(3)
        info = np.asarray(information, dtype=float).reshape(3, 3)
        model = gaussian_from_information(0.5 * (info + info.T))
        if robust_edge:
            model = robust(model, self.robust_kind, self.robust_k)
        self._factors.add(gtsam.BetweenFactorPose2(pose_key(i), pose_key(j), to_pose(2, z), model))
        self._edges.append((int(i), int(j), z, info))

    def add_prior(self, i: int, world_xytheta: np.ndarray, covariance: np.ndarray) -> None:
        """A PriorFactor on vertex ``i``: an absolute pose measurement (a scan matched against a
        known map) with its (3, 3) ``covariance`` in world (x, y, theta) terms, turned into
        GTSAM's body-frame tangent (the inverse of ``se2.covariance_body_to_world``)."""
        row = np.asarray(world_xytheta, dtype=float).reshape(3)
        cov_body = se2.covariance_world_to_body(row, np.asarray(covariance, dtype=float).reshape(3, 3))
        self._factors.add(gtsam.PriorFactorPose2(pose_key(i), to_pose(2, row),
                                                 gtsam.noiseModel.Gaussian.Covariance(0.5 * (cov_body + cov_body.T))))

    def covariance(self, row: int) -> np.ndarray:
        """(3, 3) marginal covariance of the vertex added ``row``-th, in world (x, y, theta) terms
        (``se2.covariance_body_to_world`` of GTSAM's body-frame marginal)."""
        return se2.covariance_body_to_world(self._poses[row],
                                            self._isam.marginalCovariance(pose_key(self._ids[row])))

    def covariances(self) -> np.ndarray:
        """(N, 3, 3) :meth:`covariance` of every vertex."""
        return np.array([self.covariance(k) for k in range(len(self._ids))]).reshape(-1, 3, 3)

    def update(self, extra_steps: int = 0) -> None:
        """Solve what was added (plus ``extra_steps`` empty updates: more relinearisation after a
        loop closure moved much of the graph) and refresh ``poses()``."""
        self._isam.update(self._factors, self._values)
        for _ in range(extra_steps):
            self._isam.update()
        self._factors = gtsam.NonlinearFactorGraph()
        self._values = gtsam.Values()
        self._poses = poses_from_values(2, np.asarray(self._ids), self._isam.calculateEstimate())

    def poses(self) -> np.ndarray:
        """(N, 3) current estimate (rows in the order of ``add_pose``; not yet updated vertices
        at their initial guess)."""
        return self._poses

    def graph(self) -> PoseGraph:
        """Everything added so far as a :class:`PoseGraph`, the current estimate as its poses."""
        if self._edges:
            ef, et, z, info = (np.array(v) for v in zip(*self._edges))
        else:
            ef = et = np.zeros(0, dtype=np.int64)
            z, info = np.zeros((0, 3)), np.zeros((0, 3, 3))
        return PoseGraph(2, np.asarray(self._ids), self._poses.copy(), ef.astype(np.int64),
                         et.astype(np.int64), z.reshape(-1, 3), info.reshape(-1, 3, 3), name=self.name)
