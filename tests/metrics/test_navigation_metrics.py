"""The navigation benchmark's per-episode metrics on hand-computable inputs."""

import math

import numpy as np
import pytest

from slamkit.errors import DataError
from slamkit.metrics.navigation import (bin_label, clearance_percentile_m, narrowest_passage_m, optimal_time_s,
                                        path_velocity_arrival_s,
                                        outcome, polyline_length_m, ratio_to_optimal)


@pytest.mark.parametrize("flags, expected", [
    ((True, False, False, True), "success"),
    ((False, True, False, False), "collision_static"),
    ((False, True, True, False), "collision_static"),   # a wall and a disc at once: the wall
    ((False, False, True, True), "collision_moving"),
    ((False, False, False, False), "timeout"),
    ((False, False, False, True), "off_goal"),           # believed it arrived, outside the tolerance
])
def test_outcome(flags, expected):
    assert outcome(*flags) == expected


def test_clearance_percentile_is_numpy_linear_over_finite_samples():
    # 0, 0.1, ..., 2.0 (21 samples): the 5th percentile sits at index 0.05 * 20 = 1 -> 0.1 m
    series = np.linspace(0.0, 2.0, 21)
    assert clearance_percentile_m(series) == pytest.approx(0.1)
    # +inf (no moving obstacle at that time) is not a sample; p50 of 1, 2, 3 is 2
    assert clearance_percentile_m([1.0, np.inf, 3.0, 2.0], q=50) == pytest.approx(2.0)
    assert math.isnan(clearance_percentile_m([np.inf, np.inf]))
    with pytest.raises(DataError):
        clearance_percentile_m([1.0], q=101)


def test_ratios_to_optimal():
    # 13 m at a 0.65 m/s cap: 20 s; arriving in 26 s is 1.3 times that
    assert optimal_time_s(13.0, 0.65) == pytest.approx(20.0)
    assert ratio_to_optimal(26.0, 20.0) == pytest.approx(1.3)
    assert math.isnan(ratio_to_optimal(float("nan"), 20.0)) and math.isnan(ratio_to_optimal(5.0, 0.0))
    assert polyline_length_m([[0, 0], [3, 4], [3, 5]]) == pytest.approx(6.0)
    with pytest.raises(DataError):
        optimal_time_s(13.0, 0.0)


def test_narrowest_passage_reads_the_field_along_the_path_without_its_ends():
    res = 0.1
    field = np.full((10, 60), 1.5)          # 6 m x 1 m strip, 1.5 m from walls everywhere ...
    field[5, 30] = 0.4                      # ... but a 0.8 m gap at x = 3.0-3.1 m
    field[5, 0:3] = 0.05                    # the start stands by a wall: not a passage
    path = np.array([[0.05, 0.55], [5.95, 0.55]])
    assert narrowest_passage_m(path, field, (0.0, 0.0), res) == pytest.approx(0.8)
    # a path that avoids the gap's row sees 2 x 1.5 m
    assert narrowest_passage_m(path + [0.0, 0.2], field, (0.0, 0.0), res) == pytest.approx(3.0)
    with pytest.raises(DataError):
        narrowest_passage_m(path + 100.0, field, (0.0, 0.0), res)


def test_bin_labels():
    edges = (1.0, 1.5, 2.0)
    assert [bin_label(v, edges, " m") for v in (0.8, 1.0, 1.49, 2.0, 7.0)] == \
        ["< 1 m", "1-1.5 m", "1-1.5 m", ">= 2 m", ">= 2 m"]
    assert bin_label(float("nan"), edges) == "n/a"
    with pytest.raises(DataError):
        bin_label(1.0, (2.0, 1.0))


def test_path_velocity_arrival_waits_behind_a_crossing_disc():
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    none = lambda t: (np.zeros((0, 2)), np.zeros(0))  # noqa: E731
    # nothing in the way: 10 m at 1 m/s (200 lattice steps of 0.05 m and 0.05 s)
    assert path_velocity_arrival_s(path, none, 0.2, 1.0, 90.0) == pytest.approx(10.0)
    # a 0.3 m disc crossing x = 5 at 1 m/s, on the path at t = 5 s: with clearance 0.2 the robot's
    # (x, t) may not enter the disc of radius 0.5 around (5, 5); at top speed (slope 1) the earliest
    # way passes behind it, on the tangent x = t - 0.5 sqrt(2): arrival 10.707 s (the lattice's
    # waits come in 0.05 s steps: 10.75)
    crossing = lambda t: (np.array([[5.0, t - 5.0]]), np.array([0.3]))  # noqa: E731
    t = path_velocity_arrival_s(path, crossing, 0.2, 1.0, 90.0)
    assert t == pytest.approx(10.75) and t >= 10.0 + 0.5 * np.sqrt(2.0)
    # a disc standing on the path, or on the start: never
    assert path_velocity_arrival_s(path, lambda t: (np.array([[5.0, 0.0]]), np.array([0.3])), 0.2, 1.0, 90.0) == np.inf
    assert path_velocity_arrival_s(path, lambda t: (np.array([[0.0, 0.4]]), np.array([0.3])), 0.2, 1.0, 90.0) == np.inf
    # ... unless the clearance lets it pass beside: 0.35 m off the path, 0.3 m radius, clearance 0.04
    assert path_velocity_arrival_s(path, lambda t: (np.array([[5.0, 0.35]]), np.array([0.3])), 0.04, 1.0, 90.0) \
        == pytest.approx(10.0)
    # a horizon shorter than the way: never
    assert path_velocity_arrival_s(path, none, 0.2, 1.0, 9.0) == np.inf
    with pytest.raises(DataError):
        path_velocity_arrival_s(np.array([[1.0, 1.0], [1.0, 1.0]]), none, 0.2, 1.0, 9.0)
    for bad in (dict(speed_mps=float("nan")), dict(speed_mps=-1.0), dict(horizon_s=float("nan")),
                dict(horizon_s=float("inf")), dict(clearance_m=-0.1), dict(clearance_m=float("nan"))):
        args = {"clearance_m": 0.2, "speed_mps": 1.0, "horizon_s": 9.0, **bad}
        with pytest.raises(DataError, match="path_velocity_arrival_s"):
            path_velocity_arrival_s(path, none, **args)
    with pytest.raises(DataError):
        path_velocity_arrival_s(np.array([[0.0, 0.0], [np.nan, 0.0]]), none, 0.2, 1.0, 9.0)
