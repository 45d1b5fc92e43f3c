"""The navigation benchmark's per-episode metrics on hand-computable inputs."""

import math

import numpy as np
import pytest

from slamkit.errors import DataError
from slamkit.metrics.navigation import (bin_label, clearance_percentile_m, narrowest_passage_m, optimal_time_s,
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
