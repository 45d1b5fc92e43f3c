"""slamkit.frontend.correlative: the exhaustive (dx, dy, dtheta) search finds exact grid offsets of
a synthetic scan, the multi-resolution search equals the single-level exhaustive one, and it
recovers a 40 deg turn that ICP from the guess does not."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import ConfigError
from slamkit.frontend.correlative import CorrelativeConfig, CorrelativeGrid, correlative_search
from slamkit.frontend.icp import IcpConfig, icp
from slamkit.geometry import se2


def room_scan() -> np.ndarray:
    """Points on the walls of an L-shaped room with a pillar (an asymmetric scene), every 0.037 m
    (off the 0.05 m grid, so no point sits on a cell boundary)."""
    def seg(a, b):
        t = np.arange(0.0, 1.0, 0.037 / np.hypot(*(np.subtract(b, a))))
        return np.asarray(a) + t[:, None] * (np.subtract(b, a))
    corners = [(-2.013, -1.507), (3.021, -1.507), (3.021, 0.493), (1.017, 0.493), (1.017, 2.489),
               (-2.013, 2.489), (-2.013, -1.507)]
    walls = [seg(a, b) for a, b in zip(corners[:-1], corners[1:])]
    pillar = [seg((-0.511, 0.613), (-0.211, 0.613)), seg((-0.211, 0.613), (-0.211, 1.013))]
    return np.concatenate(walls + pillar)


CFG = CorrelativeConfig(resolution_m=0.05, sigma_m=0.05, window_xy_m=0.3,
                        window_theta_rad=np.deg2rad(45.0), theta_step_rad=np.deg2rad(1.0))


@pytest.mark.parametrize("truth_cells_deg", [(3, -2, 6), (-6, 5, -40), (0, 0, 0), (1, 6, 45)])
def test_exact_offsets(truth_cells_deg):
    """The source is the target seen from target_T_source = (i * 0.05 m, j * 0.05 m, k deg):
    the search from the identity returns exactly that pose with score 1 (every point on its cell)."""
    i, j, k = truth_cells_deg
    truth = np.array([i * 0.05, j * 0.05, np.deg2rad(k)])
    target = room_scan()
    source = se2.transform_points(se2.inverse(truth), target)
    res = correlative_search(source, CorrelativeGrid(target, CFG), np.zeros(3))
    np.testing.assert_allclose(res.target_T_source, truth, atol=1e-9)
    assert res.score == pytest.approx(1.0)


def test_search_is_relative_to_the_guess():
    """From a guess (0.1 m, -0.05 m, 10 deg) the window is centred there: the truth at
    (0.3, 0.1, 30 deg) is 4 and 3 cells and 20 steps away."""
    truth = np.array([0.3, 0.1, np.deg2rad(30.0)])
    target = room_scan()
    source = se2.transform_points(se2.inverse(truth), target)
    res = correlative_search(source, CorrelativeGrid(target, CFG), np.array([0.1, -0.05, np.deg2rad(10.0)]))
    np.testing.assert_allclose(res.target_T_source, truth, atol=1e-9)


def test_multiresolution_equals_exhaustive():
    """The coarse level only prunes: same pose and score as one exhaustive level, with fewer
    candidates scored (here: a noisy source off the grid, so the optimum is not a perfect 1)."""
    rng = np.random.default_rng(3)
    truth = np.array([0.123, -0.171, np.deg2rad(-17.3)])
    target = room_scan()
    source = se2.transform_points(se2.inverse(truth), target) + rng.normal(0, 0.01, target.shape)
    fast = correlative_search(source, CorrelativeGrid(target, CFG), np.zeros(3))
    flat_cfg = CorrelativeConfig(**{**CFG.__dict__, "coarse_factor": 1})
    full = correlative_search(source, CorrelativeGrid(target, flat_cfg), np.zeros(3))
    np.testing.assert_allclose(fast.target_T_source, full.target_T_source, atol=1e-12)
    assert fast.score == pytest.approx(full.score, rel=1e-12)
    # 91 headings x 13 x 13 offsets, every one scored at the single level; the coarse level
    # (4 x 4 blocks) scores 91 x 4 x 4 bounds and then only the blocks that could still win
    n_all = 91 * 13 * 13
    assert full.candidates_scored >= n_all and fast.candidates_scored < n_all / 4
    # within a cell and a heading step of the truth
    assert np.all(np.abs(fast.target_T_source[:2] - truth[:2]) <= 0.05)
    assert abs(fast.target_T_source[2] - truth[2]) <= np.deg2rad(1.0)


def test_initial_guess_for_icp_after_a_fast_turn():
    """A 40 deg turn with a 0.2 m shift: ICP (0.3 m correspondence gate) from the identity
    converges to a pose 0.6 off; from the correlative result it recovers the truth to 1e-6."""
    truth = np.array([0.2, -0.1, np.deg2rad(40.0)])
    target = room_scan()
    source = se2.transform_points(se2.inverse(truth), target)
    cfg = IcpConfig(max_correspondence_m=0.3)
    assert np.abs(icp(source, target, np.zeros(3), cfg).target_T_source - truth).max() > 0.5
    start = correlative_search(source, CorrelativeGrid(target, CFG), np.zeros(3)).target_T_source
    np.testing.assert_allclose(icp(source, target, start, cfg).target_T_source, truth, atol=1e-6)


def test_config_is_checked():
    with pytest.raises(ConfigError):
        CorrelativeConfig(coarse_factor=0)
    with pytest.raises(ConfigError):
        CorrelativeConfig(resolution_m=0.0)
    # the window is searched cell by cell: 200 cells each side at most (10 m at 5 cm)
    assert CorrelativeConfig(window_xy_m=10.0, resolution_m=0.05).window_xy_m == 10.0
    with pytest.raises(ConfigError, match="more than 200 cells of 0.05 m"):
        CorrelativeConfig(window_xy_m=10.1, resolution_m=0.05)
    with pytest.raises(ConfigError, match="grid"):
        correlative_search(room_scan(), CorrelativeGrid(room_scan(), CFG), np.zeros(3),
                           CorrelativeConfig(resolution_m=0.1))


def test_malformed_point_sets_are_data_errors_naming_the_matcher_and_side() -> None:
    from slamkit.errors import DataError

    grid = CorrelativeGrid(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]))
    with pytest.raises(DataError, match=r"correlative source points must have shape \(N, 2\), got \(4, 3\)"):
        correlative_search(np.zeros((4, 3)), grid, np.zeros(3))
    with pytest.raises(DataError, match="correlative source has no finite points"):
        correlative_search(np.full((4, 2), np.nan), grid, np.zeros(3))
    with pytest.raises(DataError, match="correlative target has no finite points"):
        CorrelativeGrid(np.full((2, 2), np.inf))
