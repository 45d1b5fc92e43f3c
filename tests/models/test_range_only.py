"""Range-only model: values, Jacobians and the worked trilateration examples."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.models import range_only


def test_observe_and_jacobians():
    assert range_only.observe(np.array([1.0, 1.0]), np.array([4.0, 5.0])) == pytest.approx(5.0)
    dp, dm = range_only.observe_jacobians(np.array([1.0, 1.0]), np.array([4.0, 5.0]))
    np.testing.assert_allclose(dm, [0.6, 0.8])
    np.testing.assert_allclose(dp, [-0.6, -0.8])


def test_trilaterate_worked_example_three_positions():
    # beacon at (3, 4) ranged from (0, 0), (10, 0), (0, 10): 5, sqrt(65), sqrt(45)
    p = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    r = np.array([5.0, np.sqrt(65.0), np.sqrt(45.0)])
    candidates = range_only.trilaterate(p, r)
    # the mirror image across the baseline's axis converges back to the beacon: one candidate
    assert len(candidates) == 1
    np.testing.assert_allclose(candidates[0].world_p_landmark, [3.0, 4.0], atol=1e-9)
    assert candidates[0].rms_m == pytest.approx(0.0, abs=1e-9)


def test_trilaterate_straight_baseline_gives_both_mirror_candidates():
    # from (0, 0), (5, 0), (10, 0) the ranges 5, sqrt(20), sqrt(65) fit (3, 4) and (3, -4) alike
    p = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])
    r = np.array([5.0, np.sqrt(20.0), np.sqrt(65.0)])
    candidates = range_only.trilaterate(p, r)
    found = sorted(tuple(np.round(c.world_p_landmark, 9)) for c in candidates)
    assert found == [(3.0, -4.0), (3.0, 4.0)]
    assert all(c.rms_m < 1e-9 for c in candidates)


def test_trilaterate_needs_a_baseline():
    assert range_only.trilaterate(np.zeros((4, 2)), np.ones(4)) == []
    assert range_only.trilaterate(np.zeros((2, 2)), np.ones(2)) == []
