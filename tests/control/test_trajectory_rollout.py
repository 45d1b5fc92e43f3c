"""Trajectory rollout as its own controller: its window spans the horizon, its arcs accelerate,
its objective is the course's (alpha 0.8, beta 0.2, gamma 0.4)."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.control.dwa import DWAController
from slamkit.control.protocols import ControlStatus, LocalWorld, Reference, RobotState
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
