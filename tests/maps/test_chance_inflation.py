"""Covariance-aware inflation (chance constraint) as worked examples."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.control.chance_constraints import tightened_distance, tightened_world
from slamkit.control.protocols import DistanceGrid, LocalWorld
from slamkit.errors import DataError
from slamkit.maps.inflation import chance_inflation_m, chance_sigma_multiplier


def test_k_from_the_collision_probability():
    assert chance_sigma_multiplier(0.05) == pytest.approx(1.644854, abs=1e-6)
    assert chance_sigma_multiplier(0.01) == pytest.approx(2.326348, abs=1e-6)
    for bad in (0.0, 0.5, 1.2):
        with pytest.raises(DataError):
            chance_sigma_multiplier(bad)


def test_inflation_grows_with_the_covariance_along_the_obstacle_direction():
    # sigma_x = 4 cm, sigma_y = 1 cm, delta = 5 %: robot 0.2 m
    cov = np.diag([0.04**2, 0.01**2])
    # obstacle along x: 0.2 + 1.645 * 0.04 = 0.26579 m; along y: 0.2 + 1.645 * 0.01 = 0.21645 m
    assert chance_inflation_m(0.2, cov, 0.05, [1.0, 0.0]) == pytest.approx(0.265794, abs=1e-6)
    assert chance_inflation_m(0.2, cov, 0.05, [0.0, 2.0]) == pytest.approx(0.216449, abs=1e-6)
    # at 45 degrees: sigma_n^2 = (0.04^2 + 0.01^2) / 2 -> sigma_n = 0.029155
    assert chance_inflation_m(0.2, cov, 0.05, [1.0, 1.0]) == pytest.approx(0.2 + 1.644854 * 0.0291548, abs=1e-6)
    # no direction: the worst one (largest eigenvalue)
    assert chance_inflation_m(0.2, cov, 0.05) == pytest.approx(0.265794, abs=1e-6)
    # a known pose needs no more than the radius
    assert chance_inflation_m(0.2, np.zeros((2, 2)), 0.05) == pytest.approx(0.2)


def test_tightened_world_grows_circles_and_shrinks_the_static_field():
    cov = np.diag([0.04**2, 0.01**2])
    field = DistanceGrid(np.full((4, 4), 1.0), 0.5)
    world = LocalWorld([[3.0, 0.0], [0.0, 3.0]], [0.3, 0.3], [[0.0, 0.0], [0.0, 0.0]], field)
    tight = tightened_world(world, [0.0, 0.0], cov, 0.05,
                            circle_cov_xy=np.array([np.zeros((2, 2)), np.diag([0.0, 0.03**2])]))
    # circle 1 along x: + 1.645 * 0.04; circle 2 along y: + 1.645 * sqrt(0.01^2 + 0.03^2)
    np.testing.assert_allclose(tight.circle_radius_m, [0.3 + 1.644854 * 0.04, 0.3 + 1.644854 * np.sqrt(0.001)],
                               atol=1e-6)
    np.testing.assert_allclose(tight.distance.distance_m, 1.0 - 1.644854 * 0.04, atol=1e-6)
    np.testing.assert_allclose(tightened_distance(field, np.diag([1.0, 1.0]), 0.05).distance_m, 0.0)


def test_a_given_k_and_circles_measured_from_the_robot():
    cov = np.diag([0.04**2, 0.01**2])
    field = DistanceGrid(np.full((4, 4), 1.0), 0.5)
    world = LocalWorld([[3.0, 0.0]], [0.3], [[0.0, 0.0]], field)
    # k = 0.5 instead of delta's 1.645: circle + 0.5 * 4 cm, field - 0.5 * 4 cm
    tight = tightened_world(world, [0.0, 0.0], cov, k_sigma=0.5)
    np.testing.assert_allclose(tight.circle_radius_m, [0.32], atol=1e-12)
    np.testing.assert_allclose(tight.distance.distance_m, 0.98, atol=1e-12)
    # a lidar track moves with the pose error: only its own 3 cm along x count
    rel = tightened_world(world, [0.0, 0.0], cov, 0.05, circle_cov_xy=np.diag([0.03**2, 0.0])[None],
                          relative_circles=True)
    np.testing.assert_allclose(rel.circle_radius_m, [0.3 + 1.644854 * 0.03], atol=1e-6)
    np.testing.assert_allclose(rel.distance.distance_m, 1.0 - 1.644854 * 0.04, atol=1e-6)
