"""Planar odometry preintegration: the summed increment and its covariance against the exact
arc and against a numerical Jacobian of the whole chain."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.geometry import se2
from slamkit.models.planar_preintegration import PlanarPreintegration, chord_increment


def test_constant_increments_follow_the_exact_arc() -> None:
    pre = PlanarPreintegration()
    for _ in range(50):
        pre.integrate(0.02, 0.01, 0.0, 0.0, 0.002)
    # 1 m of arc turning 0.5 rad: radius 2 m
    assert pre.delta == pytest.approx([2 * np.sin(0.5), 2 * (1 - np.cos(0.5)), 0.5], abs=1e-12)
    assert pre.duration_s == pytest.approx(0.1)


def test_covariance_is_the_linearised_chain() -> None:
    rng = np.random.default_rng(3)
    steps = np.column_stack([rng.uniform(0.0, 0.05, 20), rng.uniform(-0.05, 0.05, 20)])
    var = np.column_stack([rng.uniform(1e-6, 1e-4, 20), rng.uniform(1e-6, 1e-4, 20)])
    pre = PlanarPreintegration()
    for (d, th), (vd, vt) in zip(steps, var):
        pre.integrate(d, th, vd, vt)

    def chain(flat: np.ndarray) -> np.ndarray:
        T = np.zeros(3)
        for d, th in flat.reshape(-1, 2):
            T = se2.compose(T, chord_increment(d, th)[0])
        return T

    x0 = steps.ravel()
    J = np.zeros((3, len(x0)))
    for k in range(len(x0)):
        e = np.zeros(len(x0))
        e[k] = 1e-7
        # the right perturbation: log(Delta^-1 Delta(x + e))
        J[:, k] = (se2.log(se2.between(chain(x0 - e), chain(x0 + e)))) / 2e-7
    expected = J @ np.diag(var.ravel()) @ J.T
    assert pre.covariance == pytest.approx(expected, rel=1e-5, abs=1e-12)
