"""The robot's map in the navigation pipeline: the true grid, or a map slamkit's lidar SLAM built
on a mapping tour of the world (issue 14, step 1), cached in the results folder."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import ConfigError
from slamkit.config import build
from slamkit.experiments.navigation.map_source import MapSourceConfig, RobotMap, robot_map
from slamkit.maps.generators import OfficeConfig, office
from slamkit.sim.moving_obstacles import MovingObstacles
from slamkit.sim.navigation_world import NavigationScenario


def _scenario() -> NavigationScenario:
    grid = office(np.random.default_rng(4), OfficeConfig(width_m=12.0, height_m=12.0), name="office")
    pose = np.array([6.0, 6.0, 0.0])
    return NavigationScenario("office_4", 4, grid, pose, pose, pose[None, :2], MovingObstacles.empty())


def test_map_source_config_is_checked():
    assert build(MapSourceConfig, None, "map").source == "truth"
    with pytest.raises(ConfigError, match=r"map: unknown parameter\(s\) \['sorce'\]"):
        build(MapSourceConfig, {"sorce": "slam_tour"}, "map")
    with pytest.raises(ConfigError, match="source"):
        build(MapSourceConfig, {"source": "gmapping"}, "map")
    with pytest.raises(ConfigError, match="tour_goals"):
        build(MapSourceConfig, {"source": "slam_tour", "tour_goals": 0}, "map")
    with pytest.raises(ConfigError, match="lidar_slam.slam"):
        build(MapSourceConfig, {"source": "slam_tour", "slam": {"loop_rounds_": 1}}, "map")


def test_a_pipeline_file_with_a_misspelt_map_key_names_its_line(tmp_path):
    from slamkit.config import load_yaml
    from slamkit.experiments.pipeline import check_pipeline

    path = tmp_path / "nav.yaml"
    path.write_text("pipeline: navigation\nname: x\nmap:\n  source: slam_tour\n  tour_goal: 4\n")
    doc = load_yaml(path)
    with pytest.raises(ConfigError, match=r"nav.yaml:5: map.tour_goal: unknown key \(did you mean 'tour_goals'"):
        check_pipeline(doc.data, doc, str(path))


def test_truth_source_is_the_world_grid():
    sc = _scenario()
    robot = robot_map(sc, MapSourceConfig())
    assert robot.grid is sc.grid and robot.source == "truth" and not robot.metrics


def test_slam_tour_map_matches_the_world_and_is_cached(tmp_path):
    sc = _scenario()
    cfg = MapSourceConfig(source="slam_tour", tour_goals=4, tour_duration_s=90.0)
    robot = robot_map(sc, cfg, tmp_path / "maps")
    g, m = robot.grid, robot.metrics
    assert g.resolution_m == 0.05 and g.shape == sc.grid.shape
    np.testing.assert_allclose(g.origin_xy_m, sc.grid.origin_xy_m)
    # measured: precision 1.000, recall 0.998, free coverage 0.95, tour ATE 4 mm (max error 1.5 cm)
    assert m["map_precision_1cell"] > 0.98 and m["map_recall_1cell"] > 0.98
    assert m["map_free_coverage"] > 0.85
    assert m["map_tour_ate_m"] < 0.03 and m["map_tour_error_max_m"] < 0.1
    # unobserved cells are occupied: the robot's map holds every true wall it saw and no more free space
    assert np.mean(g.occupied[sc.grid.occupied]) > 0.99
    (cached,) = (tmp_path / "maps").glob("office_*.npz")
    assert [p.name for p in (tmp_path / "maps").iterdir()] == [cached.name]  # no partial file beside it
    again = robot_map(sc, cfg, tmp_path / "maps")
    np.testing.assert_array_equal(again.grid.occupied, g.occupied)
    assert again.metrics == pytest.approx(m)
    np.testing.assert_array_equal(again.anchors_map_xytheta, robot.anchors_map_xytheta)
    np.testing.assert_array_equal(again.anchors_world_xytheta, robot.anchors_world_xytheta)


def test_start_and_goal_reach_the_robot_through_the_nearest_keyframe():
    # a map frame rotated 90 deg and shifted (1, 2) m from the world near the first keyframe,
    # and shifted only (0.1, 0) m near the second: each pose goes through its nearest keyframe
    sc = _scenario()
    world = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    in_map = np.array([[1.0, 2.0, np.pi / 2], [10.1, 0.0, 0.0]])
    robot = RobotMap(sc.grid, "slam_tour", {}, world, in_map)
    np.testing.assert_allclose(robot.to_map(np.array([1.0, 0.0, 0.0])), [1.0, 3.0, np.pi / 2], atol=1e-12)
    np.testing.assert_allclose(robot.to_map(np.array([9.0, 1.0, 0.3])), [9.1, 1.0, 0.3], atol=1e-12)
    # the world's own grid: the identity
    np.testing.assert_allclose(RobotMap(sc.grid, "truth").to_map(np.array([9.0, 1.0, 0.3])), [9.0, 1.0, 0.3])
