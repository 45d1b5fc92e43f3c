"""Unscented transform: exact for linear maps, and angle-aware near +-pi (filterpy #197)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import ConfigError
from slamkit.estimation.ukf import SigmaPointParams, sigma_points, unscented_transform


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.1, 1.0), st.floats(0.0, 3.0))
def test_linear_map_is_exact(seed, alpha, beta):
    rng = np.random.default_rng(seed)
    n = 4
    A = rng.standard_normal((3, n))
    b = rng.standard_normal(3)
    x = rng.standard_normal(n)
    L = rng.standard_normal((n, n))
    P = L @ L.T + 0.1 * np.eye(n)
    params = SigmaPointParams(alpha=alpha, beta=beta, kappa=3.0 - n + 1.0)
    X, Wm, Wc = sigma_points(x, P, params)
    mean, cov = unscented_transform(X @ A.T + b, Wm, Wc)
    np.testing.assert_allclose(mean, A @ x + b, atol=1e-9)
    # covariance exact up to the beta term, which only matters for nonlinear maps: the weights
    # Wc differ from Wm only at the centre point, whose deviation from the mean is zero here
    np.testing.assert_allclose(cov, A @ P @ A.T, atol=1e-8)


def test_weights_sum_to_one():
    Wm, Wc, c = SigmaPointParams(alpha=0.3, beta=2.0, kappa=0.0).weights(3)
    assert Wm.sum() == pytest.approx(1.0)
    assert c == pytest.approx(0.09 * 3)


def test_bad_scaling_is_a_config_error():
    with pytest.raises(ConfigError):
        SigmaPointParams(alpha=1.0, kappa=-5.0).weights(3)


def test_heading_mean_near_pi_is_circular():
    """Headings straddling +-pi: the arithmetic mean would be ~0 (the filterpy #197 pitfall)."""
    x = np.array([0.0, 0.0, np.pi - 0.01])
    P = np.diag([0.1, 0.1, 0.05**2])
    mask = np.array([False, False, True])
    X, Wm, Wc = sigma_points(x, P, SigmaPointParams(), mask)
    assert np.any(X[:, 2] < 0)  # some points wrapped to about -pi
    mean, cov = unscented_transform(X, Wm, Wc, mask)
    assert abs(np.angle(np.exp(1j * (mean[2] - x[2])))) < 1e-9
    assert cov[2, 2] == pytest.approx(0.05**2, rel=1e-6)
    naive = Wm @ X[:, 2]
    assert abs(naive - x[2]) > 0.5  # an angle-unaware mean is off by about a radian
