"""Potential fields: the issue's worked example, the conic/combined forms, field-based repulsion
and local-minimum handling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.control.potential_fields import (PotentialFieldConfig, PotentialFieldController,
                                              attractive_force, repulsive_force_circles,
                                              repulsive_force_field)
from slamkit.control.protocols import ControlStatus, DistanceGrid, LocalWorld, Reference, RobotState


def test_worked_example_robot_1_1_goal_5_5_obstacle_3_3():
    """Robot q = (1, 1), goal (5, 5), obstacle centre (3, 3) radius 1, k_att = 1, k_rep = 2, D0 = 2.

    Attractive (quadratic): F = -k_att (q - q_g) = -(1 - 5, 1 - 5) = (4, 4).
    Repulsive: rho = |q - c| - r = 2 sqrt(2) - 1 = 1.828427 <= D0, so it is active;
    |F| = k_rep (1/rho - 1/D0) / rho^2 = 2 (0.546918 - 0.5) / 3.343146 = 0.028068,
    direction (q - c)/|q - c| = (-1, -1)/sqrt(2), so F_rep = (-0.019847, -0.019847).
    """
    q = np.array([1.0, 1.0])
    att = attractive_force(q, np.array([5.0, 5.0]), k_att=1.0, kind="quadratic")
    np.testing.assert_allclose(att, [4.0, 4.0])
    rep = repulsive_force_circles(q, [[3.0, 3.0]], [1.0], k_rep=2.0, influence_m=2.0)
    rho = 2 * np.sqrt(2) - 1
    assert rho == pytest.approx(1.828427, abs=1e-6)
    np.testing.assert_allclose(rep, [-0.019847, -0.019847], atol=1e-6)
    assert np.linalg.norm(rep) == pytest.approx(0.028068, abs=1e-6)
    # pointing away from the obstacle centre
    assert np.dot(rep, q - np.array([3.0, 3.0])) > 0


def test_repulsion_inactive_beyond_influence_distance():
    # rho = 2 sqrt(2) - 1 = 1.83 > D0 = 1.5
    rep = repulsive_force_circles(np.array([1.0, 1.0]), [[3.0, 3.0]], [1.0], k_rep=2.0, influence_m=1.5)
    np.testing.assert_array_equal(rep, [0.0, 0.0])


def test_conic_and_combined_attraction():
    q, g = np.array([1.0, 1.0]), np.array([5.0, 4.0])  # |q - g| = 5
    np.testing.assert_allclose(attractive_force(q, g, 2.0, "conic"), [1.6, 1.2])
    # combined: conic scaled by d* beyond d* = 1 -> |F| = k d* = 2, quadratic within
    np.testing.assert_allclose(attractive_force(q, g, 2.0, "combined", d_star_m=1.0), [1.6, 1.2])
    near = g + np.array([0.3, -0.4])
    np.testing.assert_allclose(attractive_force(near, g, 2.0, "combined", 1.0), [-0.6, 0.8])


@settings(max_examples=50, deadline=None)
@given(st.floats(0.2, 3.0), st.floats(0.0, 2 * np.pi))
def test_combined_attraction_is_continuous_at_d_star(d_star, angle):
    g = np.zeros(2)
    u = np.array([np.cos(angle), np.sin(angle)])
    inside = attractive_force(u * d_star * (1 - 1e-9), g, 1.5, "combined", d_star)
    outside = attractive_force(u * d_star * (1 + 1e-9), g, 1.5, "combined", d_star)
    np.testing.assert_allclose(inside, outside, atol=1e-6)


def test_field_repulsion_matches_circle_for_a_wall():
    """A wall x <= 0 as a distance field d(x, y) = x: at x = 0.5 with D0 = 1, k_rep = 1
    |F| = (1/0.5 - 1) / 0.25 = 4, pointing +x."""
    res = 0.05
    xs = (np.arange(200) + 0.5) * res - 5.0  # cell centres from -5 to 5
    d = np.clip(np.tile(xs, (40, 1)), 0.0, None)
    grid = DistanceGrid(d, res, origin_xy_m=np.array([-5.0, -1.0]))
    f = repulsive_force_field(np.array([0.5, 0.0]), grid, k_rep=1.0, influence_m=1.0)
    np.testing.assert_allclose(f, [4.0, 0.0], atol=1e-6)


def test_controller_steers_along_force_and_respects_limits():
    cfg = PotentialFieldConfig(attractive="quadratic", k_att=1.0, lookahead_m=10.0, v_max_mps=0.5,
                               accel_max_mps2=1.0, dt_s=0.1, robot_radius_m=0.0)
    ctl = PotentialFieldController(cfg)
    state = RobotState([0.0, 0.0, 0.0], command=[0.3, 0.0])
    out = ctl.compute(state, Reference([[0.0, 0.0], [4.0, 0.0]]), LocalWorld())
    # force (4, 0) points straight ahead: v = min(k_v |F|, v_c + a dt = 0.4, v_max) = 0.4, omega = 0
    np.testing.assert_allclose(out.command, [0.4, 0.0])
    np.testing.assert_allclose(out.force_xy["attractive"], [4.0, 0.0])
    assert out.status is ControlStatus.OK


def _trap():
    """Goal straight behind a wide obstacle on the line to the goal: attraction and repulsion
    cancel at the robot (a classic local minimum)."""
    world = LocalWorld(circle_xy_m=[[2.0, 0.0]], circle_radius_m=[1.0])
    ref = Reference([[0.0, 0.0], [4.0, 0.0]])
    return world, ref


def test_local_minimum_hand_over_and_random_walk():
    world, ref = _trap()
    # choose a pose where forces cancel: quadratic k_att = 0.1 to the carrot 1 m ahead gives |F_att|
    # = 0.1; robot 0.5 m from the surface gives repulsion k_rep (1/0.5 - 1) / 0.25 = 4 k_rep,
    # so k_rep = 0.025 balances it exactly.
    cfg = PotentialFieldConfig(attractive="quadratic", k_att=0.1, k_rep=0.025, influence_m=1.0,
                               lookahead_m=1.0, robot_radius_m=0.0, escape="handover")
    state = RobotState([0.5, 0.0, 0.0])
    out = PotentialFieldController(cfg).compute(state, ref, world)
    np.testing.assert_allclose(out.force_xy["total"], [0.0, 0.0], atol=1e-9)
    assert out.status is ControlStatus.LOCAL_MINIMUM
    np.testing.assert_allclose(out.command, [0.0, 0.0])

    walk = PotentialFieldController(PotentialFieldConfig(**{**cfg.__dict__, "escape": "random_walk"}),
                                    rng=np.random.default_rng(3))
    out = walk.compute(state, ref, world)
    assert out.status is ControlStatus.ESCAPING
    # the escape heading lies in the half plane facing away from the obstacle: |heading - pi| < pi/2
    heading = walk._escape_heading
    assert abs((heading - np.pi + np.pi) % (2 * np.pi) - np.pi) < np.pi / 2


def test_goal_reached():
    out = PotentialFieldController().compute(RobotState([3.95, 0.0, 0.0]),
                                             Reference([[0.0, 0.0], [4.0, 0.0]]), LocalWorld())
    assert out.status is ControlStatus.GOAL_REACHED
