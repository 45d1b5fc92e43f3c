"""Seeded false loop closures added to a pose graph, in the style of the Vertigo benchmark.

Suenderhauf and Protzel, "Switchable constraints for robust pose graph SLAM", IROS 2012, and the
Vertigo package's ``generateDataset.py`` (openslam_vertigo): outliers are extra loop-closure edges
between poses that were never at the same place, with

* ``random``: both ends drawn uniformly over the whole trajectory;
* ``local``: the second end within ``local_window`` poses of the first (a short-range wrong match);
* ``grouped``: groups of ``group_size`` outliers (i + l, j + l), l = 0 .. group_size - 1, whose
  measurements agree with each other and with the graph's initial poses (a sequence of wrong but
  mutually consistent matches, the hard case for consistency checks).

A false measurement is a translation uniform in [-``extent_m``, ``extent_m``]^d and a uniformly
random rotation; its information matrix is that of a randomly chosen true loop closure (of an
odometry edge when there are none), so the outliers are as confident as the real matches.
Everything is drawn from ``rng``: the same seed gives the same graph.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from slamkit.data.pose_graph import PoseGraph, rows_to_transforms, transforms_to_rows
from slamkit.errors import ConfigError
from slamkit.geometry import se2, se3

OutlierKind = Literal["random", "local", "grouped"]
OUTLIER_KINDS = ("random", "local", "grouped")


@dataclass(frozen=True)
class OutlierConfig:
    """``count`` false loop closures of ``kind``; lengths in metres."""

    kind: str = "random"
    count: int = 100
    extent_m: float = 10.0
    local_window: int = 50
    group_size: int = 10

    def __post_init__(self) -> None:
        if self.kind not in OUTLIER_KINDS:
            raise ConfigError(f"outlier kind must be one of {OUTLIER_KINDS}, got {self.kind!r}")
        if int(self.count) < 0 or int(self.local_window) < 2 or int(self.group_size) < 1:
            raise ConfigError("outliers: count must be >= 0, local_window >= 2 and group_size >= 1")
        if not (np.isfinite(self.extent_m) and self.extent_m > 0):
            raise ConfigError(f"outliers: extent_m must be > 0, got {self.extent_m!r}")


@dataclass(frozen=True)
class CorruptedGraph:
    """``graph`` = the original edges followed by the outliers; ``is_outlier`` (M,) marks them."""

    graph: PoseGraph
    is_outlier: np.ndarray
    config: OutlierConfig
    seed: int


def add_outliers(graph: PoseGraph, config: OutlierConfig, rng: np.random.Generator, seed: int = -1
                 ) -> CorruptedGraph:
    """``graph`` plus ``config.count`` false loop closures drawn from ``rng`` (see module docstring)."""
    n, count = graph.num_poses, int(config.count)
    if n < 4:
        raise ConfigError(f"{graph.name}: too few poses ({n}) to add false loop closures")
    pairs = _pairs(config, n, rng)
    measurements = _measurements(graph, config, pairs, rng)
    loops = np.flatnonzero(~graph.is_odometry())
    pool = loops if len(loops) else np.arange(graph.num_edges)
    info = graph.information[rng.choice(pool, size=count)] if count else graph.information[:0]
    ids = graph.vertex_ids
    corrupted = replace(
        graph,
        edge_from=np.concatenate([graph.edge_from, ids[pairs[:, 0]]]),
        edge_to=np.concatenate([graph.edge_to, ids[pairs[:, 1]]]),
        measurements=np.concatenate([graph.measurements, measurements]),
        information=np.concatenate([graph.information, info]),
        name=f"{graph.name}+{count}{config.kind}",
        notes=graph.notes + (f"{count} {config.kind} false loop closures (seed {seed})",))
    mask = np.concatenate([np.zeros(graph.num_edges, bool), np.ones(count, bool)])
    mask.setflags(write=False)
    return CorruptedGraph(corrupted, mask, config, seed)


def _pairs(config: OutlierConfig, n: int, rng: np.random.Generator) -> np.ndarray:
    """(count, 2) row indices, never the same or consecutive poses."""
    count = int(config.count)
    out = np.empty((0, 2), dtype=np.int64)
    while len(out) < count:
        need = count - len(out)
        if config.kind == "random":
            a, b = rng.integers(0, n, need), rng.integers(0, n, need)
        elif config.kind == "local":
            a = rng.integers(0, n, need)
            b = a + rng.integers(-config.local_window, config.local_window + 1, need)
        else:  # grouped: group starts, expanded below
            groups = -(-need // config.group_size)
            g = min(config.group_size, n // 2)
            a0, b0 = rng.integers(0, n - g, groups), rng.integers(0, n - g, groups)
            step = np.arange(g)
            a = (a0[:, None] + step).ravel()[:need]
            b = (b0[:, None] + step).ravel()[:need]
        ok = (b >= 0) & (b < n) & (np.abs(a - b) > 1)
        out = np.concatenate([out, np.column_stack([a, b])[ok]])
    return out[:count]


def _random_measurement(dim: int, extent_m: float, rng: np.random.Generator) -> np.ndarray:
    t = rng.uniform(-extent_m, extent_m, dim)
    if dim == 2:
        return np.array([t[0], t[1], rng.uniform(-np.pi, np.pi)])
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    return np.concatenate([t, q if q[0] >= 0 else -q])


def _measurements(graph: PoseGraph, config: OutlierConfig, pairs: np.ndarray,
                  rng: np.random.Generator) -> np.ndarray:
    width = 3 if graph.dim == 2 else 7
    z = np.array([_random_measurement(graph.dim, config.extent_m, rng) for _ in range(len(pairs))]
                 ).reshape(-1, width)
    if config.kind != "grouped" or not len(pairs):
        return z
    # within a group, z_l = (X_{a+l}^-1 X_a) z_0 (X_b^-1 X_{b+l}): one wrong match seen consistently
    start = np.flatnonzero(np.r_[True, (np.diff(pairs[:, 0]) != 1) | (np.diff(pairs[:, 1]) != 1)])
    first = np.repeat(start, np.diff(np.r_[start, len(pairs)]))
    a0, b0 = pairs[first, 0], pairs[first, 1]
    a, b = pairs[:, 0], pairs[:, 1]
    if graph.dim == 2:
        X = graph.poses
        return se2.compose(se2.compose(se2.between(X[a], X[a0]), z[first]), se2.between(X[b0], X[b]))
    X, Z = rows_to_transforms(3, graph.poses), rows_to_transforms(3, z)
    return transforms_to_rows(3, se3.compose(se3.compose(se3.between(X[a], X[a0]), Z[first]),
                                             se3.between(X[b0], X[b])))
