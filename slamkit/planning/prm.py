"""PRM: probabilistic roadmap, built once per world and reused across queries.

L. E. Kavraki, P. Svestka, J.-C. Latombe and M. H. Overmars, "Probabilistic Roadmaps for Path
Planning in High-Dimensional Configuration Spaces", IEEE T-RA 12(4), 1996. The roadmap is
``n_samples`` collision-free states joined to their ``k`` nearest neighbours (or all within
``radius``) by collision-free straight motions; neighbour queries use ``scipy.spatial.cKDTree``
and every candidate edge of the roadmap is checked in one batched call. A query connects start
and goal to their nearest roadmap vertices and runs Dijkstra (``scipy.sparse.csgraph``).

Samplers: ``uniform``; ``gaussian`` (Boor, Overmars & van der Stappen, ICRA 1999: keep one of
a pair q, q + N(0, sigma^2) when exactly one is free - samples hug obstacle boundaries);
``bridge`` (Hsu et al., ICRA 2003: keep the midpoint of two colliding states sigma apart if it is
free - samples land in narrow passages). Obstacle-based samplers find nothing in open space, so a
``uniform_fraction`` of uniform samples is mixed in (as the papers recommend).

Default k: k_PRM = e (1 + 1/d) log n, the PRM* connection count (Karaman & Frazzoli 2011).
Because the planner is not exhaustive, a query whose endpoints are not joined by the roadmap
returns TIMEOUT (budget spent), never NO_PATH.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from slamkit.errors import PlanningError
from slamkit.geometry.angles import wrap_angle
from slamkit.planning._sampling import SamplingPlanner, check_endpoints
from slamkit.planning.protocols import Hook, PlanEvent, PlanResult, PlanStats, PlanStatus, PlanningProblem
from slamkit.planning.worlds import as_world

SAMPLERS = ("uniform", "gaussian", "bridge")


@dataclass(frozen=True)
class PRMConfig:
    n_samples: int = 1000
    sampler: str = "uniform"
    connection: str = "knn"           # "knn" or "radius"
    k: int | None = None              # None: e (1 + 1/d) log n (PRM*)
    radius: float | None = None       # for connection="radius"; None: 10% of the extent
    sigma: float | None = None        # gaussian/bridge spread; None: 5% (gaussian) / 10% (bridge) of the extent
    uniform_fraction: float = 0.2     # share of uniform samples mixed into gaussian/bridge
    max_sample_rounds: int = 200      # batches of candidates before giving up on n_samples

    def __post_init__(self) -> None:
        if self.sampler not in SAMPLERS:
            raise PlanningError(f"unknown sampler {self.sampler!r}; choose from {SAMPLERS}")
        if self.connection not in ("knn", "radius"):
            raise PlanningError(f"connection must be 'knn' or 'radius', got {self.connection!r}")
        if self.n_samples < 1:
            raise PlanningError("n_samples must be >= 1")


@dataclass
class Roadmap:
    nodes: np.ndarray                 # (n, d)
    edges: np.ndarray                 # (m, 2) vertex pairs i < j
    weights: np.ndarray               # (m,) edge lengths
    components: np.ndarray            # (n,) connected-component label
    build_time_s: float
    candidates_checked: int
    tree: cKDTree = field(repr=False)


def sample_states(world, cfg: PRMConfig, rng: np.random.Generator) -> tuple[np.ndarray, int]:
    """(n_samples, d) valid states drawn with ``cfg.sampler`` and the number of candidates drawn."""
    # a bridge must span an obstacle, so it needs a longer reach than a Gaussian pair
    sigma = cfg.sigma or (0.1 if cfg.sampler == "bridge" else 0.05) * world.extent
    out: list[np.ndarray] = []
    have, drawn = 0, 0
    batch = max(256, cfg.n_samples)
    for _ in range(cfg.max_sample_rounds):
        if have >= cfg.n_samples:
            break
        q = world.sample_uniform(rng, batch)
        drawn += batch
        if cfg.sampler == "uniform":
            keep = q[world.is_valid(q)]
        else:
            n_uni = int(round(cfg.uniform_fraction * batch))
            uni = q[:n_uni][world.is_valid(q[:n_uni])]
            q1 = q[n_uni:]
            q2 = q1.copy()
            q2[:, :2] += rng.normal(0.0, sigma, (len(q1), 2))
            if world.dim == 3:
                q2[:, 2] = wrap_angle(q1[:, 2] + rng.normal(0.0, 0.5, len(q1)))
            v1, v2 = world.is_valid(q1), world.is_valid(q2)
            if cfg.sampler == "gaussian":
                near = np.vstack([q1[v1 & ~v2], q2[v2 & ~v1]])
            else:  # bridge: both ends in collision, midpoint free
                mid = world.interpolate(q1, q2, 0.5)
                both = ~v1 & ~v2
                near = mid[both][world.is_valid(mid[both])] if both.any() else np.zeros((0, world.dim))
            keep = np.vstack([uni, near])
        out.append(keep)
        have += len(keep)
    nodes = np.vstack(out)[:cfg.n_samples] if out else np.zeros((0, world.dim))
    return nodes, drawn


def build_roadmap(world, cfg: PRMConfig, rng: np.random.Generator) -> Roadmap:
    t0 = time.perf_counter()
    world = as_world(world)
    nodes, _ = sample_states(world, cfg, rng)
    n, d = len(nodes), world.dim
    tree = cKDTree(nodes[:, :2] if d == 3 else nodes)
    if cfg.connection == "knn":
        k = cfg.k or max(1, int(math.ceil(math.e * (1 + 1 / d) * math.log(max(n, 2)))))
        k = min(k, n - 1)
        if k >= 1:
            _, idx = tree.query(tree.data, k=k + 1)
            i = np.repeat(np.arange(n), k)
            j = idx[:, 1:].reshape(-1)
            ok = j < n
            pairs = np.stack([np.minimum(i[ok], j[ok]), np.maximum(i[ok], j[ok])], axis=1)
        else:
            pairs = np.zeros((0, 2), dtype=np.int64)
    else:
        radius = cfg.radius or 0.1 * world.extent
        pairs = tree.query_pairs(radius, output_type="ndarray")
    pairs = np.unique(pairs, axis=0) if len(pairs) else pairs.reshape(0, 2).astype(np.int64)
    ok = world.motions_valid(nodes[pairs[:, 0]], nodes[pairs[:, 1]]) if len(pairs) else np.zeros(0, bool)
    edges = pairs[ok]
    weights = np.array([float(world.distance(nodes[a], nodes[b][None])[0]) for a, b in edges]) \
        if d == 3 else np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1)
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return Roadmap(nodes, edges, weights, labels, time.perf_counter() - t0, len(pairs), tree)


class PRMPlanner(SamplingPlanner):
    """Multi-query: the roadmap of a world is built on its first query and reused afterwards
    (``roadmap_reused`` in the stats says which happened)."""

    name = "prm"

    def __init__(self, config: PRMConfig = PRMConfig(), rng: np.random.Generator | None = None,
                 hook: Hook | None = None):
        super().__init__(config, rng, hook)
        self._roadmaps: dict[int, tuple[object, object, Roadmap]] = {}

    def roadmap(self, world) -> tuple[object, Roadmap, bool]:
        """(continuous world, roadmap, reused?) for ``world`` (an OccupancyGrid is wrapped)."""
        key = id(world)
        if key in self._roadmaps and self._roadmaps[key][0] is world:
            _, cont, rm = self._roadmaps[key]
            return cont, rm, True
        cont = as_world(world)
        rm = build_roadmap(cont, self.config, self.rng)
        self._roadmaps[key] = (world, cont, rm)
        return cont, rm, False

    def plan(self, problem: PlanningProblem) -> PlanResult:
        t0 = time.perf_counter()
        _, start, goal, bad = check_endpoints(problem, self.name)
        if bad is not None:
            return bad
        world, rm, reused = self.roadmap(problem.world)
        if self.hook is not None:
            parents = np.full(len(rm.nodes), -1)
            self.hook(PlanEvent("roadmap", 0, rm.nodes, parents))
        n = len(rm.nodes)
        d = world.dim
        k = min(n, max(self.config.k or 10, 10))
        ends = np.stack([start, goal])
        extra_edges: list[tuple[int, int, float]] = []
        if n:
            q = ends[:, :2] if d == 3 else ends
            _, idx = rm.tree.query(q, k=k)
            idx = np.atleast_2d(idx)
            for e in range(2):
                cand = idx[e][idx[e] < n]
                ok = world.motions_valid(np.broadcast_to(ends[e], (len(cand), d)), rm.nodes[cand])
                for j in cand[ok]:
                    extra_edges.append((n + e, int(j), float(world.distance(ends[e], rm.nodes[j][None])[0])))
        if world.motions_valid(ends[:1], ends[1:])[0]:
            extra_edges.append((n, n + 1, float(world.distance(start, goal[None])[0])))
        rows = np.concatenate([rm.edges[:, 0], [a for a, _, _ in extra_edges]]).astype(np.int64)
        cols = np.concatenate([rm.edges[:, 1], [b for _, b, _ in extra_edges]]).astype(np.int64)
        w = np.concatenate([rm.weights, [c for _, _, c in extra_edges]])
        graph = coo_matrix((w, (rows, cols)), shape=(n + 2, n + 2)).tocsr()
        dist, pred = dijkstra(graph, directed=False, indices=n, return_predecessors=True)
        stats_kw = dict(samples=n, tree_size=n, extra={
            "roadmap_reused": reused, "roadmap_edges": int(len(rm.edges)),
            "roadmap_build_time_s": rm.build_time_s, "roadmap_components": int(rm.components.max() + 1) if n else 0})
        if not np.isfinite(dist[n + 1]):
            return PlanResult(PlanStatus.TIMEOUT, np.zeros((0, d)), math.inf,
                              PlanStats(time_s=time.perf_counter() - t0, **stats_kw), self.name)
        order = [n + 1]
        while order[-1] != n:
            order.append(int(pred[order[-1]]))
        all_nodes = np.vstack([rm.nodes, ends]) if n else ends
        path = all_nodes[order[::-1]]
        return PlanResult(PlanStatus.SOLVED, path, float(dist[n + 1]),
                          PlanStats(time_s=time.perf_counter() - t0, **stats_kw), self.name)
