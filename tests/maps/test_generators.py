"""Office and warehouse generators: seeded, sized as asked, free space connected."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.generators import (OfficeConfig, WarehouseConfig, office, random_free_poses,
                                     warehouse)

SMALL_OFFICE = OfficeConfig(width_m=30.0, height_m=25.0, resolution_m=0.1)
SMALL_WAREHOUSE = WarehouseConfig(width_m=30.0, height_m=30.0, resolution_m=0.1)


@pytest.mark.parametrize("make,config", [(office, SMALL_OFFICE), (warehouse, SMALL_WAREHOUSE)])
def test_generated_world_is_seeded_sized_walled_and_connected(make, config):
    a = make(np.random.default_rng(1), config)
    b = make(np.random.default_rng(1), config)
    c = make(np.random.default_rng(2), config)
    assert np.array_equal(a.occupied, b.occupied)
    assert not np.array_equal(a.occupied, c.occupied)
    assert a.shape == (round(config.height_m / 0.1), round(config.width_m / 0.1))
    assert a.resolution_m == 0.1
    # closed outer wall
    occ = a.occupied
    assert occ[0].all() and occ[-1].all() and occ[:, 0].all() and occ[:, -1].all()
    # structured, neither empty nor solid
    assert 0.04 < occ.mean() < 0.35
    # every free cell is reachable from every other (4-connectivity)
    labels, n = ndimage.label(~occ)
    assert n == 1


def test_office_doors_pass_a_robot_and_corridors_are_wide():
    grid = office(np.random.default_rng(5), SMALL_OFFICE)
    # free space still connected for a robot of radius 0.3 m (cells with clearance > 0.3 m,
    # i.e. at least 0.35 m between the robot centre and any wall cell centre)
    clear = distance_field_m(grid) > 0.35
    labels, n = ndimage.label(clear)
    sizes = np.bincount(labels.ravel())[1:]
    # the component through the spine corridor holds nearly all clear cells (a few pockets
    # behind furniture may be cut off)
    assert sizes.max() / sizes.sum() > 0.95


def test_random_free_poses_respect_clearance():
    grid = warehouse(np.random.default_rng(0), SMALL_WAREHOUSE)
    poses = random_free_poses(grid, np.random.default_rng(1), 200, clearance_m=0.5)
    d = distance_field_m(grid)
    cells = grid.world_to_cell(poses[:, :2])
    assert np.all(d[cells[:, 1], cells[:, 0]] > 0.5)
    assert np.all(np.abs(poses[:, 2]) <= np.pi)
