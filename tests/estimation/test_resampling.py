"""Resampling schemes: the course's worked example, and properties every scheme must have."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import ConfigError
from slamkit.estimation.particle_filter import (
    RESAMPLERS,
    effective_sample_size,
    normalize_log_weights,
    residual_resample,
    systematic_resample,
)


def test_systematic_worked_example():
    idx = systematic_resample(np.array([0.4, 0.3, 0.2, 0.05, 0.05]), offset=0.09)
    assert (idx + 1).tolist() == [1, 1, 2, 2, 3]  # one-based, as the course states it


def test_systematic_offset_must_lie_in_first_stratum():
    with pytest.raises(ConfigError):
        systematic_resample(np.array([0.5, 0.5]), offset=0.6)


def test_residual_keeps_the_deterministic_copies():
    w = np.array([0.55, 0.25, 0.15, 0.05])
    idx = residual_resample(w, np.random.default_rng(0), n=10)
    counts = np.bincount(idx, minlength=4)
    assert np.all(counts >= np.floor(10 * w))  # floor(N w) = 5, 2, 1, 0 always present
    assert counts.sum() == 10


def test_effective_sample_size_and_log_weights():
    assert effective_sample_size(np.ones(8)) == pytest.approx(8.0)
    assert effective_sample_size(np.array([1.0, 0, 0, 0])) == pytest.approx(1.0)
    lw = normalize_log_weights(np.array([-1000.0, -1001.0, -1002.0]))  # would underflow as exp
    w = np.exp(lw)
    assert w.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(w, np.exp([0, -1, -2]) / np.exp([0, -1, -2]).sum())


@pytest.mark.parametrize("scheme", sorted(RESAMPLERS))
def test_unbiased_counts(scheme):
    """E[count_i] = N w_i: averaged over repetitions the copies match the weights."""
    rng = np.random.default_rng(42)
    w = np.array([0.5, 0.2, 0.15, 0.1, 0.05])
    n, reps = 100, 400
    counts = np.zeros(5)
    for _ in range(reps):
        counts += np.bincount(RESAMPLERS[scheme](w, rng, n), minlength=5)
    np.testing.assert_allclose(counts / (reps * n), w, atol=0.01)


@pytest.mark.parametrize("scheme", ["systematic", "stratified", "residual"])
def test_low_variance_schemes_stay_within_one_of_expectation(scheme):
    rng = np.random.default_rng(7)
    w = rng.dirichlet(np.ones(50))
    for _ in range(20):
        counts = np.bincount(RESAMPLERS[scheme](w, rng, 50), minlength=50)
        if scheme == "systematic":
            assert np.all(np.abs(counts - 50 * w) < 1.0 + 1e-9)
        assert counts.sum() == 50


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40).filter(lambda v: sum(v) > 1e-6),
       st.integers(0, 2**31 - 1))
def test_indices_valid_and_zero_weights_never_drawn(weights, seed):
    w = np.array(weights)
    rng = np.random.default_rng(seed)
    for fn in RESAMPLERS.values():
        idx = fn(w, rng)
        assert len(idx) == len(w)
        assert idx.min() >= 0 and idx.max() < len(w)
        assert np.all(w[idx] > 0)
