"""Marginal covariances against a hand derivation, and robust kernels against a false loop
closure."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slamkit.backend.solvers import OptimizeConfig, optimize
from slamkit.data.pose_graph import PoseGraph


def test_marginals_of_a_three_pose_chain_worked_example():
    """X0 = (0,0,0), X1 = (1,0,0), X2 = (2,0,0); edges 0->1 and 1->2 measure exactly (1,0,0) with
    sigmas (0.2, 0.1, 0.05); gauge prior sigma p = 0.1 on X0. At the (zero-residual) optimum
    GTSAM's marginals are in each pose's body frame and propagate as
    Sigma_j = A Sigma_i A^T + Sigma_z with A = Ad(Z^-1) = [[1,0,0],[0,1,1],[0,0,1]] (Pose2
    adjoint of (-1,0,0): heading error at i moves j sideways by 1 m per rad). By hand:
      Sigma_0 = p^2 I = 0.01 I
      Sigma_1 = [[p^2+sx^2, 0, 0], [0, 2p^2+sy^2, p^2], [0, p^2, p^2+st^2]]
              = [[0.05, 0, 0], [0, 0.03, 0.01], [0, 0.01, 0.0125]]
      Sigma_2 = [[p^2+2sx^2, 0, 0], [0, 5p^2+2sy^2+st^2, 2p^2+st^2], [0, 2p^2+st^2, p^2+2st^2]]
              = [[0.09, 0, 0], [0, 0.0725, 0.0225], [0, 0.0225, 0.015]]"""
    sigma = np.array([0.2, 0.1, 0.05])
    info = np.diag(1 / sigma**2)
    graph = PoseGraph(dim=2, vertex_ids=np.array([0, 1, 2]),
                      poses=np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]),
                      edge_from=np.array([0, 1]), edge_to=np.array([1, 2]),
                      measurements=np.array([[1, 0, 0], [1, 0, 0.0]]),
                      information=np.stack([info, info]))
    result = optimize(graph, OptimizeConfig(compute_marginals=True, prior_sigma=0.1))
    assert result.final_error == pytest.approx(0.0, abs=1e-20)
    cov = result.marginal_covariances
    assert cov.shape == (3, 3, 3)
    np.testing.assert_allclose(cov[0], 0.01 * np.eye(3), atol=1e-12)
    np.testing.assert_allclose(cov[1], [[0.05, 0, 0], [0, 0.03, 0.01], [0, 0.01, 0.0125]], atol=1e-12)
    np.testing.assert_allclose(cov[2], [[0.09, 0, 0], [0, 0.0725, 0.0225], [0, 0.0225, 0.015]],
                               atol=1e-12)


def test_3d_marginals_come_back_in_g2o_order():
    """Two poses joined by an identity measurement with g2o-order sigmas (translation 0.1, 0.2,
    0.3 m; rotation 0.01, 0.02, 0.03 rad), prior p = 0.1: Sigma_1 = p^2 I + diag(sigma^2) in the
    PoseGraph's (x, y, z, rx, ry, rz) order, i.e. diag(0.02, 0.05, 0.1, 0.0101, 0.0104, 0.0109)."""
    sigma = np.array([0.1, 0.2, 0.3, 0.01, 0.02, 0.03])
    ident = [0, 0, 0, 1, 0, 0, 0.0]
    graph = PoseGraph(dim=3, vertex_ids=np.array([0, 1]), poses=np.array([ident, ident]),
                      edge_from=np.array([0]), edge_to=np.array([1]),
                      measurements=np.array([ident]), information=np.diag(1 / sigma**2)[None])
    result = optimize(graph, OptimizeConfig(compute_marginals=True, prior_sigma=0.1))
    np.testing.assert_allclose(result.marginal_covariances[0], 0.01 * np.eye(6), atol=1e-12)
    np.testing.assert_allclose(result.marginal_covariances[1],
                               np.diag([0.02, 0.05, 0.1, 0.0101, 0.0104, 0.0109]), atol=1e-12)


def test_no_marginals_unless_asked():
    ident = [0, 0, 0.0]
    graph = PoseGraph(dim=2, vertex_ids=np.array([0, 1]), poses=np.array([ident, ident]),
                      edge_from=np.array([0]), edge_to=np.array([1]),
                      measurements=np.array([ident]), information=np.eye(3)[None])
    assert optimize(graph).marginal_covariances is None


# ---- robust kernels ---------------------------------------------------------------------------

def _compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1],
                     math.remainder(a[2] + b[2], 2 * math.pi)])


def _between(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    d = b[:2] - a[:2]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], math.remainder(b[2] - a[2], 2 * math.pi)])


def square_with_false_loop_closure(with_outlier: bool = True):
    """40 poses around a 10 m x 10 m square (1 m steps, 90-degree turns every 10 poses);
    odometry and k->k+2 edges plus two loop closures at the start/end, all with noise sigma
    (0.05 m, 0.05 m, 0.01 rad) from a seeded rng; and one FALSE loop closure claiming poses 10
    and 30 (truly 14.1 m apart) coincide. Initial estimate: dead reckoning."""
    rng = np.random.default_rng(7)
    truth = [np.zeros(3)]
    for k in range(1, 40):
        truth.append(_compose(truth[-1], [1.0, 0.0, 0.0 if k % 10 else math.pi / 2]))
    truth = np.array(truth)
    sigma = np.array([0.05, 0.05, 0.01])
    pairs = [(k, k + 1) for k in range(39)] + [(39, 0), (38, 1)] + [(k, k + 2) for k in range(38)]
    meas = [_between(truth[a], truth[b]) + rng.normal(0, sigma) for a, b in pairs]
    if with_outlier:
        pairs.append((10, 30))
        meas.append(np.zeros(3))
    init = [truth[0]]
    for k in range(39):
        init.append(_compose(init[-1], meas[k]))
    graph = PoseGraph(dim=2, vertex_ids=np.arange(40), poses=np.array(init),
                      edge_from=np.array([p[0] for p in pairs]), edge_to=np.array([p[1] for p in pairs]),
                      measurements=np.array(meas),
                      information=np.tile(np.diag(1 / sigma**2), (len(pairs), 1, 1)))
    return graph, truth


def _ate_m(poses, truth):
    # the gauge prior pins pose 0 at its true value, so no alignment is needed
    return float(np.sqrt(np.mean(np.sum((poses[:, :2] - truth[:, :2]) ** 2, axis=1))))


def test_robust_kernels_reject_a_false_loop_closure():
    """Measured: without the outlier LM reaches ATE 0.132 m; with it, plain least squares is
    dragged to ATE 3.22 m, Huber (k = 1.345) holds 0.172 m and Cauchy (k = 2.3849) 0.130 m."""
    graph, truth = square_with_false_loop_closure()
    clean_graph, _ = square_with_false_loop_closure(with_outlier=False)
    ate = {kind: _ate_m(optimize(graph, OptimizeConfig(robust=kind)).poses, truth)
           for kind in ("none", "huber", "cauchy")}
    clean = _ate_m(optimize(clean_graph).poses, truth)
    assert clean == pytest.approx(0.132, abs=2e-3)
    assert ate["none"] == pytest.approx(3.22, abs=0.02)
    assert ate["huber"] == pytest.approx(0.172, abs=2e-3)
    assert ate["cauchy"] == pytest.approx(0.130, abs=2e-3)
    assert ate["none"] > 10 * ate["cauchy"] and ate["huber"] < 1.5 * clean
