"""Blueprint views that fit the data (slamkit.viz.views): worked examples."""

from __future__ import annotations

import numpy as np

from slamkit.viz.views import FILL, LEGEND_HEADROOM, VIEW_FOV_Y_RAD, labels_fit, scene_bounds, series_view, top_down_view


def test_the_top_down_eye_looks_straight_down_at_the_centre_from_the_height_that_shows_the_extent() -> None:
    view = top_down_view("world", "w", [-2.0, 0.0], [18.0, 10.0])
    eye = view.properties["EyeControls3D"]
    position = eye.position.as_arrow_array().to_numpy(zero_copy_only=False)[0]
    target = eye.look_target.as_arrow_array().to_numpy(zero_copy_only=False)[0]
    # centre (8, 5); extent 20 m fills FILL of the view: height = 10 / FILL / tan(fov / 2)
    np.testing.assert_allclose(position, [8.0, 5.0, 10.0 / FILL / np.tan(0.5 * VIEW_FOV_Y_RAD)])
    np.testing.assert_allclose(target, [8.0, 5.0, 0.0])
    assert 20.0 < position[2] < 25.0  # 22.8 m for a 20 m scene


def test_the_series_axis_leaves_headroom_for_the_legend() -> None:
    view = series_view("plots", "error", y_max=2.0)
    axis = view.properties["ScalarAxis"].range.as_arrow_array().to_numpy(zero_copy_only=False)[0]
    np.testing.assert_allclose(axis, [0.0, 2.0 * LEGEND_HEADROOM])
    assert "ScalarAxis" not in series_view("plots", "error", y_max=None).properties


def test_labels_are_shown_only_where_they_cannot_overlap() -> None:
    assert labels_fit([[0, 0], [5, 0], [0, 5]])            # 3 points 5 m apart in a 5 m scene
    assert not labels_fit([[0, 0], [0.1, 0], [10, 10]])    # two 0.1 m apart in a 10 m scene
    assert not labels_fit(np.random.default_rng(0).uniform(0, 100, (41, 2)))  # more than 40
    assert labels_fit([[1.0, 2.0]])


def test_scene_bounds_skip_empty_and_non_finite_parts() -> None:
    lo, hi = scene_bounds(np.array([[0.0, 1.0], [np.nan, 5.0]]), None, np.zeros((0, 2)), np.array([[3.0, -2.0, 0.5]]))
    np.testing.assert_allclose(lo, [0.0, -2.0])
    np.testing.assert_allclose(hi, [3.0, 1.0])
