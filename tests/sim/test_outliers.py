"""Vertigo-style false loop closures (slamkit.sim.outliers): reproducible by seed, the right
kinds, counts and shapes, and grouped outliers mutually consistent."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import ConfigError
from slamkit.geometry import se2
from slamkit.sim.outliers import OutlierConfig, add_outliers


def chain(n: int = 200) -> PoseGraph:
    rng = np.random.default_rng(5)
    steps = np.column_stack([np.ones(n - 1), np.zeros(n - 1), rng.uniform(-0.3, 0.3, n - 1)])
    poses = [np.zeros(3)]
    for s in steps:
        poses.append(se2.compose(poses[-1], s))
    info = np.broadcast_to(np.diag([100.0, 100.0, 400.0]), (n, 3, 3)).copy()
    return PoseGraph(2, np.arange(n) + 1000, np.array(poses),
                     np.r_[np.arange(n - 1), 0] + 1000, np.r_[np.arange(1, n), 150] + 1000,
                     np.vstack([steps, se2.between(poses[0], poses[150])]), info, name="chain")


@pytest.mark.parametrize("kind", ["random", "local", "grouped"])
def test_reproducible_by_seed(kind):
    g = chain()
    cfg = OutlierConfig(kind=kind, count=37)
    a = add_outliers(g, cfg, np.random.default_rng(11), 11)
    b = add_outliers(g, cfg, np.random.default_rng(11), 11)
    c = add_outliers(g, cfg, np.random.default_rng(12), 12)
    assert np.array_equal(a.graph.measurements, b.graph.measurements)
    assert np.array_equal(a.graph.edge_from, b.graph.edge_from) and np.array_equal(a.graph.edge_to, b.graph.edge_to)
    assert not np.array_equal(a.graph.measurements, c.graph.measurements)
    assert a.graph.num_edges == g.num_edges + 37 and int(a.is_outlier.sum()) == 37
    assert not a.is_outlier[: g.num_edges].any()
    new_from, new_to = a.graph.edge_from[g.num_edges:], a.graph.edge_to[g.num_edges:]
    assert np.all(np.abs(new_from - new_to) > 1)                  # never an odometry pair
    assert np.isin(new_from, g.vertex_ids).all() and np.isin(new_to, g.vertex_ids).all()
    # information copied from the graph's (one) loop closure
    assert np.array_equal(a.graph.information[-1], g.information[-1])


def test_local_outliers_stay_within_the_window():
    a = add_outliers(chain(), OutlierConfig(kind="local", count=200, local_window=20), np.random.default_rng(1))
    gap = np.abs(a.graph.edge_from[-200:] - a.graph.edge_to[-200:])
    assert gap.max() <= 20 and gap.min() >= 2


def test_grouped_outliers_are_mutually_consistent():
    # consecutive members l, l+1 of a group close a cycle with the graph's poses:
    # z_l^-1 (X_{a+l}^-1 X_{a+l+1}) z_{l+1} (X_{b+l+1}^-1 X_{b+l}) = identity
    g = chain()
    a = add_outliers(g, OutlierConfig(kind="grouped", count=30, group_size=10), np.random.default_rng(4))
    row = g.index_of()
    i = np.array([row[v] for v in a.graph.edge_from[-30:]])
    j = np.array([row[v] for v in a.graph.edge_to[-30:]])
    z = a.graph.measurements[-30:]
    X = g.poses
    same_group = (np.diff(i) == 1) & (np.diff(j) == 1)
    assert same_group.sum() >= 25
    for l in np.flatnonzero(same_group):
        cycle = se2.compose(se2.compose(se2.inverse(z[l]), se2.between(X[i[l]], X[i[l + 1]])),
                            se2.compose(z[l + 1], se2.between(X[j[l + 1]], X[j[l]])))
        assert np.allclose(cycle, 0.0, atol=1e-9)


def test_bad_config_is_a_config_error():
    with pytest.raises(ConfigError, match="kind"):
        OutlierConfig(kind="everywhere")
    with pytest.raises(ConfigError, match="count"):
        OutlierConfig(count=-1)
