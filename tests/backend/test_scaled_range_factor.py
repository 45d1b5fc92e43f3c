"""The range factor with an unknown scale, r = s |m - p| (issue 12 follow-up: Plaza's ranges are
~7% long), as the smoothers build it: a worked example and its Jacobians against finite
differences on the manifold (Pose2 retracted in the body frame)."""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from slamkit.backend.landmark_slam import RANGE_SCALE_KEY, scaled_range_factor
from slamkit.models import range_only


def _values(pose=gtsam.Pose2(1.0, 2.0, 0.7), beacon=(4.0, 6.0), scale=1.07) -> gtsam.Values:
    values = gtsam.Values()
    values.insert(X(0), pose)
    values.insert(L(0), gtsam.Point2(*beacon))
    values.insert(RANGE_SCALE_KEY, np.array([scale]))
    return values


def test_worked_example_and_jacobians_by_finite_differences():
    factor = scaled_range_factor(X(0), L(0), RANGE_SCALE_KEY, 5.0, gtsam.noiseModel.Unit.Create(1))
    values = _values()
    # beacon - body = (3, 4): distance 5, u = (0.6, 0.8); error 1.07 * 5 - 5 = 0.35
    np.testing.assert_allclose(factor.unwhitenedError(values), [0.35], atol=1e-12)
    A, b = factor.linearize(values).jacobian()
    c, s = np.cos(0.7), np.sin(0.7)
    expected = np.array([[*(-1.07 * np.array([0.6, 0.8]) @ np.array([[c, -s], [s, c]])), 0.0,
                          1.07 * 0.6, 1.07 * 0.8, 5.0]])
    np.testing.assert_allclose(A, expected, atol=1e-12)
    np.testing.assert_allclose(b, [-0.35], atol=1e-12)
    # central differences: the pose through Pose2.retract, the beacon and s additively
    eps, numeric = 1e-6, np.zeros(6)
    for i in range(6):
        d = np.zeros(6)
        d[i] = eps
        plus = _values(values.atPose2(X(0)).retract(d[:3]), values.atPoint2(L(0)) + d[3:5], 1.07 + d[5])
        minus = _values(values.atPose2(X(0)).retract(-d[:3]), values.atPoint2(L(0)) - d[3:5], 1.07 - d[5])
        numeric[i] = (factor.unwhitenedError(plus)[0] - factor.unwhitenedError(minus)[0]) / (2 * eps)
    np.testing.assert_allclose(A[0], numeric, atol=1e-8)


def test_scale_one_is_gtsams_range_factor():
    values = _values(scale=1.0)
    model = gtsam.noiseModel.Isotropic.Sigma(1, 0.6)
    ours = scaled_range_factor(X(0), L(0), RANGE_SCALE_KEY, 4.2, model)
    theirs = gtsam.RangeFactor2D(X(0), L(0), 4.2, model)
    np.testing.assert_allclose(ours.unwhitenedError(values), theirs.unwhitenedError(values), atol=1e-12)
    np.testing.assert_allclose(ours.linearize(values).jacobian()[0][:, :5],
                               theirs.linearize(values).jacobian()[0], atol=1e-12)


def test_scaled_jacobians_model():
    Jp, Jm, distance = range_only.observe_scaled_jacobians(np.array([1.0, 2.0]), np.array([4.0, 6.0]), 2.0)
    np.testing.assert_allclose(Jp, [-1.2, -1.6])
    np.testing.assert_allclose(Jm, [1.2, 1.6])
    assert distance == 5.0
