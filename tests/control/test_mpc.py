"""MPC (IPOPT and the OSQP fast path): limits to 1e-6, brake on infeasibility, tracking and
obstacle avoidance with stated numbers, the bicycle model."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.control.mpc import MPCConfig, MPCController, discrete_dynamics
from slamkit.control.protocols import (ControlStatus, DistanceGrid, LocalWorld, Reference,
                                       RobotState)
from slamkit.errors import ControlError
from slamkit.models.diff_drive import motion

SOLVERS = ["ipopt", "osqp", "fatrop"]


def _run(ctl, x0, ref, world, steps, plant=None):
    x, u = np.asarray(x0, float), np.zeros(2)
    xs, us, outs = [x], [u], []
    for _ in range(steps):
        out = ctl.compute(RobotState(x, u), ref, world)
        outs.append(out)
        u = out.command
        x = plant(x, u) if plant is not None else motion(x, u, ctl.config.dt_s)
        xs.append(x)
        us.append(u)
    return np.array(xs), np.array(us), outs


@pytest.fixture(scope="module", params=SOLVERS)
def controller(request):
    return MPCController(MPCConfig(solver=request.param))


def test_config_validation():
    with pytest.raises(ControlError):
        MPCConfig(model="tank")
    with pytest.raises(ControlError):
        MPCConfig(u_min=(1.0, -1.0), u_max=(0.5, 1.0))


def test_dynamics_is_midpoint_arc():
    """v = 1, omega = 1, dt = 0.1 from the origin: (0.1 cos 0.05, 0.1 sin 0.05, 0.1); the exact
    arc differs by the factor sinc(0.05) = 0.99958."""
    f = discrete_dynamics(MPCConfig())
    x = np.asarray(f([0, 0, 0], [1.0, 1.0])).ravel()
    np.testing.assert_allclose(x, [0.1 * np.cos(0.05), 0.1 * np.sin(0.05), 0.1], atol=1e-15)
    exact = motion(np.zeros(3), np.array([1.0, 1.0]), 0.1)
    np.testing.assert_allclose(exact[:2] / x[:2], np.sinc(0.05 / np.pi), rtol=1e-12)


def test_tracks_a_line_and_respects_limits_to_1e6(controller):
    """Start 0.5 m left of the x axis facing +x, track the axis at 0.6 m/s for 8 s: ends within
    3 cm of the line; every command inside the box [0, 0.8] x [-1.5, 1.5] and every change within
    (1.0, 3.0) * 0.1 = (0.1, 0.3) per step, to 1e-6."""
    controller.reset()
    ref = Reference([[0.0, 0.0], [20.0, 0.0]], speed_mps=0.6)
    xs, us, outs = _run(controller, [0.0, 0.5, 0.0], ref, LocalWorld(), 80)
    assert all(o.status is ControlStatus.OK for o in outs)
    assert abs(xs[-1, 1]) < 0.03
    assert xs[-1, 0] > 4.0  # about 0.6 m/s once converged
    c = controller.config
    assert np.all(us[:, 0] >= c.u_min[0] - 1e-6) and np.all(us[:, 0] <= c.u_max[0] + 1e-6)
    assert np.all(np.abs(us[:, 1]) <= c.u_max[1] + 1e-6)
    du = np.abs(np.diff(us, axis=0))
    assert np.all(du[:, 0] <= 0.1 + 1e-6) and np.all(du[:, 1] <= 0.3 + 1e-6)
    # the horizon explains the command: its first input is the command (up to the projection)
    np.testing.assert_allclose(outs[-1].predicted_commands[0], outs[-1].command, atol=1e-3)
    assert outs[-1].predicted_xytheta.shape == (21, 3)


def test_avoids_a_static_circle_on_the_path(controller):
    """A circle of radius 0.4 centred on the path at x = 2.5; robot radius 0.2 + margin 0.05, so
    the centre must stay >= 0.65 m from it (0.6 m allowing for the discretisation of the
    constraint between samples and the midpoint model)."""
    controller.reset()
    world = LocalWorld(circle_xy_m=[[2.5, 0.02]], circle_radius_m=[0.4])
    ref = Reference([[0.0, 0.0], [6.0, 0.0]], speed_mps=0.6)
    xs, _us, outs = _run(controller, [0.0, 0.0, 0.0], ref, world, 140)
    d = np.linalg.norm(xs[:, :2] - [2.5, 0.02], axis=1)
    assert d.min() > 0.6
    assert np.linalg.norm(xs[-1, :2] - [6.0, 0.0]) < 0.25
    assert sum(o.status is ControlStatus.FALLBACK_BRAKE for o in outs) == 0


def test_crossing_obstacle_is_predicted(controller):
    """An obstacle (r = 0.3) crossing the path at x = 2 from below at 0.5 m/s, timed to meet the
    robot: with its velocity in the prediction the robot keeps >= 0.45 m centre distance."""
    controller.reset()
    ref = Reference([[0.0, 0.0], [5.0, 0.0]], speed_mps=0.6)
    x, u = np.zeros(3), np.zeros(2)
    dmin = np.inf
    for k in range(100):
        t = 0.1 * k
        obs = np.array([2.0, -2.0 + 0.5 * t])
        world = LocalWorld(circle_xy_m=[obs], circle_radius_m=[0.3], circle_velocity_mps=[[0, 0.5]])
        out = controller.compute(RobotState(x, u), ref, world)
        u = out.command
        x = motion(x, u, 0.1)
        dmin = min(dmin, np.linalg.norm(x[:2] - (obs + [0, 0.05])))
    assert dmin > 0.45
    assert np.linalg.norm(x[:2] - [5.0, 0.0]) < 0.3


def test_distance_field_wall(controller):
    """Corridor along x with a wall at y >= 0.6 (distance field d = 0.6 - y) and a path at
    y = 0.5: the robot (radius 0.2 + 0.05) must stay at y <= 0.35 (+1 cm linearisation slack)."""
    controller.reset()
    res = 0.05
    ys = (np.arange(60) + 0.5) * res - 1.5
    d = np.clip(0.6 - ys, 0.0, None)
    grid = DistanceGrid(np.tile(d[:, None], (1, 200)), res, origin_xy_m=np.array([-1.0, -1.5]))
    world = LocalWorld(distance=grid)
    ref = Reference([[0.0, 0.5], [8.0, 0.5]], speed_mps=0.5)
    xs, _us, outs = _run(controller, [0.0, 0.0, 0.0], ref, world, 60)
    assert xs[:, 1].max() <= 0.36
    assert xs[-1, 1] > 0.25  # but it does get close to the wall, where the reference pulls


@pytest.mark.parametrize("solver", SOLVERS)
def test_infeasible_problem_brakes_instead_of_raising(solver):
    """Hard obstacle constraints; the robot sits inside the inflated obstacle (circle of radius
    1 m at its position): no input sequence satisfies the constraint at stage 1, the solver fails,
    the status is FALLBACK_BRAKE and the command brakes from (0.5, 0.2) by the rate limits
    (0.1, 0.3) to (0.4, 0.0)."""
    controller = MPCController(MPCConfig(solver=solver, soft_obstacles=False))
    world = LocalWorld(circle_xy_m=[[0.05, 0.0]], circle_radius_m=[1.0])
    ref = Reference([[0.0, 0.0], [5.0, 0.0]])
    out = controller.compute(RobotState([0.0, 0.0, 0.0], [0.5, 0.2]), ref, world)
    assert out.status is ControlStatus.FALLBACK_BRAKE
    np.testing.assert_allclose(out.command, [0.4, 0.0], atol=1e-12)
    # and the controller recovers on the next, feasible, cycle
    out = controller.compute(RobotState([0.0, 0.0, 0.0], [0.4, 0.0]), ref, LocalWorld())
    assert out.status is ControlStatus.OK


def test_soft_constraints_give_the_least_violating_plan(controller):
    """Same situation with the default soft constraints: the problem stays feasible, the plan
    reports a positive slack (the violation it could not avoid, here >= 0.5 m: the robot can move
    at most 0.9 m in 2 s from inside a 1.25 m inflated radius), and the robot drives out."""
    controller.reset()
    world = LocalWorld(circle_xy_m=[[0.05, 0.0]], circle_radius_m=[1.0])
    out = controller.compute(RobotState([0.0, 0.0, 0.0], [0.5, 0.2]),
                             Reference([[0.0, 0.0], [5.0, 0.0]]), world)
    assert out.status is ControlStatus.OK
    assert out.info["max_slack_m"] > 0.5


@pytest.mark.parametrize("solver", SOLVERS)
def test_bicycle_tracks_a_turn_within_steering_limits(solver):
    """Kinematic bicycle (L = 0.5 m, |steer| <= 0.5 rad, steer rate <= 1 rad/s) follows an L-shaped
    path, the plant being ``slamkit.models.bicycle`` (exact arc, not the MPC's midpoint model): ends
    within 0.3 m of the corner's far end with steering within limits to 1e-6."""
    from slamkit.models.bicycle import Bicycle

    cfg = MPCConfig(model="bicycle", solver=solver, u_min=(0.0, -0.5), u_max=(0.8, 0.5),
                    du_max_per_s=(1.0, 1.0))
    ctl = MPCController(cfg)
    car = Bicycle(wheelbase_m=0.5, max_steer_rad=0.5)
    plant = lambda x, u: car.motion(x, u, cfg.dt_s)  # noqa: E731
    ref = Reference([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]], speed_mps=0.5)
    xs, us, outs = _run(ctl, [0.0, 0.0, 0.0], ref, LocalWorld(), 170, plant=plant)
    assert np.linalg.norm(xs[-1, :2] - [3.0, 3.0]) < 0.3
    assert np.abs(us[:, 1]).max() <= 0.5 + 1e-6
    assert np.abs(np.diff(us[:, 1])).max() <= 0.1 + 1e-6


def test_opti_reference_solves_the_same_problem():
    """The benchmark's reference (casadi.Opti, default IPOPT, cold start) and the tuned build give
    the same first input on the same problem (to 1e-3: both stop at IPOPT tolerances)."""
    from slamkit.bench.mpc_reference import OptiMPC

    cfg = MPCConfig()
    ctl = MPCController(cfg)
    world = LocalWorld(circle_xy_m=[[1.5, 0.3]], circle_radius_m=[0.3], circle_velocity_mps=[[0.0, -0.2]])
    state = RobotState([0.0, 0.0, 0.1], [0.3, 0.0])
    ref = Reference([[0.0, 0.0], [5.0, 0.0]], speed_mps=0.6)
    prob = ctl.problem(state, ref, world)
    out = ctl.compute(state, ref, world)
    ok, u0, _t = OptiMPC(cfg).solve(prob)
    assert ok and out.status is ControlStatus.OK
    np.testing.assert_allclose(u0, out.command, atol=1e-3)
