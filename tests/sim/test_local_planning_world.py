"""The local-planning world (issue 30: moved out of experiments.closed_loop): seeded maps, the
perfect obstacle sensor and the ground-truth clearance, with worked numbers."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import ConfigError
from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.local_planning_world import SCENARIO_KINDS, clearance_m, open_room, scenario_map, visible_obstacles
from slamkit.sim.moving_obstacles import MovingObstacles


def test_open_room_walls_and_boxes():
    grid = open_room(np.random.default_rng(0))
    occ = grid.occupied
    assert occ.shape == (120, 160) and grid.resolution_m == 0.1
    assert occ[:2, :].all() and occ[-2:, :].all() and occ[:, :2].all() and occ[:, -2:].all()
    inner = occ[12:-12, 12:-12].sum()
    assert 6 * 25 <= inner <= 6 * 144        # six boxes of 5-12 cells a side (they may overlap)
    assert not occ[2:12, 2:-2].any()          # kept 10 cells off the walls


def test_maps_are_seeded_and_kinds_checked():
    for kind in SCENARIO_KINDS:
        a, b = scenario_map(kind, np.random.default_rng(4)), scenario_map(kind, np.random.default_rng(4))
        assert np.array_equal(a.occupied, b.occupied)
    with pytest.raises(ConfigError, match="unknown scenario kind 'forest'"):
        scenario_map("forest", np.random.default_rng(0))


def _two_discs() -> MovingObstacles:
    # at rest (speed 0): centres (3, 0) and (10, 0), radii 0.5 and 1.0
    return MovingObstacles([[3.0, 0.0], [10.0, 0.0]], [[4.0, 0.0], [11.0, 0.0]], [0.0, 0.0], [0.5, 1.0], [0.0, 0.0])


def test_the_sensor_sees_surfaces_within_range():
    xy, radius, velocity = visible_obstacles(_two_discs(), np.array([0.0, 0.0]), 0.0, sensor_range_m=5.0)
    np.testing.assert_allclose(xy, [[3.0, 0.0]])
    np.testing.assert_allclose(radius, [0.5])
    np.testing.assert_allclose(velocity, [[0.0, 0.0]])
    # the second disc's surface is 9 m away: seen from 9 m on
    assert len(visible_obstacles(_two_discs(), np.array([0.0, 0.0]), 0.0, 9.0)[0]) == 2


def test_clearance_worked_example():
    occ = np.zeros((40, 40), dtype=bool)
    occ[:, 0] = True                                   # a wall along x in [0, 0.1)
    grid = OccupancyGrid(occ, 0.1, np.zeros(2))
    field = distance_field_m(grid)
    none = MovingObstacles.empty()
    # robot centre at the centre of cell (20, 10): 1.0 m from the wall cell's centre, minus half
    # a cell for the cell's extent, minus the robot's 0.2 m radius
    assert clearance_m(grid, field, none, np.array([1.05, 2.05]), 0.0, 0.2) == pytest.approx(1.0 - 0.05 - 0.2)
    # a disc (radius 0.5) centred 1.0 m away is nearer than the wall
    disc = MovingObstacles([[2.05, 2.05]], [[3.0, 2.05]], [0.0], [0.5], [0.0])
    assert clearance_m(grid, field, disc, np.array([1.05, 2.05]), 0.0, 0.2) == pytest.approx(1.0 - 0.5 - 0.2)
