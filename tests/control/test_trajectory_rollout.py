"""Trajectory rollout as its own controller: its window spans the horizon, its arcs accelerate,
its objective is the course's (alpha 0.8, beta 0.2, gamma 0.4)."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.control.dwa import DWAController
from slamkit.control.protocols import ControlStatus, LocalWorld, Reference, RobotState
from slamkit.errors import ControlError
from slamkit.control.trajectory_rollout import RolloutConfig, RolloutController, ramped_commands


def test_course_objective_is_the_default():
    c = RolloutConfig()
    assert (c.w_heading, c.w_clearance, c.w_velocity, c.w_path, c.w_progress) == (0.8, 0.2, 0.4, 0.0, 0.0)


def test_window_spans_the_horizon_not_one_period():
    state = RobotState([0.0, 0.0, 0.0], [0.2, 0.0])
    ro = RolloutController().candidates(state)
    dwa = DWAController().candidates(state)
    # v: DWA 0.2 +- 1.0 * 0.1 -> [0.1, 0.3]; rollout 0.2 +- 1.0 * 2.0 clipped to [0, 0.8]
    assert (dwa[:, 0].min(), dwa[:, 0].max()) == pytest.approx((0.1, 0.3))
    assert (ro[:, 0].min(), ro[:, 0].max()) == pytest.approx((0.0, 0.8))
    # omega: DWA 0 +- 3 * 0.1 = +-0.3; rollout 0 +- 3 * 2 clipped to +-1.5
    assert (ro[:, 1].min(), ro[:, 1].max()) == pytest.approx((-1.5, 1.5))


def test_a_straight_rollout_accelerates_from_rest():
    # from rest towards 0.8 m/s at 1 m/s^2 in 0.1 s steps: speeds 0.1 ... 0.8 then 0.8 for 12 steps;
    # distance after 2 s = 0.1 * (0.1 + ... + 0.8) + 12 * 0.08 = 0.36 + 0.96 = 1.32 m
    ctl = RolloutController()
    traj = ctl.rollouts(RobotState([0.0, 0.0, 0.0], [0.0, 0.0]), np.array([[0.8, 0.0]]), 20)
    assert traj.shape == (1, 21, 3)
    assert traj[0, -1, 0] == pytest.approx(1.32)
    assert traj[0, 1, 0] == pytest.approx(0.01)
    np.testing.assert_allclose(ramped_commands([0.0, 0.0], [[0.8, -1.0]], ctl.config, 3)[0],
                               [[0.1, -0.3], [0.2, -0.6], [0.3, -0.9]])


def test_sends_the_first_step_of_the_chosen_ramp():
    ctl = RolloutController()
    ref = Reference([[0.0, 0.0], [5.0, 0.0]])
    out = ctl.compute(RobotState([0.0, 0.0, 0.0], [0.0, 0.0]), ref, LocalWorld())
    assert out.status is ControlStatus.OK
    # on an open straight path the fastest straight arc wins; the command is its first step
    assert out.info["target_command"] == pytest.approx((0.8, 0.0))
    np.testing.assert_allclose(out.command, [0.1, 0.0], atol=1e-12)


def test_a_hedged_prediction_grows_the_disc_with_the_look_ahead_time():
    from slamkit.control.protocols import LocalWorld

    # a 0.3 m disc at (2, 0) coming at 0.5 m/s, predicted with lam = 0.5 (centre at half its
    # speed, radius growing at 0.25 m/s): at t = 2 s the centre is at (1.5, 0), radius 0.8 m, so the
    # origin is 0.7 m clear; the plain constant-velocity prediction puts it at (1, 0) with 0.3 m
    # (0.7 m clear as well: the front edge is the same), and a point behind it, (2.5, 0), is 0.2 m
    # clear of the hedged disc against 1.2 m of the plain one
    hedged = LocalWorld([[2.0, 0.0]], [0.3], [[-0.25, 0.0]], circle_growth_mps=[0.25])
    plain = LocalWorld([[2.0, 0.0]], [0.3], [[-0.5, 0.0]])
    np.testing.assert_allclose(hedged.radii_at([0.0, 2.0]), [[0.3], [0.8]])
    pts = np.array([[[0.0, 0.0]], [[2.5, 0.0]]])  # (2 points, T = 1, 2)
    np.testing.assert_allclose(hedged.clearance_m(pts, [2.0]).ravel(), [0.7, 0.2], atol=1e-12)
    np.testing.assert_allclose(plain.clearance_m(pts, [2.0]).ravel(), [0.7, 1.2], atol=1e-12)
    with pytest.raises(ControlError, match="growth"):
        LocalWorld([[2.0, 0.0]], [0.3], circle_growth_mps=[-0.1])


def test_a_disc_stops_growing_at_its_growth_limit():
    from slamkit.control.chance_constraints import tightened_world
    from slamkit.control.protocols import LocalWorld

    # two standing 0.3 m discs growing at 0.2 m/s, the first up to 0.1 m: at 0.25 s both are
    # 0.35 m, at 2 s the first is 0.4 m (limited from 0.5 s on) and the second 0.7 m
    world = LocalWorld([[2.0, 0.0], [0.0, 2.0]], [0.3, 0.3], circle_growth_mps=[0.2, 0.2],
                       circle_growth_max_m=[0.1, np.inf])
    np.testing.assert_allclose(world.radii_at([0.0, 0.25, 2.0]), [[0.3, 0.3], [0.35, 0.35], [0.4, 0.7]])
    np.testing.assert_allclose(world.clearance_m(np.array([[0.0, 0.0]]), [2.0]), [1.3])
    # the chance tightening keeps the limits (it rebuilds the world with wider discs)
    tight = tightened_world(world, [0.0, 0.0], np.diag([0.01, 0.01]), k_sigma=1.0)
    np.testing.assert_allclose(tight.radii_at([2.0]), [[0.5, 0.8]])
    assert LocalWorld([[2.0, 0.0]], [0.3]).circle_growth_max_m.tolist() == [np.inf]
    # a copy of the first disc elsewhere (a second guess of the same obstacle) keeps its radius,
    # growth and limit: at (1, 1) coming at (0, -0.5) m/s, 0.4 m at 2 s, centre (1, 0)
    more = world.with_copies([0], [[1.0, 1.0]], [[0.0, -0.5]])
    assert more.num_circles == 3 and world.num_circles == 2
    np.testing.assert_allclose(more.radii_at([2.0]), [[0.4, 0.7, 0.4]])
    np.testing.assert_allclose(more.circles_at([2.0])[0, 2], [1.0, 0.0])
    for bad in ([-0.1], [np.nan], [0.1, 0.2]):
        with pytest.raises(ControlError, match="growth"):
            LocalWorld([[2.0, 0.0]], [0.3], circle_growth_max_m=bad)


def test_rollout_profiles_of_held_commands_are_the_exact_arcs():
    from slamkit.control.rollout import rollout_arcs, rollout_profiles

    cmds = np.array([[0.5, 0.3], [-0.2, 0.0], [0.4, -1.0]])
    held = np.repeat(cmds[:, None, :], 20, axis=1)
    np.testing.assert_allclose(rollout_profiles([1.0, 2.0, 0.3], held, 0.1), rollout_arcs([1.0, 2.0, 0.3], cmds, 0.1, 20),
                               atol=1e-12)
