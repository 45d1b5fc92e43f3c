"""PCM-style pairwise consistency check of loop closures (slamkit.frontend.pcm)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2 as chi2_dist

from slamkit.data.pose_graph import PoseGraph, transforms_to_rows
from slamkit.errors import ConfigError
from slamkit.frontend.pcm import (cycle_errors, dead_reckoning, exact_max_clique, greedy_max_clique, loop_closures,
                                  odometry_chain, pcm)
from slamkit.geometry import se2, se3


def test_greedy_clique_finds_the_planted_clique():
    # vertices 0-3 form a clique; 4 and 5 each touch two of them and each other
    adj = np.zeros((6, 6), bool)
    for a in range(4):
        for b in range(4):
            adj[a, b] = True
    for a, b in ((4, 0), (4, 1), (5, 2), (5, 3), (4, 5)):
        adj[a, b] = adj[b, a] = True
    assert greedy_max_clique(adj).tolist() == [0, 1, 2, 3]
    assert exact_max_clique(adj).tolist() == [0, 1, 2, 3]


def test_exact_clique_where_greedy_peeling_fails():
    # a K4 (vertices 0-3, degree 3) beside a K5,5 (vertices 4-13, degree 5, no triangle): peeling
    # the least degree first destroys the K4 and ends on a single edge of the K5,5
    adj = np.zeros((14, 14), bool)
    adj[:4, :4] = True
    adj[4:9, 9:14] = adj[9:14, 4:9] = True
    assert len(greedy_max_clique(adj)) == 2
    assert exact_max_clique(adj).tolist() == [0, 1, 2, 3]
    with pytest.raises(ConfigError, match="clique solver"):
        pcm(PoseGraph(2, np.arange(3), np.zeros((3, 3)), np.array([0, 1]), np.array([1, 2]), np.zeros((2, 3)),
                      np.broadcast_to(np.eye(3), (2, 3, 3))), clique="best")


def test_true_loop_closures_are_kept_and_gross_outliers_dropped():
    # a noise-free spiral: the odometry and 6 true loop closures agree exactly; 4 false ones do not
    n = 120
    steps = np.tile([1.0, 0.0, 2 * np.pi / 40], (n - 1, 1))
    poses = [np.zeros(3)]
    for s in steps:
        poses.append(se2.compose(poses[-1], s))
    poses = np.array(poses)
    true_pairs = [(0, 40), (5, 45), (10, 90), (20, 100), (40, 80), (60, 100)]
    false = [(3, 70, [4.0, -2.0, 1.0]), (15, 33, [-6.0, 1.0, -2.0]), (50, 110, [2.0, 7.0, 0.5]),
             (8, 99, [0.0, 5.0, 3.0])]
    ef = list(range(n - 1)) + [a for a, _ in true_pairs] + [a for a, _, _ in false]
    et = list(range(1, n)) + [b for _, b in true_pairs] + [b for _, b, _ in false]
    z = np.vstack([steps, se2.between(poses[[a for a, _ in true_pairs]], poses[[b for _, b in true_pairs]]),
                   np.array([m for _, _, m in false])])
    info = np.broadcast_to(np.diag([100.0, 100.0, 1000.0]), (len(ef), 3, 3)).copy()
    g = PoseGraph(2, np.arange(n), poses, np.array(ef), np.array(et), z, info)
    assert np.allclose(dead_reckoning(g), poses)
    result = pcm(g)
    assert result.accepted[: n - 1 + len(true_pairs)].all()
    assert not result.accepted[n - 1 + len(true_pairs):].any()
    assert result.clique_size == 6




def _chain_with_two_closures(dim: int, closures, rng: np.random.Generator, n: int = 12):
    """A noise-free chain of ``n`` poses with random steps, anisotropic correlated step covariance,
    and the two loop closures ``closures`` ((from, to) rows) measured exactly; covariance x2."""
    group = se2 if dim == 2 else se3
    if dim == 2:
        steps = np.column_stack([rng.uniform(0.5, 1.5, n - 1), rng.uniform(-0.3, 0.3, n - 1),
                                 rng.uniform(-0.6, 0.6, n - 1)])
        cov_odo = np.array([[0.01, 0.003, 0.001], [0.003, 0.02, -0.002], [0.001, -0.002, 0.004]])
    else:
        steps = se3.exp(np.column_stack([rng.uniform(0.5, 1.5, n - 1), rng.uniform(-0.3, 0.3, (n - 1, 2)),
                                         rng.uniform(-0.4, 0.4, (n - 1, 3))]))
        A = rng.normal(size=(6, 6)) * 0.03
        cov_odo = A @ A.T + np.diag([0.01, 0.01, 0.01, 0.002, 0.002, 0.002])
    X = [np.zeros(3) if dim == 2 else se3.identity()]
    for s in steps:
        X.append(group.compose(X[-1], s))
    X = np.array(X)
    d = cov_odo.shape[0]
    (i, j), (k, l) = closures
    z = np.concatenate([steps, np.stack([group.between(X[i], X[j]), group.between(X[k], X[l])])])
    cov = np.concatenate([np.broadcast_to(cov_odo, (n - 1, d, d)), np.broadcast_to(2 * cov_odo, (2, d, d))])

    graph = PoseGraph(dim, np.arange(n), transforms_to_rows(dim, X), np.r_[np.arange(n - 1), i, k],
                      np.r_[np.arange(1, n), j, l], transforms_to_rows(dim, z), np.linalg.inv(cov))
    return group, graph, X, steps, z[n - 1:], cov_odo


# (closures, measured relative Frobenius error of the first-order covariance against 20000 samples):
# disjoint stretches, overlapping ones walked the same way, reversed, and nested opposite ways
CYCLES = [(((1, 9), (3, 11)), 0.015, 0.026), (((1, 9), (8, 2)), 0.006, 0.016),
          (((10, 2), (4, 8)), 0.020, 0.020), (((1, 3), (9, 11)), 0.019, 0.052)]


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("closures, err2, err3", CYCLES)
def test_cycle_covariance_matches_monte_carlo_composition(dim, closures, err2, err3):
    """The prefix-sum first-order covariance of the cycle error E_ab against the sample covariance
    of Log(E_ab) over 20000 brute-force compositions of sampled step and closure noise
    (z Exp(n), n ~ N(0, Sigma)); and the Mahalanobis test at the noisy samples is chi2_d."""
    rng = np.random.default_rng(0)
    group, graph, X, steps, z_loops, cov_odo = _chain_with_two_closures(dim, closures, rng)
    n, d, N = len(X), cov_odo.shape[0], 20000
    chain = odometry_chain(graph)
    eps, cov_world = cycle_errors(chain, loop_closures(graph, chain, np.array([n - 1, n])), np.array(0),
                                  np.array(1))
    assert np.allclose(eps, 0.0, atol=1e-9)  # two exact closures close the cycle
    (i, j), (k, l) = closures
    Ad = group.adjoint(group.inverse(X[j]))
    cov_cycle = Ad @ cov_world @ Ad.T  # the same covariance in E_ab's own (pose j) frame
    chol_odo, chol_lc = np.linalg.cholesky(cov_odo), np.linalg.cholesky(2 * cov_odo)
    u = group.compose(steps[None], group.exp(rng.normal(size=(N, n - 1, d)) @ chol_odo.T))
    za = group.compose(z_loops[0], group.exp(rng.normal(size=(N, d)) @ chol_lc.T))
    zb = group.compose(z_loops[1], group.exp(rng.normal(size=(N, d)) @ chol_lc.T))
    Xn = [np.broadcast_to(X[0], (N,) + X[0].shape)]
    for m in range(n - 1):
        Xn.append(group.compose(Xn[-1], u[:, m]))
    Xn = np.stack(Xn, axis=1)
    E = group.compose(group.compose(group.inverse(za), group.between(Xn[:, i], Xn[:, k])),
                      group.compose(zb, group.between(Xn[:, l], Xn[:, j])))
    sample = np.cov(group.log(E).T)
    err = np.linalg.norm(sample - cov_cycle) / np.linalg.norm(cov_cycle)
    assert err == pytest.approx(err2 if dim == 2 else err3, abs=2e-3)
    assert err < 0.06
    # the whole test evaluated at 400 noisy samples (dead reckoning and Jacobians from the noisy
    # measurements) is chi2_d: mean d, about 99% inside the 0.99 gate
    stats = []
    for s in range(400):
        zs = np.concatenate([u[s], np.stack([za[s], zb[s]])])
        noisy = replace(graph, measurements=transforms_to_rows(dim, zs))
        ch = odometry_chain(noisy)
        e, c = cycle_errors(ch, loop_closures(noisy, ch, np.array([n - 1, n])), np.array(0), np.array(1))
        stats.append(float(e @ np.linalg.solve(c, e)))
    stats = np.array(stats)
    assert abs(stats.mean() - d) < 0.25 * d
    assert np.mean(stats <= chi2_dist.ppf(0.99, d)) >= 0.97


def test_pcm_in_space_keeps_true_closures_and_drops_gross_outliers():
    # a noise-free climbing helix: 6 true closures agree with the odometry exactly, 4 false ones
    # (metres off, tilted) do not; dead reckoning reproduces the poses in the (x, y, z, quat) layout
    n = 120
    xi = np.tile([1.0, 0.0, 0.05, 0.0, 0.02, 2 * np.pi / 40], (n - 1, 1))
    steps = se3.exp(xi)
    X = [se3.identity()]
    for s in steps:
        X.append(se3.compose(X[-1], s))
    X = np.array(X)
    true_pairs = [(0, 40), (5, 45), (10, 90), (20, 100), (40, 80), (60, 100)]
    false = [(3, 70, [4.0, -2.0, 1.0, 0.3, 1.0, -0.5]), (15, 33, [-6.0, 1.0, 2.0, -1.0, 0.2, 2.0]),
             (50, 110, [2.0, 7.0, -3.0, 0.5, 0.5, 0.5]), (8, 99, [0.0, 5.0, 1.0, 2.5, 0.0, 1.0])]
    ef = list(range(n - 1)) + [a for a, _ in true_pairs] + [a for a, _, _ in false]
    et = list(range(1, n)) + [b for _, b in true_pairs] + [b for _, b, _ in false]
    z = np.concatenate([steps, se3.between(X[[a for a, _ in true_pairs]], X[[b for _, b in true_pairs]]),
                        se3.exp(np.array([m for _, _, m in false]))])
    info = np.broadcast_to(np.diag([100.0, 100.0, 100.0, 1000.0, 1000.0, 1000.0]), (len(ef), 6, 6)).copy()
    g = PoseGraph(3, np.arange(n), transforms_to_rows(3, X), np.array(ef), np.array(et), transforms_to_rows(3, z), info)
    assert np.allclose(dead_reckoning(g), transforms_to_rows(3, X), atol=1e-9)
    result = pcm(g)
    assert result.accepted[: n - 1 + len(true_pairs)].all()
    assert not result.accepted[n - 1 + len(true_pairs):].any()
    assert result.clique_size == 6
