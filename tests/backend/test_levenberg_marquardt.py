"""slamkit's Python-driven Levenberg-Marquardt takes GTSAM's LM steps: on the same graph (here a
range-only graph with the scaled Python CustomFactor, and one of GTSAM's own factors only) it
stops after the same number of iterations at the same error and values."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from gtsam.symbol_shorthand import L, X

from slamkit.backend.landmark_slam import RANGE_SCALE_KEY, scaled_range_factor
from slamkit.backend.levenberg_marquardt import levenberg_marquardt

BEACONS = np.array([[10.0, 0.0], [0.0, 12.0], [-8.0, -6.0]])


def _range_only_graph(scaled: bool, n: int = 40, seed: int = 2):
    """A circle of n poses with odometry, ranges 7% long to three beacons (noise 0.05 m), and an
    initial guess 0.5 m / 0.1 rad off; the scale is a variable when ``scaled``."""
    rng = np.random.default_rng(seed)
    graph, initial = gtsam.NonlinearFactorGraph(), gtsam.Values()
    poses = [gtsam.Pose2(5 * np.cos(a), 5 * np.sin(a), a + np.pi / 2)
             for a in np.linspace(0, 2 * np.pi, n, endpoint=False)]
    graph.add(gtsam.PriorFactorPose2(X(0), poses[0], gtsam.noiseModel.Isotropic.Sigma(3, 1e-3)))
    odo = gtsam.noiseModel.Diagonal.Sigmas(np.array([0.05, 0.05, 0.02]))
    rmodel = gtsam.noiseModel.Isotropic.Sigma(1, 0.05)
    for k, pose in enumerate(poses):
        if k:
            graph.add(gtsam.BetweenFactorPose2(X(k - 1), X(k), poses[k - 1].between(pose), odo))
        initial.insert(X(k), pose.retract(np.array([0.5, -0.5, 0.1]) * rng.standard_normal(3)))
        for j, beacon in enumerate(BEACONS):
            r = np.linalg.norm(beacon - [pose.x(), pose.y()]) + 0.05 * rng.standard_normal()
            if scaled:
                graph.add(scaled_range_factor(X(k), L(j), RANGE_SCALE_KEY, 1.07 * r, rmodel))
            else:
                graph.add(gtsam.RangeFactor2D(X(k), L(j), r, rmodel))
    for j, beacon in enumerate(BEACONS):
        initial.insert(L(j), gtsam.Point2(*(beacon + 1.0)))
    if scaled:
        graph.add(gtsam.PriorFactorVector(RANGE_SCALE_KEY, np.ones(1), gtsam.noiseModel.Isotropic.Sigma(1, 0.1)))
        initial.insert(RANGE_SCALE_KEY, np.ones(1))
    return graph, initial


@pytest.mark.parametrize("scaled", [True, False])
@pytest.mark.parametrize("lambda_upper_bound", [1e5, 1e10])
def test_the_same_steps_as_gtsams_lm(scaled, lambda_upper_bound):
    graph, initial = _range_only_graph(scaled)
    params = gtsam.LevenbergMarquardtParams()
    params.setlambdaUpperBound(lambda_upper_bound)
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, initial, params)
    theirs = optimizer.optimize()
    ours = levenberg_marquardt(graph, initial, lambda_upper_bound=lambda_upper_bound)
    assert ours.iterations == optimizer.iterations() > 2
    assert ours.trials >= ours.iterations
    assert ours.error == pytest.approx(graph.error(theirs), rel=1e-9)
    assert ours.error == pytest.approx(graph.error(ours.values), rel=1e-12)
    for k in range(40):
        np.testing.assert_allclose(ours.values.atPose2(X(k)).translation(), theirs.atPose2(X(k)).translation(),
                                   atol=1e-7)
    if scaled:
        assert ours.values.atVector(RANGE_SCALE_KEY)[0] == pytest.approx(1.07, abs=0.005)


def test_max_iterations_stops_early():
    graph, initial = _range_only_graph(True)
    capped = levenberg_marquardt(graph, initial, max_iterations=2)
    assert capped.iterations == 2
    assert graph.error(initial) > capped.error > levenberg_marquardt(graph, initial).error
