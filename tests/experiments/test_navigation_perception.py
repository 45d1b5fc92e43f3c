"""Privileged perception, the navigation benchmark's ablation (issue 33: which share of the moving
hits is the detector's, the tracker's, the planner's): slamkit.experiments.navigation.perception."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import ConfigError
from slamkit.estimation.obstacle_tracker import Detection, TrackerConfig
from slamkit.experiments.navigation.config import variants_of
from slamkit.experiments.navigation.episode import EpisodeConfig
from slamkit.experiments.navigation.map_source import RobotMap
from slamkit.experiments.navigation.perception import TruePerception
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.moving_obstacles import MovingObstacles
from slamkit.sim.navigation_world import NavigationPlant, NavigationScenario

NO_DETECTION = Detection(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=int))


def _plant(discs: MovingObstacles) -> NavigationPlant:
    """A 10 m room (walls 0.1 m thick), the robot at (5, 5) facing +x."""
    occ = np.zeros((200, 200), bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    grid = OccupancyGrid(occ, 0.05, np.zeros(2), name="room")
    sc = NavigationScenario("room", 0, grid, np.array([5.0, 5.0, 0.0]), np.array([5.0, 5.0, 0.0]),
                            np.zeros((0, 2)), discs)
    return NavigationPlant(sc, np.random.default_rng(0))


def _walker() -> MovingObstacles:
    """A disc of 0.3 m walking from (7, 3) to (7, 7) at 0.5 m/s (8 s one way), beside a still one
    behind it at (9, 5) that the first hides at t = 4 s."""
    return MovingObstacles(np.array([[7.0, 3.0], [9.0, 5.0]]), np.array([[7.0, 7.0], [9.0, 5.0]]),
                           np.array([0.5, 0.0]), np.array([0.3, 0.25]), np.zeros(2))


def _run(perception: TruePerception, plant: NavigationPlant, stamps_s) -> None:
    for t in stamps_s:
        plant.scan(float(t))
        perception.update(float(t), NO_DETECTION)  # what the stack's own detector found is ignored


def test_true_tracks_hold_the_true_discs_states_and_only_the_ones_the_lidar_saw():
    plant = _plant(_walker())
    perception = TruePerception(plant, RobotMap(plant.scenario.grid, "truth"), TrackerConfig(), true_tracks=True)
    _run(perception, plant, [0.0])
    assert len(perception.tracks().ids) == 0  # one scan: tentative (confirm_hits 2)
    _run(perception, plant, [0.1, 0.2, 0.3])
    tracks = perception.tracks()
    assert len(tracks.ids) == 2
    order = np.argsort(tracks.xy_m[:, 0])
    np.testing.assert_allclose(tracks.xy_m[order], [[7.0, 3.15], [9.0, 5.0]], atol=1e-12)
    np.testing.assert_allclose(tracks.velocity_mps[order], [[0.0, 0.5], [0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(tracks.radius_m[order], [0.3, 0.25], atol=1e-12)


def test_true_detections_leave_the_filter_its_lag_at_a_turn():
    """Exact centres every 0.1 s of a disc shuttling between (7, 4) and (7, 6) at 0.5 m/s, turning
    at t = 4 s: the constant-velocity filter (accel_psd 0.5, detections believed to 8 cm) still
    says +0.06 m/s at 4.2 s, when the disc has been coming back at 0.5 m/s for 0.2 s, and -0.45 m/s
    at 4.5 s -- the lag ``true_tracks`` removes."""
    shuttler = MovingObstacles(np.array([[7.0, 4.0]]), np.array([[7.0, 6.0]]), np.array([0.5]), np.array([0.3]),
                               np.zeros(1))
    for t_end, vy, y in ((3.9, 0.5, 5.95), (4.2, 0.0613, 5.9607), (4.5, -0.4473, 5.7778)):
        plant = _plant(shuttler)
        perception = TruePerception(plant, RobotMap(plant.scenario.grid, "truth"), TrackerConfig(), true_tracks=False)
        _run(perception, plant, np.arange(0.0, t_end + 1e-9, 0.1))
        tracks = perception.tracks()
        np.testing.assert_allclose(tracks.velocity_mps[0], [0.0, vy], atol=1e-3)
        np.testing.assert_allclose(tracks.xy_m[0], [7.0, y], atol=1e-3)


def test_a_disc_the_lidar_does_not_see_gets_no_detection():
    """At t = 4 s the walker stands at (7, 5) between the robot and the still disc at (9, 5) (it
    spans +-2.9 deg from the robot, the walker +-8.6 deg): only one detection reaches the tracker."""
    plant = _plant(_walker())
    perception = TruePerception(plant, RobotMap(plant.scenario.grid, "truth"), TrackerConfig(), true_tracks=True)
    _run(perception, plant, [4.0, 4.1])
    tracks = perception.tracks()
    assert len(tracks.ids) == 1
    np.testing.assert_allclose(tracks.xy_m[0], [7.0, 5.05], atol=1e-12)


def test_the_truth_enters_in_the_robots_map_frame():
    """A SLAM map whose frame is the world's turned by 90 deg and moved by (1, 2): the walker at
    (7, 3.5) moving +y at 0.5 m/s appears at (1 - 3.5, 2 + 7) = (-2.5, 9) moving -x."""
    plant = _plant(_walker())
    robot = RobotMap(plant.scenario.grid, "slam", anchors_world_xytheta=np.zeros((1, 3)),
                     anchors_map_xytheta=np.array([[1.0, 2.0, np.pi / 2]]))
    xy, v, r = TruePerception(plant, robot, TrackerConfig(), true_tracks=True).truth_at(1.0)
    np.testing.assert_allclose(xy[0], [-2.5, 9.0], atol=1e-12)
    np.testing.assert_allclose(v[0], [-0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(r, [0.3, 0.25])


def test_the_perception_is_an_episode_setting_a_variant_may_change():
    variants = variants_of({}, {}, [{"name": "lidar"}, {"name": "oracle", "episode": {"perception": "true_tracks"}}])
    assert [ep.perception for _, _, ep in variants] == ["lidar", "true_tracks"]
    with pytest.raises(ConfigError, match="perception must be one of lidar, true_detections, true_tracks"):
        EpisodeConfig(perception="perfect")
