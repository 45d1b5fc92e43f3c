"""MPC (IPOPT, fatrop and the OSQP fast path): limits to 1e-6, brake on infeasibility, tracking and
obstacle avoidance with stated numbers, the bicycle model; the one OCP behind every backend (the
transcriptions' sizes, the QP's cost equal to the NLP's) and the backend contract."""

from __future__ import annotations

import numpy as np
import pytest

import casadi as ca

from slamkit.control.mpc import (BACKENDS, SOLVERS, MPCBackend, MPCConfig, MPCController, MPCProblem,
                                 MPCSolution, NLPTranscription, OptimalControlProblem, build_nlp,
                                 build_nlp_stagewise, discrete_dynamics)
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


# --------------------------------------------------------------------------- the one OCP, its backends


def test_transcriptions_of_the_one_ocp():
    """N = 6 stages, K = 2 circles plus the distance-field row. Multiple shooting: 3 * 7 states +
    2 * 6 inputs + 6 slacks = 39 variables; 3 (x_0) + 18 (dynamics) + 10 (rates of u_1..u_5) +
    6 * 3 (obstacle rows) = 49 constraints. Stage-wise (fatrop): 7 z_k of 5 + 6 v_k of 3 = 53
    variables; 30 dynamics + 5 (z_0) + 12 rate + 12 box + 6 slack + 5 * 3 obstacle rows (stages
    1..5) = 80 rows, of which the 35 dynamics and initial rows are equalities."""
    ocp = OptimalControlProblem.of(MPCConfig(horizon=6, max_circles=2))
    ms, sw = build_nlp(ocp), build_nlp_stagewise(ocp)
    assert isinstance(ms, NLPTranscription) and isinstance(sw, NLPTranscription)
    assert (ms.size, ms.g.shape[0], len(ms.lbg)) == (39, 49, 49) and ms.equality is None
    assert ms.x_index.shape == (7, 3) and ms.u_index.shape == (6, 2) and ms.s_index.shape == (6,)
    assert (sw.size, sw.g.shape[0], sum(sw.equality)) == (53, 80, 35)
    np.testing.assert_array_equal(sw.x_index[1], [8, 9, 10])
    np.testing.assert_array_equal(sw.u_index[0], [5, 6])
    assert sw.s_index[-1] == 8 * 5 + 7


def test_the_qp_fast_path_minimises_the_nlp_cost():
    """The OSQP backend's 1/2 z'Pz + q'z is the multiple-shooting NLP's cost over the same z: at a
    random z and random parameters, J(z) - J(0) agrees to 1e-9, and P and q equal CasADi's Hessian
    and gradient at 0 to 1e-12 (entries up to 2 * slack weight = 2000)."""
    cfg = MPCConfig(horizon=6, max_circles=2)
    ocp = OptimalControlProblem.of(cfg)
    nlp = build_nlp(ocp)
    rng = np.random.default_rng(4)
    prob = MPCProblem(rng.normal(size=3), rng.normal(size=2), rng.normal(size=(6, 3)),
                      rng.normal(size=(6, 2, 2)), np.ones(2), rng.normal(size=(6, 2)), rng.normal(size=6),
                      np.zeros(2), np.zeros(2))
    p = prob.vector(ocp.layout)
    J = ca.Function("J", [nlp.w, nlp.p], [nlp.f, ca.gradient(nlp.f, nlp.w), ca.hessian(nlp.f, nlp.w)[0]])
    upper = ocp.cost_hessian().toarray()
    P, q = upper + np.triu(upper, 1).T, ocp.cost_gradient(prob)
    f0, g0, h0 = (np.asarray(v) for v in J(np.zeros(nlp.size), p))
    np.testing.assert_allclose(P, h0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(q, g0.ravel(), rtol=0, atol=1e-12)
    z = rng.normal(size=nlp.size)
    fz = float(J(z, p)[0])
    assert abs((fz - f0.item()) - (0.5 * z @ P @ z + q @ z)) < 1e-9 * max(1.0, abs(fz))


REF_L = Reference([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]], speed_mps=0.6)
WORLD_2 = LocalWorld(circle_xy_m=[[1.5, 0.2], [3.2, 1.5]], circle_radius_m=[0.2, 0.3],
                     circle_velocity_mps=[[0.0, -0.3], [0.0, 0.0]])


def _solve_once(solver):
    ctl = MPCController(MPCConfig(solver=solver))
    state = RobotState([0.0, 0.1, 0.05], [0.3, 0.0])
    warm = ctl.warm_start(state.world_xytheta_body, state.command)
    prob = ctl.ocp.instantiate(state, REF_L, WORLD_2, warm)
    return ctl, prob, warm, ctl.backend.solve(prob, warm)


@pytest.mark.parametrize("solver", SOLVERS)
def test_backend_contract(solver):
    """Every backend behind ``solve(problem, warm_start)``: an MPCSolution whose plan starts at x0,
    keeps every input in the box and u_0 in its rate window (to 1e-6), the same plan again after
    ``reset`` (bit for bit), and the NLP backends' plans obey the model to 1e-5."""
    assert set(BACKENDS) == set(SOLVERS)
    ctl, prob, warm, sol = _solve_once(solver)
    assert isinstance(ctl.backend, MPCBackend) and isinstance(sol, MPCSolution) and sol.success
    X, U = sol.states_xytheta, sol.commands
    assert X.shape == (21, 3) and U.shape == (20, 2)
    np.testing.assert_allclose(X[0], prob.x0, atol=1e-6)
    assert np.all(U >= ctl.ocp.u_min - 1e-6) and np.all(U <= ctl.ocp.u_max + 1e-6)
    assert np.all(U[0] >= prob.u_lo0 - 1e-6) and np.all(U[0] <= prob.u_hi0 + 1e-6)
    assert sol.info["max_slack_m"] < 1e-6  # this problem is feasible without slack
    ctl.backend.reset()
    again = ctl.backend.solve(prob, warm)
    np.testing.assert_array_equal(again.commands, U)
    if solver != "osqp":  # the QP keeps the dynamics linearised along the warm start only
        f = ctl.ocp.dynamics
        defect = max(np.abs(np.asarray(f(X[i], U[i])).ravel() - X[i + 1]).max() for i in range(20))
        assert defect < 1e-5


def test_ipopt_and_fatrop_solve_the_same_problem():
    """The two NLP transcriptions of the one OCP give the same first input to 2e-3 (measured
    7e-4: the transcriptions relax the obstacle rows with differently indexed slacks and both
    stop at their tolerances)."""
    u0 = {s: _solve_once(s)[3].commands[0] for s in ("ipopt", "fatrop")}
    np.testing.assert_allclose(u0["ipopt"], u0["fatrop"], atol=2e-3)
