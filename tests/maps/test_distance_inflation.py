"""Distance field, inflation and costmap: worked examples and a brute-force property test."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from slamkit.errors import DataError
from slamkit.maps.distance_field import (bilinear, distance_at, distance_field_m, signed_distance_field_m,
                                        surface_distance_field_m)
from slamkit.maps.inflation import INSCRIBED_COST, LETHAL_COST, costmap, inflate
from slamkit.maps.occupancy_grid import OccupancyGrid


def _single_obstacle(res=0.5):
    occ = np.zeros((5, 7), bool)
    occ[2, 3] = True  # iy=2, ix=3
    return OccupancyGrid(occ, res, np.array([1.0, -2.0]))


def test_distance_field_worked_example():
    d = distance_field_m(_single_obstacle(res=0.5))
    assert d[2, 3] == 0.0
    assert d[2, 4] == pytest.approx(0.5)            # one cell to the right
    assert d[3, 4] == pytest.approx(0.5 * np.sqrt(2))
    assert d[0, 0] == pytest.approx(0.5 * np.hypot(3, 2))
    assert d[4, 6] == pytest.approx(0.5 * np.hypot(3, 2))


def test_distance_field_empty_grid_is_infinite_and_signed_field_is_negative_inside():
    grid = OccupancyGrid(np.zeros((3, 3), bool))
    assert np.all(np.isinf(distance_field_m(grid)))
    occ = np.zeros((5, 5), bool)
    occ[1:4, 1:4] = True
    sdf = signed_distance_field_m(OccupancyGrid(occ, 0.1))
    assert sdf[2, 2] == pytest.approx(-0.2)  # centre of the 3x3 block: two cells to free space
    assert sdf[0, 0] == pytest.approx(0.1 * np.sqrt(2))


def test_surface_distance_field_worked_example():
    # a 3-cell wall (x in [0.2, 0.5)) in a row of 7 cells of 0.1 m
    occ = np.zeros((1, 7), bool)
    occ[0, 2:5] = True
    grid = OccupancyGrid(occ, 0.1)
    np.testing.assert_allclose(surface_distance_field_m(grid)[0], [0.15, 0.05, 0, 0, 0, 0.05, 0.15])
    signed = surface_distance_field_m(grid, signed=True)
    np.testing.assert_allclose(signed[0], [0.15, 0.05, -0.05, -0.15, -0.05, 0.05, 0.15])
    # bilinear between the centres: exact on the faces (x = 0.2 and 0.5) and 2 cm either side;
    # the clipped field reads a quarter cell on the face and 0 wherever behind it
    x = np.array([0.18, 0.2, 0.22, 0.48, 0.5, 0.52])
    xy = np.column_stack([x, np.full(6, 0.05)])
    np.testing.assert_allclose(bilinear(signed, 0.1, grid.origin_xy_m, xy)[0], [0.02, 0, -0.02, -0.02, 0, 0.02],
                               atol=1e-12)
    np.testing.assert_allclose(bilinear(surface_distance_field_m(grid), 0.1, grid.origin_xy_m, xy)[0],
                               [0.035, 0.025, 0.015, 0.015, 0.025, 0.035], atol=1e-12)
    # no obstacle: infinite either way; all occupied: -inf inside
    assert np.all(np.isinf(surface_distance_field_m(OccupancyGrid(np.zeros((2, 2), bool)), signed=True)))
    assert np.all(surface_distance_field_m(OccupancyGrid(np.ones((2, 2), bool)), signed=True) == -np.inf)


@settings(max_examples=40, deadline=None)
@given(arrays(bool, st.tuples(st.integers(1, 9), st.integers(1, 9))), st.floats(0.05, 2.0))
def test_distance_field_matches_brute_force(occ, res):
    grid = OccupancyGrid(occ, res)
    d = distance_field_m(grid)
    iy, ix = np.nonzero(occ)
    if len(iy) == 0:
        assert np.all(np.isinf(d))
        return
    yy, xx = np.mgrid[0:occ.shape[0], 0:occ.shape[1]]
    brute = np.min(np.hypot(xx[..., None] - ix, yy[..., None] - iy), axis=-1) * res
    np.testing.assert_allclose(d, brute, atol=1e-9)


def test_distance_at_looks_up_world_points_and_outside_is_zero():
    grid = _single_obstacle(res=0.5)
    d = distance_field_m(grid)
    # origin (1, -2): cell (ix=5, iy=2) has centre (1 + 2.75, -2 + 1.25)
    got = distance_at(grid, d, np.array([[3.75, -0.75], [100.0, 0.0]]))
    np.testing.assert_allclose(got, [1.0, 0.0])


def test_inflate_radius_counts_cells_within_radius():
    grid = _single_obstacle(res=0.5)
    assert np.array_equal(inflate(grid, 0.0).occupied, grid.occupied)
    # radius 0.5 m = one cell: the 4-neighbourhood plus the centre
    assert inflate(grid, 0.5).occupied.sum() == 5
    # radius 0.75 m covers diagonals (0.707 m) too: 3x3 block
    infl = inflate(grid, 0.75)
    assert infl.occupied.sum() == 9 and infl.occupied[1:4, 2:5].all()
    assert infl.resolution_m == 0.5 and np.allclose(infl.origin_xy_m, [1.0, -2.0])
    with pytest.raises(DataError):
        inflate(grid, -1.0)


def test_costmap_nav2_values():
    grid = _single_obstacle(res=0.5)
    c = costmap(grid, inscribed_radius_m=0.5, inflation_radius_m=1.5, cost_scaling=2.0)
    assert c[2, 3] == LETHAL_COST
    assert c[2, 4] == INSCRIBED_COST                  # d = 0.5 = inscribed radius
    assert c[3, 4] == pytest.approx(252 * np.exp(-2.0 * (np.sqrt(0.5) - 0.5)))  # d = 0.707
    assert c[2, 5] == pytest.approx(252 * np.exp(-2.0 * 0.5))                   # d = 1.0
    assert c[2, 6] == pytest.approx(252 * np.exp(-2.0 * 1.0))                   # d = 1.5, edge
    assert c[0, 0] == 0.0                                                       # d = 1.80 > 1.5
    # cost never increases with distance
    d = distance_field_m(grid)
    order = np.argsort(d, axis=None)
    assert np.all(np.diff(c.ravel()[order]) <= 1e-12)
    with pytest.raises(DataError):
        costmap(grid, 1.0, 0.5)
