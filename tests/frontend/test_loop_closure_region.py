"""slamkit.frontend.loop_closure.DriftRegion: the relative covariance of keyframe pairs along the
scan-match chain (first-order compounding as prefix sums) -- a worked example, agreement with a
Monte Carlo of the compounded chain, the reset at a closure, and the chi-square membership test
with its floor and cap."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import ConfigError
from slamkit.frontend.loop_closure import DriftRegion, LoopClosureConfig, chi2_quantile
from slamkit.geometry import se2


def _chain(region: DriftRegion, rels: np.ndarray, covs=None) -> np.ndarray:
    poses = [np.zeros(3)]
    region.start(poses[0])
    for k, rel in enumerate(rels):
        region.add(poses[-1], rel, None if covs is None else covs[k])
        poses.append(se2.compose(poses[-1], rel))
    return np.asarray(poses)


def test_worked_example_straight_chain():
    """Three 1 m steps along x, heading variance h per metre, translation variance a per metre:
    keyframe 3 relative to keyframe 0 has x variance 3a and y variance 3a + h (2^2 + 1^2 + 0^2)
    = 3a + 5h (the heading noise of step e turns the rest of the chain about its end)."""
    a, h = 1e-3, 2e-4
    cfg = LoopClosureConfig(drift_xy_m2_per_m=a, drift_heading_rad2_per_m=h, drift_heading_rad2_per_rad=0.0)
    region = DriftRegion(cfg)
    _chain(region, np.array([[1.0, 0, 0]] * 3))
    cov = region.covariances(np.array([0, 1, 2, 3]), 3)
    np.testing.assert_allclose(cov[0], np.diag([3 * a, 3 * a + 5 * h]), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(cov[1], np.diag([2 * a, 2 * a + 1 * h]), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(cov[3], np.zeros((2, 2)), atol=1e-15)
    np.testing.assert_allclose(region.heading_sigmas(np.array([0, 2]), 3), np.sqrt([3 * h, h]), rtol=1e-12)


def test_matches_a_monte_carlo_of_the_compounded_chain():
    """A curved 20-edge chain with edge covariances (translation and heading, per edge): the
    prefix-sum covariance of keyframe 20 relative to keyframe 4 agrees with the sample covariance
    of 20000 compounded noisy chains to within 5% (the first-order error at these noise levels
    and the sampling error, ~1.4%)."""
    rng = np.random.default_rng(0)
    rels = np.column_stack([rng.uniform(0.3, 0.6, 20), rng.uniform(-0.05, 0.05, 20), rng.uniform(-0.2, 0.2, 20)])
    covs = np.array([np.diag([4e-5, 2e-5, 1e-5])] * 20)
    cfg = LoopClosureConfig(drift_xy_m2_per_m=0.0, drift_heading_rad2_per_m=0.0, drift_heading_rad2_per_rad=0.0)
    region = DriftRegion(cfg)
    poses = _chain(region, rels, covs)
    n = 20000
    noise = rng.normal(size=(n, 20, 3)) * np.sqrt(np.diag(covs[0]))
    pose = np.tile(poses[4], (n, 1))
    for e in range(4, 20):
        pose = se2.compose(pose, se2.compose(rels[e], noise[:, e]))
    # keyframe 20 in world coordinates, keyframe 4 held fixed: the spread is relative to 4
    sample = np.cov(pose[:, :2].T)
    model = region.covariances(np.array([4]), 20)[0]
    np.testing.assert_allclose(model, sample, rtol=0.05, atol=0.05 * np.abs(sample).max())


def test_a_closure_ties_the_drift_to_the_older_place():
    """Keyframes 0-6 on a curved chain, a closure (0, 6), three more keyframes: keyframe 9 is as
    uncertain relative to 0 as the chain 6 -> 9 alone (the bound through the closure equals the
    chain's compounding from 6: the two forms of the same first-order propagation), far less than
    along the whole chain without the closure; relative to 8 the short chain stays the bound."""
    rels = np.array([[0.5, 0.0, 0.1]] * 9)
    plain, closed = DriftRegion(LoopClosureConfig()), DriftRegion(LoopClosureConfig())
    _chain(plain, rels)
    poses = _chain(closed, rels[:6])
    closed.closed(0, 6)
    for rel in rels[6:]:
        closed.add(poses[-1], rel)
        poses = np.vstack([poses, se2.compose(poses[-1], rel)])
    after = closed.covariances(np.array([0, 6, 8]), 9)
    np.testing.assert_allclose(after[0], plain.covariances(np.array([6]), 9)[0], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(after[1:], plain.covariances(np.array([6, 8]), 9), rtol=1e-9, atol=1e-15)
    assert np.trace(plain.covariances(np.array([0]), 9)[0]) > 3 * np.trace(after[0])
    # a second closure to a place no better known changes nothing
    again = DriftRegion(LoopClosureConfig())
    _chain(again, rels)
    again.closed(5, 9)
    before = again.covariances(np.array([0, 5, 7]), 9)
    again.closed(7, 9)
    np.testing.assert_array_equal(again.covariances(np.array([0, 5, 7]), 9), before)


def test_unmatched_edges_drift_faster():
    """An edge that kept the motion prior carries drift_unmatched_scale times the drift variance."""
    cfg = LoopClosureConfig(drift_unmatched_scale=100.0)
    a, b = DriftRegion(cfg), DriftRegion(cfg)
    a.add(np.zeros(3), np.array([1.0, 0.0, 0.0]), matched=True)
    b.add(np.zeros(3), np.array([1.0, 0.0, 0.0]), matched=False)
    np.testing.assert_allclose(b.covariances(np.array([0]), 1), 100 * a.covariances(np.array([0]), 1), rtol=1e-12)


def test_membership_floor_and_cap():
    """With no drift the region is the floor disc (search_radius_m); with drift it stretches
    along the chain's uncertainty up to the cap."""
    cfg = LoopClosureConfig(search_radius_m=2.0, max_search_radius_m=6.0, region_probability=0.99,
                            drift_xy_m2_per_m=0.0, drift_heading_rad2_per_m=0.0, drift_heading_rad2_per_rad=0.0)
    region = DriftRegion(cfg)
    _chain(region, np.array([[1.0, 0, 0]] * 30))
    offsets = np.array([[1.9, 0.0], [2.1, 0.0], [0.0, 1.99]])
    inside, m2, radius = region.members(np.array([0, 0, 0]), 30, offsets)
    assert inside.tolist() == [True, False, True] and np.all(radius == 0)
    q = chi2_quantile(0.99, 2)
    assert q == pytest.approx(-2 * np.log(0.01), rel=1e-9)
    np.testing.assert_allclose(m2, q * np.sum(offsets ** 2, axis=1) / 4.0, rtol=1e-12)
    # heading drift 1e-3 rad^2/m over a 30 m chain: y sigma sqrt(1e-3 * sum_k<30 k^2) = 2.92 m
    drift = DriftRegion(LoopClosureConfig(**{**cfg.__dict__, "drift_heading_rad2_per_m": 1e-3}))
    _chain(drift, np.array([[1.0, 0, 0]] * 30))
    inside, _, radius = drift.members(np.array([0, 0, 0]), 30, np.array([[0.0, 3.0], [3.0, 0.0], [0.0, 6.5]]))
    assert radius[0] == pytest.approx(np.sqrt(q * 1e-3 * sum(k * k for k in range(30))), rel=1e-9)
    assert inside.tolist() == [True, False, False]     # along y yes; along x the floor; 6.5 m: the cap


def test_config_is_checked():
    with pytest.raises(ConfigError):
        LoopClosureConfig(region_probability=1.0)
    with pytest.raises(ConfigError):
        LoopClosureConfig(search_radius_m=3.0, max_search_radius_m=2.0)
    with pytest.raises(ConfigError):
        LoopClosureConfig(drift_xy_m2_per_m=-1.0)
    with pytest.raises(ConfigError):
        LoopClosureConfig(global_depth=0)
    with pytest.raises(ConfigError, match="global_far_min_fitness"):
        LoopClosureConfig(global_far_min_fitness=0.0)
    with pytest.raises(ConfigError, match="global_far"):
        LoopClosureConfig(global_far_m=-0.1)
    with pytest.raises(ConfigError, match="global_far_max_rival"):
        LoopClosureConfig(global_far_max_rival=0.0)
    with pytest.raises(ConfigError, match="global_far_max_rival"):
        LoopClosureConfig(global_far_rival_m=0.0)
    assert LoopClosureConfig().global_far_max_rival == 1.0     # off
