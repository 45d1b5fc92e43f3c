"""The robot's map built by lidar SLAM as a system (issue 30): slamkit.systems.slam_map runs
LidarSlam over a sequence and returns the map a navigation stack gets."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import ConfigError
from slamkit.maps.log_odds import map_quality
from slamkit.sim.grid_world import GridScenario, simulate_grid_sequence
from slamkit.systems.lidar_slam import LidarSlam, LidarSlamConfig
from slamkit.systems.slam_map import slam_map


@pytest.fixture(scope="module")
def tour():
    scenario = GridScenario(name="tour", world="office", world_size_m=(20.0, 20.0), num_goals=3, duration_s=60.0,
                            encoder=None, imu_rate_hz=None, gps=None)
    return simulate_grid_sequence(scenario, np.random.default_rng(0))


def test_the_map_is_the_slam_estimate_on_the_worlds_cells(tour):
    sequence, truth = tour
    built = slam_map(sequence, LidarSlamConfig(), like=truth, name="robot")
    # the world's extent at the config's resolution (0.1 m; the world is 0.05 m)
    assert built.grid.resolution_m == 0.1 and built.grid.name == "robot"
    np.testing.assert_allclose(np.array(built.grid.shape) * 0.1, np.array(truth.shape) * truth.resolution_m)
    np.testing.assert_array_equal(built.grid.origin_xy_m, truth.origin_xy_m)
    # unknown: occupied -- every cell no scan observed is a wall to the robot
    assert built.grid.occupied[~built.log_odds.observed].all()
    np.testing.assert_array_equal(built.grid.occupied[built.log_odds.observed],
                                  built.log_odds.occupancy_grid().occupied[built.log_odds.observed])
    # the same SLAM run as the system driven by hand (no hidden extra step)
    system = LidarSlam(LidarSlamConfig(), sequence.initial_world_xytheta_body, None, name=sequence.name)
    for ev in sequence:
        system.step(ev)
    np.testing.assert_array_equal(system.finish().keyframe_poses, built.estimate.keyframe_poses)
    # measured (seed 0, 52 keyframes, 52% of the cells observed): precision 1.0, IoU 0.9986 within
    # one cell; the band leaves room for the last-bit flips of ICP and loop closure, and still
    # refuses a map drawn at wrong poses
    q = map_quality(built.log_odds, truth, tolerance_cells=1)
    assert q.precision > 0.95 and q.iou > 0.9


def test_unknown_free_differs_only_on_unobserved_cells(tour):
    sequence, truth = tour
    occ = slam_map(sequence, LidarSlamConfig(), like=truth)
    free = slam_map(sequence, LidarSlamConfig(), like=truth, unknown="free")
    seen = occ.log_odds.observed
    np.testing.assert_array_equal(occ.grid.occupied[seen], free.grid.occupied[seen])
    assert not free.grid.occupied[~seen].any()
    with pytest.raises(ConfigError, match="unknown"):
        slam_map(sequence, LidarSlamConfig(), unknown="maybe")
