"""DWA: the issue's worked window, admissibility, the scoring terms and the rollout geometry."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.control.dwa import DWAConfig, DWAController, dynamic_window
from slamkit.control.protocols import ControlStatus, DistanceGrid, LocalWorld, Reference, RobotState
from slamkit.control.rollout import distance_to_collision, rollout_arcs, trajectory_clearance


def test_worked_example_window():
    """v_c = 0.4, omega_c = 0, a = 0.5 m/s^2, alpha = 1 rad/s^2, dt = 0.1 s:
    v in [0.4 - 0.05, 0.4 + 0.05] = [0.35, 0.45], omega in [-0.1, 0.1]."""
    cfg = DWAConfig(accel_max_mps2=0.5, alpha_max_radps2=1.0, dt_s=0.1)
    (v_lo, v_hi), (w_lo, w_hi) = dynamic_window(0.4, 0.0, cfg)
    assert (v_lo, v_hi) == pytest.approx((0.35, 0.45))
    assert (w_lo, w_hi) == pytest.approx((-0.1, 0.1))
    cand = DWAController(cfg).candidates(RobotState([0, 0, 0], command=[0.4, 0.0]))
    assert cand.shape == (cfg.n_v * cfg.n_omega, 2)
    assert cand[:, 0].min() == pytest.approx(0.35) and cand[:, 0].max() == pytest.approx(0.45)
    assert cand[:, 1].min() == pytest.approx(-0.1) and cand[:, 1].max() == pytest.approx(0.1)


def test_window_clipped_by_velocity_limits():
    cfg = DWAConfig(v_max_mps=0.8, omega_max_radps=1.5, accel_max_mps2=0.5, alpha_max_radps2=1.0)
    (v_lo, v_hi), (w_lo, w_hi) = dynamic_window(0.78, 1.45, cfg)
    assert (v_lo, v_hi) == pytest.approx((0.73, 0.8))
    assert (w_lo, w_hi) == pytest.approx((1.35, 1.5))


def test_rollout_is_exact_arc():
    """v = 0.5, omega = 0.5 for 2 s: a quarter... radius 1 m arc through angle 1 rad:
    (sin 1, 1 - cos 1) = (0.841471, 0.459698), heading 1."""
    traj = rollout_arcs(np.zeros(3), np.array([[0.5, 0.5], [0.5, 0.0]]), 0.1, 20)
    assert traj.shape == (2, 21, 3)
    np.testing.assert_allclose(traj[0, -1], [np.sin(1.0), 1 - np.cos(1.0), 1.0], atol=1e-12)
    np.testing.assert_allclose(traj[1, -1], [1.0, 0.0, 0.0], atol=1e-12)
    # radius of every sample is 1 around the centre (0, 1)
    np.testing.assert_allclose(np.linalg.norm(traj[0, :, :2] - [0.0, 1.0], axis=1), 1.0, atol=1e-12)


def test_distance_to_collision_and_admissibility():
    """Straight at 1 m/s towards a circle of radius 0.5 at x = 2 with a 0.2 m robot: the disc touches
    it at x = 1.3; samples every 0.1 m -> first hit at x = 1.3 (clearance 0, index 13), safe until
    index 12 -> dist 1.2 m. Admissible iff v <= sqrt(2 * 1.2 * b)."""
    world = LocalWorld(circle_xy_m=[[2.0, 0.0]], circle_radius_m=[0.5])
    traj = rollout_arcs(np.zeros(3), np.array([[1.0, 0.0]]), 0.1, 30)
    clear = trajectory_clearance(traj, world, 0.1, 0.2)
    assert clear[0, 0] == pytest.approx(1.3)
    dist = distance_to_collision(traj, clear, np.array([1.0]), 0.1)
    assert dist[0] == pytest.approx(1.2)


def test_moving_obstacle_is_predicted():
    """An obstacle at (1, -1) moving +y at 1 m/s sits on the robot's straight line at t = 1 s."""
    world = LocalWorld(circle_xy_m=[[1.0, -1.0]], circle_radius_m=[0.1], circle_velocity_mps=[[0.0, 1.0]])
    traj = rollout_arcs(np.zeros(3), np.array([[1.0, 0.0]]), 0.1, 20)
    clear = trajectory_clearance(traj, world, 0.1, 0.0)
    assert int(np.argmin(clear[0])) == 10
    assert clear[0, 10] == pytest.approx(-0.1)


def test_brakes_when_nothing_is_admissible():
    """Robot at 0.5 m/s, a circle whose surface is 0.2 m from the robot's disc on every arc of the
    window ([0.45, 0.55] x [-0.1, 0.1]). At v = 0.45 the first colliding sample is 5 (0.225 m),
    safe distance 4 * 0.045 = 0.18 m, sqrt(2 * 0.18 * 0.5) = 0.42 < 0.45: nothing is admissible,
    so the command is the brake within the window, (0.45, 0)."""
    world = LocalWorld(circle_xy_m=[[0.7, 0.0]], circle_radius_m=[0.3])
    cfg = DWAConfig(robot_radius_m=0.2, safety_margin_m=0.0, accel_max_mps2=0.5, alpha_max_radps2=1.0,
                    brake_decel_mps2=0.5)
    out = DWAController(cfg).compute(RobotState([0, 0, 0], command=[0.5, 0.0]),
                                     Reference([[0.0, 0.0], [5.0, 0.0]]), world)
    assert out.status is ControlStatus.FALLBACK_BRAKE
    np.testing.assert_allclose(out.command, [0.45, 0.0])
    assert np.all(np.isneginf(out.scores))


def test_prefers_turning_away_from_an_obstacle_on_the_path():
    """Obstacle slightly left of the straight line; with alpha = 5 rad/s^2 the window reaches
    |omega| = 0.5 and arcs turning right stay free over the 3 s horizon (the straight ones at
    v >= 0.3 m/s reach x >= 0.9 and hit the inflated circle at x = 0.6), so a right turn wins."""
    world = LocalWorld(circle_xy_m=[[1.2, 0.05]], circle_radius_m=[0.3])
    out = DWAController(DWAConfig(alpha_max_radps2=5.0, horizon_s=3.0)).compute(RobotState([0, 0, 0], command=[0.4, 0.0]),
                                  Reference([[0.0, 0.0], [5.0, 0.0]]), world)
    assert out.status is ControlStatus.OK
    assert out.command[1] < 0  # obstacle slightly left of the line: turn right
    assert out.candidates_xytheta.shape == (11 * 21, 31, 3)
    assert out.scores[out.chosen] == np.max(out.scores)


def test_heads_for_goal_in_free_space():
    out = DWAController().compute(RobotState([0, 0, 0], command=[0.4, 0.0]),
                                  Reference([[0.0, 0.0], [5.0, 0.0]]), LocalWorld())
    # straight ahead, fastest speed in the window [0.3, 0.5] (a = 1 m/s^2)
    np.testing.assert_allclose(out.command, [0.5, 0.0])


def test_line_of_sight_target_stops_where_the_path_turns_out_of_sight():
    """A path east 2 m, then north, hooking round a post at P = (1.6, 0.6); the robot at the
    start needs its disc plus margin (0.2 + 0.05 m) clear. The line from the robot to (2, y)
    passes P at |1.2 - 1.6 y| / sqrt(4 + y^2), which falls to 0.25 m at y = 0.4298 (the root of
    2.4975 y^2 - 3.84 y + 1.19 = 0): path points every 5 cm are seen up to (2, 0.40), arc length
    2.40 m -- though (2, 1.2) and beyond are seen again past the post's other side, the sight
    ends at the first point hidden."""
    res = 0.01
    xs = np.arange(-1.0, 4.0, res) + res / 2
    gx, gy = np.meshgrid(xs, xs)
    grid = DistanceGrid(np.hypot(gx - 1.6, gy - 0.6), res, origin_xy_m=np.array([-1.0, -1.0]))
    path = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 3.0]])
    cfg = DWAConfig(robot_radius_m=0.2, safety_margin_m=0.05, v_max_mps=1.0, horizon_s=2.0, lookahead_m=1.0)
    dwa = DWAController(cfg)
    assert dwa.visible_s(path, np.zeros(2), grid) == pytest.approx(2.40)
    # a robot at (1.6, 0.38), 0.22 m below the post, needs only the clearance it has (else even
    # the first point would be hidden: no limit): the line to (2, y) passes P at 0.088 /
    # sqrt(0.16 + (y - 0.38)^2), 0.219 m at y = 0.418, so the sight ends at (2, 0.40) again
    assert dwa.visible_s(path, np.array([1.6, 0.38]), grid) == pytest.approx(2.40)
    # nothing in the way: no limit short of the reach (1 + 1 x 2 m beyond the projection)
    assert dwa.visible_s(path, np.zeros(2), DistanceGrid(np.full((500, 500), 5.0), res, np.array([-1.0, -1.0]))) \
        == pytest.approx(3.0)
