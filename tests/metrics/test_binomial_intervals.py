"""Binomial intervals of a rate against published values and scipy's own implementation."""

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.stats import binomtest

from slamkit.errors import DataError
from slamkit.metrics.stats import clopper_pearson_interval, rate_interval, rate_of, wilson_interval

# Newcombe, "Two-sided confidence intervals for the single proportion: comparison of seven
# methods", Stat. Med. 17 (1998) 857-872, Table I: (events, trials) -> method 3 (Wilson score,
# no continuity correction) and method 5 (exact, Clopper-Pearson), 95%, to 4 decimals
NEWCOMBE = [
    ((81, 263), (0.2553, 0.3662), (0.2527, 0.3676)),
    ((15, 148), (0.0624, 0.1605), (0.0578, 0.1617)),
    ((0, 20), (0.0, 0.1611), (0.0, 0.1684)),
    ((1, 29), (0.0061, 0.1718), (0.0009, 0.1776)),
]


@pytest.mark.parametrize("counts, wilson, exact", NEWCOMBE)
def test_published_values(counts, wilson, exact):
    assert wilson_interval(*counts) == pytest.approx(wilson, abs=5e-5)
    assert clopper_pearson_interval(*counts) == pytest.approx(exact, abs=5e-5)


def test_hand_computed_wilson_29_of_30():
    # p = 29/30, z = 1.959964: centre (p + z^2/60) / (1 + z^2/30) = 0.913694, half-width
    # z / (1 + z^2/30) * sqrt(p (1 - p) / 30 + z^2 / 3600) = 0.080398
    lo, hi = wilson_interval(29, 30)
    assert lo == pytest.approx(0.913694 - 0.080398, abs=2e-6)
    assert hi == pytest.approx(0.913694 + 0.080398, abs=2e-6)


def test_all_or_nothing_bounds_are_exact():
    # 0 of n: the exact upper bound solves (1 - p)^n = alpha / 2; n of n mirrors it
    assert clopper_pearson_interval(0, 30) == (0.0, pytest.approx(1 - 0.025 ** (1 / 30), rel=1e-12))
    assert clopper_pearson_interval(30, 30) == (pytest.approx(0.025 ** (1 / 30), rel=1e-12), 1.0)
    # Wilson at 0 of n: upper bound z^2 / (n + z^2)
    z2 = 1.959963984540054 ** 2
    assert wilson_interval(0, 30) == (0.0, pytest.approx(z2 / (30 + z2), rel=1e-12))
    assert wilson_interval(30, 30)[1] == 1.0


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 400).flatmap(lambda n: st.tuples(st.integers(0, n), st.just(n))),
       st.sampled_from([0.8, 0.9, 0.95, 0.99]))
def test_agrees_with_scipy_and_nests(counts, confidence):
    k, n = counts
    ref = binomtest(k, n)
    w = wilson_interval(k, n, confidence)
    e = clopper_pearson_interval(k, n, confidence)
    assert w == pytest.approx(tuple(ref.proportion_ci(confidence, "wilson")), abs=1e-9)
    assert e == pytest.approx(tuple(ref.proportion_ci(confidence, "exact")), abs=1e-9)
    for lo, hi in (w, e):
        assert 0.0 <= lo <= k / n <= hi <= 1.0


def test_rate_of_flags_drops_nan_and_formats():
    r = rate_of([1, 1, 0, float("nan"), 1])
    assert (r.events, r.trials, r.rate) == (3, 4, 0.75)
    assert (r.low, r.high) == pytest.approx(wilson_interval(3, 4))
    assert r.text() == f"0.750 [{r.low:.3f}, {r.high:.3f}] (3/4)"
    empty = rate_interval(0, 0)
    assert math.isnan(empty.rate) and (empty.low, empty.high) == (0.0, 1.0)


@pytest.mark.parametrize("bad", [(3, 2), (-1, 2), (1.5, 3), (True, 3)])
def test_bad_counts_are_data_errors(bad):
    with pytest.raises(DataError):
        wilson_interval(*bad)


def test_bad_method_and_flags():
    with pytest.raises(DataError, match="unknown interval method"):
        rate_interval(1, 2, method="wald")
    with pytest.raises(DataError, match="0/1"):
        rate_of(np.array([0.0, 0.5]))
