"""The compiled ray-casting walk (``_raycast.c``) and the numpy fallback: both give the per-beam
loop's ranges bit for bit on random grids, poses and the edge cases of the walk (beams along
cell boundaries, origins on cell corners and outside the grid, the maximum range exactly at a
cell boundary), and the caster says which walk ran."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.maps.raycast import RayCaster, cast_ray_loop, native_raycast

PATHS = ["native", "numpy"]


@pytest.fixture(params=PATHS)
def path(request, monkeypatch) -> str:
    if request.param == "numpy":
        monkeypatch.setenv("SLAMKIT_NO_NATIVE", "1")
    else:
        _require_native(monkeypatch)
    return request.param


def _require_native(monkeypatch) -> None:
    # the native cases run even when the suite runs with SLAMKIT_NO_NATIVE=1, so that every
    # run compares both walks; only a missing compiler skips them
    monkeypatch.delenv("SLAMKIT_NO_NATIVE", raising=False)
    if native_raycast() is None:
        pytest.skip("compiled walk unavailable here (no C compiler, or its build failed)")


def _loop(grid, origins, angles, max_range, no_hit=np.nan):
    return np.array([cast_ray_loop(grid, origins[i], angles[i], max_range, no_hit)
                     for i in range(len(origins))])


def _cast(grid, origins, angles, max_range, path, no_hit=np.nan, chunk=3):
    caster = RayCaster(grid, chunk=chunk)
    out = caster.cast(origins, angles, max_range, no_hit=no_hit)
    assert caster.last_path == path
    return out


def _room(res=0.5):
    """6 x 5 cells of ``res``, one-cell walls, grid origin at world (0, 0)."""
    occ = np.zeros((5, 6), bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    return OccupancyGrid(occ, res)


def test_worked_example_and_max_range_exactly_at_the_wall(path):
    grid = _room()
    # From (1.25, 1.25) along +x the right wall (column 5) starts at x = 2.5: range 1.25, exact
    # in binary. A maximum range of exactly 1.25 still hits (entry time <= max range); one ulp
    # less does not.
    origin = np.array([[1.25, 1.25]])
    assert _cast(grid, origin, np.array([0.0]), 1.25, path)[0] == 1.25
    assert np.isnan(_cast(grid, origin, np.array([0.0]), math.nextafter(1.25, 0.0), path)[0])
    assert _cast(grid, origin, np.array([0.0]), 1.0, path, no_hit=-1.0)[0] == -1.0
    # along -x: the left wall's inner face x = 0.5, range 0.75; inside a wall: 0
    assert _cast(grid, origin, np.array([np.pi]), 5.0, path)[0] == 0.75
    assert _cast(grid, np.array([[0.1, 1.3]]), np.array([0.7]), 5.0, path)[0] == 0.0
    # negative maximum range: only a start inside an obstacle counts
    assert np.isnan(_cast(grid, origin, np.array([0.0]), -1.0, path)[0])
    assert _cast(grid, np.array([[0.1, 1.3]]), np.array([0.7]), -1.0, path)[0] == 0.0


def test_origin_on_a_cell_corner_steps_x_first(path):
    # Occupied cells (ix=2, iy=1) and (ix=1, iy=2) touch the free cell (1, 1) only at the corner
    # (2, 2) (res 1), so which of them a diagonal beam through that corner enters depends on the
    # order of two nearly equal crossing times; both walks must follow the loop's rule.
    occ = np.zeros((4, 4), bool)
    occ[1, 2] = occ[2, 1] = True
    grid = OccupancyGrid(occ, 1.0)
    origins = np.array([[1.5, 1.5], [1.0, 1.0], [2.0, 2.0], [1.0, 3.0]])
    angles = np.array([np.pi / 4, np.pi / 4, -3 * np.pi / 4, -np.pi / 4])
    got = _cast(grid, origins, angles, 10.0, path)
    np.testing.assert_array_equal(got, _loop(grid, origins, angles, 10.0))
    # from the corner (1, 1) at 45 degrees: np.cos(pi/4) rounds one ulp above np.sin(pi/4), so
    # the x crossing (t = 1 / cos) comes first, into occupied (2, 1)
    assert got[1] == 1.0 / np.cos(np.pi / 4)


def test_outside_the_grid_entering_and_leaving(path):
    grid = _room(res=0.25)
    origins = np.array([[-3.0, 0.6], [-3.0, 0.6], [5.0, -2.0], [0.75, 20.0], [0.75, 20.0]])
    angles = np.array([0.0, np.pi, np.pi / 2 + 0.3, -np.pi / 2, np.pi / 2])
    got = _cast(grid, origins, angles, 100.0, path)
    np.testing.assert_array_equal(got, _loop(grid, origins, angles, 100.0))
    # from x = -3 towards +x the left wall (world x in [0, 0.25)) is entered after 3 m;
    # moving away from the grid never hits; from y = 20 down the top wall starts at y = 1.25
    assert got[0] == 3.0 and np.isnan(got[1]) and np.isnan(got[4])
    assert got[3] == 18.75
    # a Fortran-ordered origins array (memory layout must not matter)
    f_origins = np.asfortranarray(origins)
    np.testing.assert_array_equal(_cast(grid, f_origins, angles, 100.0, path), got)


def _edge_case_rays(grid, rng, n):
    """Origins on grid lines and corners, in and around the grid; axis-aligned, diagonal and
    random beams."""
    h, w = grid.shape
    res = grid.resolution_m
    cells = rng.integers(-3, [w + 4, h + 4], size=(n, 2)).astype(float)
    kind = rng.integers(0, 3, n)
    frac = rng.random((n, 2))
    cells += np.where(kind[:, None] == 0, 0.0,                       # a corner
                      np.where(kind[:, None] == 1, np.array([0.0, 0.5]), frac))  # an edge / anywhere
    origins = grid.origin_xy_m + cells * res
    angles = np.where(rng.random(n) < 0.6, rng.integers(-4, 4, n) * (np.pi / 4),
                      rng.uniform(-np.pi, np.pi, n))
    return origins, angles


@pytest.mark.parametrize("seed", range(6))
def test_random_grids_match_the_per_beam_loop_bit_for_bit(path, seed):
    rng = np.random.default_rng(seed)
    h, w = rng.integers(1, 25, 2)
    occ = rng.random((h, w)) < rng.choice([0.0, 0.05, 0.3, 0.7])
    res = float(rng.choice([0.05, 0.1, 0.25, 1.0]))
    grid = OccupancyGrid(occ, res, rng.uniform(-3, 3, 2))
    origins, angles = _edge_case_rays(grid, rng, 150)
    # maximum ranges: random, and exactly a whole number of cells (a crossing time in
    # axis-aligned beams from a grid line)
    for max_range in (float(rng.uniform(0, 2 * (h + w) * res)), 3 * res, 0.0):
        got = _cast(grid, origins, angles, max_range, path)
        np.testing.assert_array_equal(got, _loop(grid, origins, angles, max_range))


def test_both_walks_agree_on_a_cluttered_grid(monkeypatch):
    _require_native(monkeypatch)
    rng = np.random.default_rng(11)
    occ = rng.random((300, 200)) < 0.01
    grid = OccupancyGrid(occ, 0.05, np.array([-2.0, 1.0]))
    origins = grid.origin_xy_m + rng.uniform(-1, [11, 16], size=(5000, 2))
    angles = rng.uniform(-np.pi, np.pi, 5000)
    caster = RayCaster(grid)
    native = caster.cast(origins, angles, 8.0)
    assert caster.last_path == "native"
    monkeypatch.setenv("SLAMKIT_NO_NATIVE", "1")
    fallback = caster.cast(origins, angles, 8.0)
    assert caster.last_path == "numpy"
    np.testing.assert_array_equal(native, fallback)
    hits = np.isfinite(native)
    assert 0.3 < hits.mean() < 1.0  # the case exercises both hits and misses
    # the native result is an ordinary writable float64 array, like the numpy path's
    assert native.dtype == np.float64 and native.flags.writeable


def test_origin_too_far_away_for_exact_cell_indices_uses_the_numpy_walk(path):
    grid = _room(res=1.0)
    origins = np.array([[2.0**53, 1.5], [1.5, 1.5]])
    angles = np.array([np.pi, 0.0])
    caster = RayCaster(grid)
    got = caster.cast(origins, angles, 4.0)
    assert caster.last_path == "numpy"
    np.testing.assert_array_equal(got, [np.nan, 3.5])
