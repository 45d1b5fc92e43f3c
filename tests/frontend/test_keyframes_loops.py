"""Keyframe selection, loop-closure candidates by distance and their ICP verification, and the
despeckle filter -- worked examples with stated numbers."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import ConfigError
from slamkit.frontend.icp import scan_to_points
from slamkit.frontend.keyframes import KeyframeConfig, select_keyframes
from slamkit.frontend.loop_closure import LoopClosureConfig, detect_loops, loop_candidates, verify_loop
from slamkit.frontend.preprocess import despeckle, voxel_downsample
from slamkit.geometry import se2
from slamkit.maps.generators import OfficeConfig, office
from slamkit.maps.raycast import RayCaster

BEAMS = np.linspace(-np.pi, np.pi, 360, endpoint=False)


def test_keyframes_by_distance_and_rotation():
    # 0.1 m steps along x: a keyframe every 5 steps (0.5 m); then a turn on the spot in 5.01
    # degree steps: a keyframe every 4 steps (20.04 degrees; exactly 20 would sit on the
    # threshold, where the last bit of the angle difference decides)
    straight = np.column_stack([np.arange(21) * 0.1, np.zeros(21), np.zeros(21)])
    turn = np.column_stack([np.full(12, 2.0), np.zeros(12), np.deg2rad(5.01) * np.arange(1, 13)])
    poses = np.vstack([straight, turn])
    idx = select_keyframes(np.arange(len(poses)) * 0.1, poses)
    np.testing.assert_array_equal(idx, [0, 5, 10, 15, 20, 24, 28, 32])
    # a time limit adds keyframes while standing still
    still = np.zeros((10, 3))
    idx = select_keyframes(np.arange(10) * 1.0, still, KeyframeConfig(max_interval_s=3.0))
    np.testing.assert_array_equal(idx, [0, 3, 6, 9])


def _square(n_side=20, side_m=10.0):
    t = np.linspace(0, 1, n_side, endpoint=False)
    legs = [np.column_stack([t * side_m, np.zeros(n_side)]),
            np.column_stack([np.full(n_side, side_m), t * side_m]),
            np.column_stack([side_m - t * side_m, np.full(n_side, side_m)]),
            np.column_stack([np.zeros(n_side), side_m - t * side_m])]
    xy = np.vstack(legs + [np.zeros((1, 2))])
    return np.column_stack([xy, np.zeros(len(xy))])


def test_loop_candidates_on_a_square():
    poses = _square()  # 81 keyframes 0.5 m apart; the last returns to the first
    cfg = LoopClosureConfig(search_radius_m=1.2, min_index_gap=10, min_path_gap_m=5.0,
                            max_candidates_per_keyframe=2)
    pairs = loop_candidates(poses, cfg)
    # only the closing corner qualifies. Within 1.2 m: (0,80) 0 m, (1,80) 0.5, (2,80) 1.0,
    # (0,79) 0.5, (1,79) 0.71, (2,79) 1.12, (0,78) 1.0, (1,78) 1.12; two closest per j kept
    assert {tuple(map(int, p)) for p in pairs} == {(0, 80), (1, 80), (0, 79), (1, 79), (0, 78), (1, 78)}
    np.testing.assert_array_equal(pairs[:, 1], [78, 78, 79, 79, 80, 80])  # by j, closest first
    assert tuple(pairs[-2]) == (0, 80)
    assert np.all(pairs[:, 1] - pairs[:, 0] >= 10)


@pytest.fixture(scope="module")
def office_caster():
    grid = office(np.random.default_rng(4), OfficeConfig(width_m=20.0, height_m=20.0))
    return RayCaster(grid)


def test_verify_accepts_true_loop_and_rejects_false_one(office_caster):
    rng = np.random.default_rng(0)
    a = np.array([4.82, 17.53, 0.67])
    b = se2.compose(a, [0.4, 0.2, 0.3])  # the same room, revisited
    far = np.array([14.52, 1.92, 2.25])  # another room
    pts = {k: scan_to_points(office_caster.scan(p, BEAMS, 20.0)[0] + rng.normal(0, 0.02, 360), BEAMS)
           for k, p in (("a", a), ("b", b), ("far", far))}
    true_rel = se2.between(a, b)
    drifted_guess = se2.compose(true_rel, [0.5, -0.4, 0.1])  # what a drifted estimate believes
    ok, res = verify_loop(pts["a"], pts["b"], drifted_guess)
    assert ok and res.fitness > 0.8
    assert np.hypot(*se2.between(true_rel, res.target_T_source)[:2]) < 0.02
    ok_far, res_far = verify_loop(pts["a"], pts["far"], se2.between(a, far))
    # measured fitness 0.93 for the true pair; the wrong pair cannot be aligned (< 0.6)
    assert not ok_far and res_far.fitness < 0.6


def test_detect_loops_end_to_end(office_caster):
    rng = np.random.default_rng(1)
    a = np.array([4.82, 17.53, 0.67])
    truth = np.array([a, se2.compose(a, [3.0, 0.0, 0.0]), se2.compose(a, [0.3, 0.1, 0.2])])
    pts = [scan_to_points(office_caster.scan(p, BEAMS, 20.0)[0] + rng.normal(0, 0.02, 360), BEAMS)
           for p in truth]
    estimate = truth + np.array([[0, 0, 0], [0, 0, 0], [0.4, -0.3, 0.05]])
    loops, tried = detect_loops(estimate, pts, LoopClosureConfig(min_index_gap=2, min_path_gap_m=1.0))
    assert tried == 1 and len(loops) == 1 and (loops[0].i, loops[0].j) == (0, 2)
    err = se2.between(se2.between(truth[0], truth[2]), loops[0].i_T_j)
    assert np.hypot(err[0], err[1]) < 0.02 and abs(err[2]) < 0.005


def test_despeckle_removes_isolated_returns():
    r = np.array([5.0, 5.02, 5.05, 12.0, 5.1, 5.12, np.nan, 3.0, np.nan, 7.0, 7.1])
    out = despeckle(r, jump_m=0.3, relative=0.05, circular=False)
    # 12.0 disagrees with both 5.05 and 5.1 -> removed; 3.0 sits between two no-returns -> removed
    expected = r.copy()
    expected[[3, 7]] = np.nan
    np.testing.assert_array_equal(np.isnan(out), np.isnan(expected))
    # circular: the last beam neighbours the first
    assert np.isnan(despeckle(np.array([1.0, 1.0, 1.0, 9.0]), circular=True)[3])


def test_voxel_downsample_keeps_one_centroid_per_cell():
    pts = np.array([[0.01, 0.01], [0.03, 0.04], [0.12, 0.0], [0.02, 0.02], [-0.01, 0.0]])
    out = voxel_downsample(pts, 0.05)
    # cells (0, 0): the three points in [0, 0.05)^2; (2, 0): 0.12; (-1, 0): -0.01 -- in the order of
    # the cells' first points
    np.testing.assert_allclose(out, [[0.02, 7.0 / 300.0], [0.12, 0.0], [-0.01, 0.0]])
    np.testing.assert_array_equal(voxel_downsample(pts, 0.0), pts)


def test_bad_config():
    with pytest.raises(ConfigError):
        KeyframeConfig(min_translation_m=0.0)
    with pytest.raises(ConfigError):
        LoopClosureConfig(min_fitness=0.0)
