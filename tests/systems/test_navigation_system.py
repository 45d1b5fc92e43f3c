"""The navigation stack: its contract (events in, commands out, a public pose and covariance),
and a short closed-loop run through the simulator in the default suite."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data.estimate import LatestBelief
from slamkit.data.sequence import Odometry
from slamkit.errors import ConfigError
from slamkit.experiments.navigation import EpisodeConfig, make_navigation_scenario, run_episode
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.systems.navigation import NavigationConfig, NavigationStack


def _room() -> OccupancyGrid:
    occ = np.zeros((80, 120), bool)  # 6 m x 4 m at 5 cm, walls 2 cells thick
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    return OccupancyGrid(occ, 0.05)


def test_events_in_commands_out_and_a_public_belief():
    stack = NavigationStack(_room())
    stack.reset([1.0, 2.0, 0.0], np.diag([0.01, 0.01, 0.01]))
    assert isinstance(stack, LatestBelief)
    assert stack.command(0.0).status == "no_goal"
    stack.set_goal([4.5, 2.0, 0.0])
    out = stack.command(0.0)
    assert out.status == "driving" and out.command[0] >= 0.0 and out.safe_stop
    assert stack.path is not None and np.allclose(stack.path[-1], [4.5, 2.0], atol=0.05)
    stack.step(Odometry(0.1, 0.1, 0.5, 0.0))
    mean, cov = stack.current_pose()
    assert mean[0] == pytest.approx(1.05, abs=0.05) and cov.shape == (3, 3)
    est = stack.latest_estimate()
    np.testing.assert_allclose(est.trajectory.xytheta()[0], mean)
    assert est.pose_covariances.shape == (1, 3, 3)
    assert set(stack.timings_s) == {"localisation", "perception", "global_planner", "local_planner"}


def test_config_is_checked():
    with pytest.raises(ConfigError, match="uncertainty"):
        NavigationConfig(uncertainty="maybe")
    with pytest.raises(ConfigError, match="grid planner"):
        NavigationConfig(global_planner="rrt_star")


def test_short_closed_loop_run_reaches_the_goal_within_3_cm():
    # office seed 1 with its two crossing obstacles: measured 25.5 s, final error 0.57 cm
    sc = make_navigation_scenario(1, "office")
    ep = run_episode(sc, NavigationConfig(), EpisodeConfig(max_time_s=60.0))
    m = ep.metrics
    assert m["success"] == 1.0
    assert m["final_position_error_m"] <= 0.03 and m["final_heading_error_rad"] <= 0.1
    assert m["collision_static"] == 0.0 and m["collision_moving"] == 0.0
    assert m["localisation_error_max_m"] < 0.1
    assert m["replans"] >= 1
