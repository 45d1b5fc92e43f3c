"""Path helpers and the distance-grid lookup the controllers share: worked examples and properties."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.control.path_following import (crop, lookahead_point, path_reference, point_at,
                                            project_many, project_on_path)
from slamkit.control.protocols import DistanceGrid, LocalWorld

L_PATH = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]])  # 7 m long, corner at s = 4


def test_projection_and_lookahead_worked_example():
    assert project_on_path(L_PATH, np.array([2.0, 1.0])) == pytest.approx(2.0)
    assert project_on_path(L_PATH, np.array([5.0, 2.0])) == pytest.approx(6.0)
    np.testing.assert_allclose(lookahead_point(L_PATH, np.array([3.0, -0.5]), 2.0), [4.0, 1.0])
    np.testing.assert_allclose(point_at(L_PATH, np.array([-1.0, 9.0])), [[0.0, 0.0], [4.0, 3.0]])


def test_path_reference_headings_follow_the_tangent_and_unwrap():
    """From (0, 0) facing 2 pi + 0.1, spacing 1 m: points at s = 1..6, headings 0 then pi/2, unwrapped
    to lie near the robot's 2 pi + 0.1 (so 2 pi and 2 pi + pi/2)."""
    ref = path_reference(L_PATH, np.zeros(2), 1.0, 6, 2 * np.pi + 0.1)
    np.testing.assert_allclose(ref[:, :2], [[1, 0], [2, 0], [3, 0], [4, 0], [4, 1], [4, 2]], atol=1e-12)
    np.testing.assert_allclose(ref[[0, 1, 2, 4, 5], 2], 2 * np.pi + np.array([0, 0, 0, np.pi / 2, np.pi / 2]),
                               atol=1e-9)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), min_size=1, max_size=8))
def test_project_many_equals_pointwise_projection(points):
    pts = np.array(points)
    batch = project_many(L_PATH, pts)
    single = np.array([project_on_path(L_PATH, p) for p in pts])
    np.testing.assert_allclose(batch, single, atol=1e-9)


def test_crop_keeps_the_span():
    path = np.column_stack([np.arange(11.0), np.zeros(11)])  # s = x
    sub = crop(path, 2.5, 5.5)
    np.testing.assert_array_equal(sub[:, 0], [2, 3, 4, 5, 6])


def test_distance_grid_bilinear_and_outside():
    """d(x, y) = x sampled at cell centres (res 0.5, origin 0): bilinear interpolation is exact for a
    linear field, gradient (1, 0); outside the grid the distance is 0 (unknown = occupied)."""
    xs = (np.arange(8) + 0.5) * 0.5
    grid = DistanceGrid(np.tile(xs, (6, 1)), 0.5)
    d, g = grid.query(np.array([[1.3, 1.1], [2.6, 2.2]]))
    np.testing.assert_allclose(d, [1.3, 2.6])
    np.testing.assert_allclose(g, [[1.0, 0.0], [1.0, 0.0]])
    d_out, _ = grid.query(np.array([[-1.0, 1.0]]))
    assert d_out[0] == 0.0
    world = LocalWorld(circle_xy_m=[[3.0, 1.5]], circle_radius_m=[0.5], distance=grid)
    # nearest: the circle surface (0.5 m away) beats the field value at x = 2 (2 m)
    assert world.clearance_m(np.array([2.0, 1.5]))[0] == pytest.approx(0.5)
