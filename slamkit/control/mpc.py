"""Model predictive control with CasADi (Andersson et al., "CasADi: a software framework for
nonlinear optimization and optimal control", Math. Prog. Comp. 11, 2019) for a unicycle /
differential drive or a kinematic bicycle.

Optimal control problem over N stages of length dt (multiple shooting, Bock & Plitt 1984):

    min   sum_{k=1}^{N-1} |p_k - p_k^ref|^2_Q + q_th (th_k - th_k^ref)^2
          + |p_N - p_N^ref|^2_{Q_N} + q_th,N (th_N - th_N^ref)^2          (terminal cost)
          + sum_{k=0}^{N-1} |u_k|^2_R + |u_k - u_{k-1}|^2_{R_d}
    s.t.  x_0 = x(t),  x_{k+1} = f(x_k, u_k)                              (dynamics)
          u_min <= u_k <= u_max,  |u_k - u_{k-1}| <= du_max dt  (u_{-1} = last command)
          |p_k - o_{j,k}|^2 >= (r_j + r_robot + margin)^2                 (moving circles, predicted)
          d(p_k^-) + grad d(p_k^-) . (p_k - p_k^-) >= r_robot + margin   (static distance field,
                                                                           linearised at the previous
                                                                           plan's p_k^-)

f is the midpoint (second-order) discretisation of the continuous model -- for the unicycle
x+ = x + v dt (cos, sin)(th + w dt / 2), th+ = th + w dt, which differs from the exact arc only by
the factor sinc(w dt / 2) (< 0.4 % at w dt = 0.3) and is smooth everywhere, unlike the exact arc
written with 1/w. The bicycle (rear-axle reference, wheelbase L) has w = v tan(delta) / L.

Architecture (issue 18): the module reads top to bottom in three parts.

1. **The problem, defined once.** :class:`OptimalControlProblem` holds, built from one
   :class:`MPCConfig`, the dynamics f, the running cost (J_{k+1} = J_k + l_k, stage and terminal
   weights) and the obstacle rows h >= 0 as CasADi functions, the input and rate limits, the
   parameter layout, and the exact quadratic form of the same cost for the QP. An
   :class:`MPCProblem` is the numbers of one cycle (initial state, last command, reference,
   predicted circles, distance-field linearisation): the OCP's parameters.
   :func:`build_nlp` (multiple shooting, w = (X, U, S)) and :func:`build_nlp_stagewise` (w =
   (z_0, v_0, ..., z_N), the layout fatrop's structure detection needs) are two transcriptions of
   those functions into a typed :class:`NLPTranscription`; neither writes the cost itself.
2. **One backend per solver** behind :class:`MPCBackend` -- ``solve(problem, warm_start) ->
   MPCSolution`` and ``reset()``: :class:`IpoptBackend`, :class:`FatropBackend` and
   :class:`OsqpRtiBackend`. A backend builds its solver once and keeps that solver's private state
   (IPOPT's multipliers, OSQP's factorisation and duals); nothing else knows which solver runs.
3. **The controller on top.** :class:`MPCController` picks the backend once at construction
   (:data:`BACKENDS`), keeps the previous plan, hands every cycle the problem and the warm start
   (that plan shifted by one stage and rolled out from the measured state), and turns the
   solution into a :class:`~slamkit.control.protocols.ControlOutput`.

The NLPs are built ONCE as parametric ``casadi.nlpsol`` objects (initial state, last command,
reference, obstacle positions and the distance-field linearisation are parameters), so a control
cycle is only a solve, warm-started from the previous solution shifted by one stage. Backends:

* ``ipopt`` (default): the interior-point NLP solver with options chosen for warm-started MPC
  (see ``MPCConfig.ipopt_options``), warm-started in the primal and dual variables.
* ``osqp`` (the fast path): one real-time-iteration step (Diehl et al., "Real-time optimization
  and nonlinear model predictive control of processes governed by DAEs", J. Proc. Control 12, 2002):
  dynamics and obstacle constraints are linearised around the shifted previous solution and the
  resulting sparse QP is solved by OSQP (Stellato et al., Math. Prog. Comp. 12, 2020), whose matrix
  pattern is fixed at construction so a cycle only updates numbers. Its cost is the OCP's cost,
  exactly (a quadratic; ``tests/control/test_mpc.py`` checks it against CasADi's derivatives).
* ``fatrop`` (Vanroye et al., "FATROP: a fast constrained optimal control problem solver for
  robot trajectory optimization and control", IROS 2023; shipped with CasADi 3.8): an interior-point
  method whose linear algebra is a Riccati recursion over the stages. Its structure detection needs
  every constraint to involve one stage only, so the rate constraint u_k - u_{k-1} is written with
  the last input carried as extra state, z_k = (x_k, u_{k-1}), and each stage's slack is a third
  input; the terminal stage (which has no input, hence no slack) carries no obstacle rows.

A solver failure (infeasible, iteration limit, numerical trouble) never raises inside the loop: the
output has status FALLBACK_BRAKE and the command decelerates within the rate limits. The returned
command is projected onto the input and rate limits exactly (interior-point solvers satisfy them
only to their tolerances).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Protocol, runtime_checkable

import casadi as ca
import numpy as np
import osqp
import scipy.sparse as sp

from slamkit.control.path_following import path_reference
from slamkit.control.protocols import (non_finite_brake, ControlOutput, ControlStatus, LocalWorld, Reference,
                                       RobotState, brake_command)
from slamkit.errors import ControlError

MODELS = ("unicycle", "bicycle")
SOLVERS = ("ipopt", "osqp", "fatrop")
_OSQP_OK = (int(osqp.SolverStatus.OSQP_SOLVED), int(osqp.SolverStatus.OSQP_SOLVED_INACCURATE))
_FAR_M = 1e3  # where unused obstacle slots are parked (relative to the robot)


def _default_ipopt() -> dict[str, Any]:
    return {
        "print_level": 0, "sb": "yes",
        # warm start from the shifted previous primal-dual solution; a small initial barrier with
        # the monotone (Fiacco-McCormick) update keeps the iterate near that point instead of
        # re-centring it: measured 3-4 iterations per cycle instead of 7-9 with the adaptive rule
        "warm_start_init_point": "yes", "mu_strategy": "monotone", "mu_init": 1e-4,
        "warm_start_bound_push": 1e-6, "warm_start_mult_bound_push": 1e-6,
        "warm_start_slack_bound_push": 1e-6,
        "tol": 1e-4, "acceptable_tol": 1e-3, "acceptable_iter": 3, "max_iter": 100,
        # exact Hessian: limited-memory BFGS needed 13 iterations and ran ~4x slower here
    }


@dataclass(frozen=True)
class MPCConfig:
    model: str = "unicycle"
    solver: str = "ipopt"
    horizon: int = 20
    dt_s: float = 0.1
    wheelbase_m: float = 0.5
    #: input limits: (v, omega) for the unicycle, (v, steering) for the bicycle
    u_min: tuple[float, float] = (0.0, -1.5)
    u_max: tuple[float, float] = (0.8, 1.5)
    #: rate limits per second: (accel m/s^2, omega accel rad/s^2 or steering rate rad/s)
    du_max_per_s: tuple[float, float] = (1.0, 3.0)
    q_xy: float = 4.0
    q_theta: float = 0.2
    q_xy_terminal: float = 20.0
    q_theta_terminal: float = 0.5
    r_u: tuple[float, float] = (0.05, 0.05)
    r_du: tuple[float, float] = (0.5, 0.2)
    robot_radius_m: float = 0.2
    safety_margin_m: float = 0.1
    #: obstacle slots in the NLP; the nearest ``max_circles`` circles are constrained
    max_circles: int = 6
    #: circles farther than this from the robot are not constrained (saves slots)
    circle_range_m: float = 5.0
    #: obstacle rows get one slack per stage (metres, >= 0) with an exact L1 penalty, so a
    #: moving obstacle that cannot be avoided any more yields the least-violating plan (measured:
    #: with hard constraints the QP/NLP went infeasible, the robot braked and was hit from the
    #: side); False makes them hard (then infeasibility -> FALLBACK_BRAKE)
    soft_obstacles: bool = True
    slack_weight: float = 1e3
    #: reference points inside an inflated circle are pushed this far beyond its border
    reference_clearance_m: float = 0.15
    use_distance_field: bool = True
    goal_tolerance_m: float = 0.2
    ipopt_options: dict[str, Any] = field(default_factory=_default_ipopt)
    fatrop_options: dict[str, Any] = field(default_factory=lambda: {"print_level": 0, "tol": 1e-4,
                                                                     "mu_init": 1e-2, "max_iter": 100})
    osqp_eps: float = 1e-4
    #: SQP-style re-linearisations per cycle of the OSQP fast path (1 = real-time iteration)
    osqp_iterations: int = 1

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ControlError(f"MPCConfig.model must be one of {MODELS}, got {self.model!r}")
        if self.solver not in SOLVERS:
            raise ControlError(f"MPCConfig.solver must be one of {SOLVERS}, got {self.solver!r}")
        if self.horizon < 1 or self.dt_s <= 0:
            raise ControlError("MPCConfig.horizon must be >= 1 and dt_s > 0")
        if any(lo > hi for lo, hi in zip(self.u_min, self.u_max)):
            raise ControlError("MPCConfig.u_min must be <= u_max")
        if min(self.du_max_per_s) <= 0:
            raise ControlError("MPCConfig.du_max_per_s must be positive")


# --------------------------------------------------------------------------- the problem, once


def discrete_dynamics(config: MPCConfig) -> ca.Function:
    """x+ = f(x, u) with the midpoint rule (see the module docstring); a casadi Function (3,2)->3."""
    x = ca.SX.sym("x", 3)
    u = ca.SX.sym("u", 2)
    dt = config.dt_s
    w = u[1] if config.model == "unicycle" else u[0] * ca.tan(u[1]) / config.wheelbase_m
    phi = x[2] + 0.5 * w * dt
    xn = ca.vertcat(x[0] + u[0] * dt * ca.cos(phi), x[1] + u[0] * dt * ca.sin(phi), x[2] + w * dt)
    return ca.Function("f", [x, u], [xn], ["x", "u"], ["x_next"])


def running_cost(config: MPCConfig, terminal: bool = False) -> ca.Function:
    """J_{k+1} = J_k + l_k, the one definition of the cost: the effort |u_k|^2_R and rate
    |u_k - u_{k-1}|^2_{R_d} of stage k's input, the tracking error of the state x_{k+1} it leads
    to (terminal weights for k = N-1), and the exact L1 penalty (plus a small quadratic for a
    unique minimiser) on the obstacle slack s >= 0 the transcription gives the stage. Written as
    an accumulation so that every transcription adds the terms in the same order (the IPOPT
    build's expression graph is node for node the one it had before issue 18)."""
    J = ca.SX.sym("J")
    x, u, u_prev, ref, s = (ca.SX.sym("x", 3), ca.SX.sym("u", 2), ca.SX.sym("u_prev", 2),
                            ca.SX.sym("ref", 3), ca.SX.sym("s"))
    r_u, r_du = np.asarray(config.r_u), np.asarray(config.r_du)
    q_xy = config.q_xy_terminal if terminal else config.q_xy
    q_theta = config.q_theta_terminal if terminal else config.q_theta
    J_next = J + (ca.sumsqr(np.sqrt(r_u) * u) + ca.sumsqr(np.sqrt(r_du) * (u - u_prev)))
    e = x - ref
    J_next = J_next + q_xy * ca.sumsqr(e[:2])
    J_next = J_next + q_theta * e[2] ** 2
    J_next = J_next + (config.slack_weight * s + config.slack_weight * s ** 2)
    return ca.Function("terminal_cost" if terminal else "stage_cost", [J, x, u, u_prev, ref, s], [J_next],
                       ["J", "x_next", "u", "u_prev", "ref", "s"], ["J_next"])


def obstacle_rows(config: MPCConfig) -> ca.Function:
    """h(p, circles, radii, grad, offset, s) >= 0 for one stage's position p: the distance to each
    of the ``max_circles`` predicted circles minus its inflated radius (a distance, not squared, so
    the slack s is in metres like the distance-field row), then the linearised distance-field row
    grad . p - offset (when ``use_distance_field``); every row relaxed by the stage's slack."""
    k = config.max_circles
    p, obs, radius = ca.SX.sym("p", 2), ca.SX.sym("obs", 2, k), ca.SX.sym("r", k)
    grad, offset, s = ca.SX.sym("g", 2), ca.SX.sym("b"), ca.SX.sym("s")
    rows = [ca.sqrt(ca.sumsqr(p - obs[:, j]) + 1e-9) - radius[j] + s for j in range(k)]
    if config.use_distance_field:
        rows.append(ca.dot(grad, p) - offset + s)
    return ca.Function("h", [p, obs, radius, grad, offset, s], [ca.vertcat(*rows)],
                       ["p", "circles", "radii", "grad", "offset", "s"], ["rows"])


class ParameterLayout:
    """Where each parameter sits in the flat parameter vector of the NLPs (stage-major)."""

    def __init__(self, n: int, k: int):
        self.n, self.k = n, k
        sizes = [("x0", 3), ("u_prev", 2), ("ref", 3 * n), ("obs_xy", 2 * n * k), ("obs_r", k),
                 ("dist_g", 2 * n), ("dist_b", n)]
        self.slices: dict[str, slice] = {}
        i = 0
        for name, size in sizes:
            self.slices[name] = slice(i, i + size)
            i += size
        self.size = i


@dataclass(frozen=True)
class MPCProblem:
    """The numbers of one cycle's OCP (its parameters), shared by every backend."""

    x0: np.ndarray
    u_prev: np.ndarray
    ref: np.ndarray          # (N, 3) for stages 1..N
    obs_xy: np.ndarray       # (N, K, 2) predicted centres for stages 1..N
    obs_r: np.ndarray        # (K,) radii inflated by robot radius + margin
    dist_g: np.ndarray       # (N, 2)
    dist_b: np.ndarray       # (N,)
    u_lo0: np.ndarray        # (2,) bounds of u_0 from limits and rate
    u_hi0: np.ndarray

    def vector(self, layout: ParameterLayout) -> np.ndarray:
        p = np.zeros(layout.size)
        s = layout.slices
        p[s["x0"]] = self.x0
        p[s["u_prev"]] = self.u_prev
        p[s["ref"]] = self.ref.ravel()          # stage-major: (x, y, th) per stage
        p[s["obs_xy"]] = self.obs_xy.ravel()    # stage-major, then obstacle, then (x, y)
        p[s["obs_r"]] = self.obs_r
        p[s["dist_g"]] = self.dist_g.ravel()
        p[s["dist_b"]] = self.dist_b
        return p


@dataclass(frozen=True)
class SymbolicParameters:
    """The parameter vector ``p`` of an NLP and its named views (CasADi SX)."""

    p: ca.SX
    x0: ca.SX       # (3,)
    u_prev: ca.SX   # (2,)
    ref: ca.SX      # (3, N)
    obs_xy: ca.SX   # (2, N K): stage i's circles are columns i K .. (i+1) K - 1
    obs_r: ca.SX    # (K,)
    dist_g: ca.SX   # (2, N)
    dist_b: ca.SX   # (N,)


@dataclass(frozen=True)
class WarmStart:
    """The previous plan shifted by one stage (its last input repeated) and rolled out from the
    measured state -- a dynamically consistent guess; the circle and distance-field rows are
    linearised along it too. ``states_xytheta`` (N+1, 3), ``commands`` (N, 2)."""

    states_xytheta: np.ndarray
    commands: np.ndarray


@dataclass(frozen=True)
class OptimalControlProblem:
    """The OCP of the module docstring as CasADi functions and limits, built once from a config
    (:meth:`of`); every backend transcribes these and nothing else."""

    config: MPCConfig
    layout: ParameterLayout
    dynamics: ca.Function       # x_{k+1} = f(x_k, u_k)
    stage_cost: ca.Function     # J_{k+1} = J_k + l_k, k < N-1
    terminal_cost: ca.Function  # the same with the terminal tracking weights, k = N-1
    obstacle_rows: ca.Function  # h(p_k, ...) >= 0, stages 1..N
    u_min: np.ndarray
    u_max: np.ndarray
    du: np.ndarray              # rate limit per stage, du_max_per_s * dt_s

    @classmethod
    def of(cls, config: MPCConfig) -> OptimalControlProblem:
        return cls(config, ParameterLayout(config.horizon, config.max_circles), discrete_dynamics(config),
                   running_cost(config), running_cost(config, terminal=True), obstacle_rows(config),
                   np.asarray(config.u_min, dtype=float), np.asarray(config.u_max, dtype=float),
                   np.asarray(config.du_max_per_s) * config.dt_s)

    @property
    def horizon(self) -> int:
        return self.config.horizon

    def cost(self, k: int) -> ca.Function:
        """The running cost of stage k = 0 .. N-1 (whose input u_k leads to x_{k+1})."""
        return self.terminal_cost if k == self.horizon - 1 else self.stage_cost

    def symbolic_parameters(self) -> SymbolicParameters:
        n, k, sl = self.horizon, self.config.max_circles, self.layout.slices
        P = ca.SX.sym("p", self.layout.size)
        return SymbolicParameters(P, P[sl["x0"]], P[sl["u_prev"]], ca.reshape(P[sl["ref"]], 3, n),
                                  ca.reshape(P[sl["obs_xy"]], 2, n * k), P[sl["obs_r"]],
                                  ca.reshape(P[sl["dist_g"]], 2, n), P[sl["dist_b"]])

    # -- the cost as a quadratic form (what the QP backend minimises) ---------------------------

    def _state_weights(self) -> np.ndarray:
        c, n = self.config, self.horizon
        wx = np.zeros(3 * (n + 1))
        for i in range(1, n + 1):
            last = i == n
            wx[3 * i:3 * i + 2] = c.q_xy_terminal if last else c.q_xy
            wx[3 * i + 2] = c.q_theta_terminal if last else c.q_theta
        return wx

    def cost_hessian(self) -> sp.csc_matrix:
        """The running costs summed over the horizon are 1/2 z' P z + q' z + const in
        z = (x_0 .. x_N, u_0 .. u_{N-1}, s_1 .. s_N); P's upper triangle (OSQP's convention)."""
        c, n = self.config, self.horizon
        r_u, r_du = np.asarray(c.r_u), np.asarray(c.r_du)
        D = sp.eye(2 * n, format="csc") - sp.eye(2 * n, k=-2, format="csc")  # u_k - u_{k-1}
        Pu = sp.diags(np.tile(r_u, n)) + D.T @ sp.diags(np.tile(r_du, n)) @ D
        Ps = sp.diags(np.full(n, c.slack_weight))
        return sp.triu(2.0 * sp.block_diag([sp.diags(self._state_weights()), Pu, Ps]), format="csc")

    def cost_gradient(self, prob: MPCProblem) -> np.ndarray:
        """q of :meth:`cost_hessian`: -2 W ref for the states, -2 R_d u_prev for u_0 and the L1
        slack weight."""
        c, n = self.config, self.horizon
        nx = 3 * (n + 1)
        q = np.zeros(nx + 3 * n)
        ref_full = np.vstack([prob.x0, prob.ref]).ravel()
        q[:nx] = -2.0 * self._state_weights() * ref_full
        q[nx:nx + 2] = -2.0 * np.asarray(c.r_du) * prob.u_prev
        q[nx + 2 * n:] = c.slack_weight
        return q

    # -- one cycle's numbers ------------------------------------------------------------------

    def instantiate(self, state: RobotState, reference: Reference, world: LocalWorld,
                    warm_start: WarmStart) -> MPCProblem:
        """This cycle's parameters: the reference sampled along the path (pushed out of circles),
        the nearest ``max_circles`` circles within range predicted over the horizon, and the
        distance field linearised along the warm start's positions."""
        c = self.config
        n, k = c.horizon, c.max_circles
        x0 = state.world_xytheta_body.copy()
        u_prev = state.command.copy()
        spacing = max(reference.speed_mps, 1e-3) * c.dt_s
        ref = path_reference(reference.path_xy_m, x0[:2], spacing, n, x0[2])
        t = c.dt_s * np.arange(1, n + 1)
        inflate = c.robot_radius_m + c.safety_margin_m
        obs_xy = np.tile(x0[:2] + _FAR_M, (n, k, 1))
        obs_r = np.zeros(k)
        if world.num_circles:
            d_now = np.linalg.norm(world.circle_xy_m - x0[:2], axis=1) - world.circle_radius_m
            near = np.argsort(d_now)[:k]
            near = near[d_now[near] <= c.circle_range_m]
            obs_xy[:, :len(near)] = world.circles_at(t)[:, near]
            obs_r[:len(near)] = world.circle_radius_m[near] + inflate
            ref = self._push_reference_out(ref, obs_xy[:, :len(near)], obs_r[:len(near)])
        dist_g = np.zeros((n, 2))
        dist_b = np.full(n, -1.0)  # 0 . p - (-1) >= 0 always holds
        if c.use_distance_field and world.distance is not None:
            p_lin = warm_start.states_xytheta[1:, :2]
            d, grad = world.distance.query(p_lin)
            norm = np.linalg.norm(grad, axis=1, keepdims=True)
            g_unit = np.where(norm > 1e-9, grad / np.maximum(norm, 1e-9), 0.0)
            # only constrain stages within reach of an obstacle; elsewhere the row stays inactive
            active = (norm[:, 0] > 1e-9) & (d < inflate + 1.0)
            dist_g = np.where(active[:, None], g_unit, 0.0)
            dist_b = np.where(active, inflate - d + np.einsum("ij,ij->i", g_unit, p_lin), -1.0)
        lo0 = np.clip(u_prev - self.du, self.u_min, self.u_max)
        hi0 = np.clip(u_prev + self.du, self.u_min, self.u_max)
        return MPCProblem(x0, u_prev, ref, obs_xy, obs_r, dist_g, dist_b, lo0, hi0)

    def _push_reference_out(self, ref: np.ndarray, obs_xy: np.ndarray, obs_r: np.ndarray) -> np.ndarray:
        """Move reference points that fall inside an (inflated, predicted) circle radially out to
        its border plus ``reference_clearance_m``. Without this a circle sitting on the path is a
        local minimum of the tracking cost: the solver stops in front of it because every way
        round first moves away from the reference (observed: stuck at the obstacle, 0 % progress).
        A point at the very centre goes to the left of the path direction."""
        if obs_xy.shape[1] == 0:
            return ref
        out = ref.copy()
        d = ref[:, None, :2] - obs_xy  # (N, K, 2)
        dist = np.linalg.norm(d, axis=2)
        radius = obs_r + self.config.reference_clearance_m
        inside = (dist < radius) & (obs_r > 0)
        if not inside.any():
            return ref
        left = np.stack([-np.sin(ref[:, 2]), np.cos(ref[:, 2])], axis=1)[:, None, :]
        unit = np.where(dist[..., None] > 1e-6, d / np.maximum(dist, 1e-6)[..., None], left)
        push = np.where(inside[..., None], obs_xy + unit * radius[None, :, None] - ref[:, None, :2], 0.0)
        # several overlapping circles: take the largest push per point (approximate but monotone)
        pick = np.argmax(np.linalg.norm(push, axis=2), axis=1)
        out[:, :2] += push[np.arange(len(ref)), pick]
        return out


# --------------------------------------------------------------------------- transcriptions


@dataclass(frozen=True)
class NLPTranscription:
    """The OCP as ``casadi.nlpsol`` takes it -- min f(w; p) s.t. lbg <= g(w; p) <= ubg -- with
    where the states (N+1, 3), inputs (N, 2) and slacks (N,) sit in the variable vector w, and
    for fatrop an ``equality`` flag per constraint row."""

    w: ca.SX
    p: ca.SX
    f: ca.SX
    g: ca.SX
    lbg: np.ndarray
    ubg: np.ndarray
    x_index: np.ndarray
    u_index: np.ndarray
    s_index: np.ndarray
    equality: tuple[bool, ...] | None = None

    @property
    def size(self) -> int:
        return int(self.w.shape[0])

    def nlp(self) -> dict[str, ca.SX]:
        return {"x": self.w, "p": self.p, "f": self.f, "g": self.g}


def build_nlp(ocp: OptimalControlProblem) -> NLPTranscription:
    """Multiple shooting: w = (x_0 .. x_N, u_0 .. u_{N-1}, s_1 .. s_N), s_k relaxing the
    obstacle rows of x_k; input limits (and u_0's rate window) are variable bounds."""
    c = ocp.config
    n, k = c.horizon, c.max_circles
    f = ocp.dynamics
    X = [ca.SX.sym(f"x{i}", 3) for i in range(n + 1)]
    U = [ca.SX.sym(f"u{i}", 2) for i in range(n)]
    S = ca.SX.sym("s", n)
    par = ocp.symbolic_parameters()
    cost = 0
    g, lbg, ubg = [X[0] - par.x0], [np.zeros(3)], [np.zeros(3)]
    for i in range(n):
        g.append(X[i + 1] - f(X[i], U[i]))
        lbg.append(np.zeros(3))
        ubg.append(np.zeros(3))
        prev = par.u_prev if i == 0 else U[i - 1]
        if i > 0:  # u_0's rate limit is a variable bound (see IpoptBackend._bounds)
            g.append(U[i] - prev)
            lbg.append(-ocp.du)
            ubg.append(ocp.du)
        cost = ocp.cost(i)(cost, X[i + 1], U[i], prev, par.ref[:, i], S[i])
        rows = ocp.obstacle_rows(X[i + 1][:2], par.obs_xy[:, i * k:(i + 1) * k], par.obs_r,
                                 par.dist_g[:, i], par.dist_b[i], S[i])
        g.append(rows)
        lbg.append(np.zeros(rows.shape[0]))
        ubg.append(np.full(rows.shape[0], np.inf))
    wv = ca.vertcat(*X, *U, S)
    nx = 3 * (n + 1)
    idx = np.arange(wv.shape[0])
    return NLPTranscription(wv, par.p, cost, ca.vertcat(*g), np.concatenate(lbg), np.concatenate(ubg),
                            idx[:nx].reshape(n + 1, 3), idx[nx:nx + 2 * n].reshape(n, 2), idx[nx + 2 * n:])


def build_nlp_stagewise(ocp: OptimalControlProblem) -> NLPTranscription:
    """The same OCP for fatrop: w = (z_0, v_0, z_1, v_1, ..., z_N) with z_k = (x_k, u_{k-1}) and
    v_k = (u_k, s_k); constraints ordered stage by stage, each involving one stage (plus z_{k+1}
    in the dynamics), with an ``equality`` flag per row for fatrop's structure detection. Every
    bound is a row; x_k's obstacle rows (1 <= k < N) are relaxed by its own stage's slack s_k."""
    c = ocp.config
    n, k = c.horizon, c.max_circles
    f = ocp.dynamics
    Z = [ca.SX.sym(f"z{i}", 5) for i in range(n + 1)]
    V = [ca.SX.sym(f"v{i}", 3) for i in range(n)]
    par = ocp.symbolic_parameters()
    s_hi = np.inf if c.soft_obstacles else 0.0
    g, lbg, ubg = [], [], []

    def add(expr, lo, hi):
        g.append(expr)
        lbg.append(np.broadcast_to(np.asarray(lo, float), (expr.shape[0],)))
        ubg.append(np.broadcast_to(np.asarray(hi, float), (expr.shape[0],)))

    cost = 0
    w = []
    for i in range(n + 1):
        w.append(Z[i])
        if i < n:
            w.append(V[i])
            u, slack = V[i][:2], V[i][2]
            add(Z[i + 1] - ca.vertcat(f(Z[i][:3], u), u), 0.0, 0.0)
        if i == 0:
            add(Z[0] - ca.vertcat(par.x0, par.u_prev), 0.0, 0.0)
        if i < n:
            # u_0's window is also bounded by the parameters lo0/hi0 through z_0 = (x0, u_prev)
            add(u - Z[i][3:5], -ocp.du, ocp.du)
            add(u, ocp.u_min, ocp.u_max)
            add(slack, 0.0, s_hi)
            cost = ocp.cost(i)(cost, Z[i + 1][:3], u, Z[i][3:5], par.ref[:, i], slack)
        if 1 <= i < n:
            add(ocp.obstacle_rows(Z[i][:2], par.obs_xy[:, (i - 1) * k:i * k], par.obs_r,
                                  par.dist_g[:, i - 1], par.dist_b[i - 1], slack), 0.0, np.inf)
    lbg_a, ubg_a = np.concatenate(lbg), np.concatenate(ubg)
    base = 8 * np.arange(n + 1)
    return NLPTranscription(ca.vertcat(*w), par.p, cost, ca.vertcat(*g), lbg_a, ubg_a,
                            base[:, None] + np.arange(3), base[:n, None] + 5 + np.arange(2), base[:n] + 7,
                            tuple(bool(e) for e in lbg_a == ubg_a))


# --------------------------------------------------------------------------- backends


@dataclass(frozen=True)
class MPCSolution:
    """What a backend returns: ``success``, the plan (``states_xytheta`` (N+1, 3) and
    ``commands`` (N, 2); a failed NLP still returns its last iterate, a failed QP None) and solver
    details for :attr:`ControlOutput.info` (status, iterations, max slack, solver time)."""

    success: bool
    states_xytheta: np.ndarray | None
    commands: np.ndarray | None
    info: Mapping[str, Any] = field(default_factory=dict)


@runtime_checkable
class MPCBackend(Protocol):
    """One solver for an :class:`OptimalControlProblem` (built once in the constructor, which
    takes the OCP). ``reset`` forgets what the solver carries between cycles."""

    def reset(self) -> None: ...

    def solve(self, problem: MPCProblem, warm_start: WarmStart) -> MPCSolution: ...


class _NLPBackend:
    """A ``casadi.nlpsol`` over a transcription; subclasses say how the bounds and the primal
    (and dual) guesses map onto their variable layout."""

    plugin = ""

    def __init__(self, ocp: OptimalControlProblem, nlp: NLPTranscription, options: dict[str, Any]):
        self.ocp, self.nlp = ocp, nlp
        self._solver = ca.nlpsol("mpc", self.plugin, nlp.nlp(), {**options, "print_time": False})
        self.reset()

    def reset(self) -> None:
        pass

    def _bounds(self, prob: MPCProblem) -> tuple[np.ndarray, np.ndarray]:
        return np.full(self.nlp.size, -np.inf), np.full(self.nlp.size, np.inf)

    def _primal_guess(self, prob: MPCProblem, warm: WarmStart) -> np.ndarray:
        w0 = np.zeros(self.nlp.size)
        w0[self.nlp.x_index] = warm.states_xytheta
        w0[self.nlp.u_index] = np.clip(warm.commands, self.ocp.u_min, self.ocp.u_max)
        return w0

    def _dual_guess(self) -> dict[str, np.ndarray]:
        return {}

    def _solved(self, sol: dict[str, Any]) -> None:
        """Called with the solution of a successful solve."""

    def solve(self, problem: MPCProblem, warm_start: WarmStart) -> MPCSolution:
        lbx, ubx = self._bounds(problem)
        args = {"x0": self._primal_guess(problem, warm_start), "p": problem.vector(self.ocp.layout),
                "lbx": lbx, "ubx": ubx, "lbg": self.nlp.lbg, "ubg": self.nlp.ubg, **self._dual_guess()}
        t0 = time.perf_counter()
        sol = self._solver(**args)
        solver_time_s = time.perf_counter() - t0
        stats = self._solver.stats()
        w = np.asarray(sol["x"]).ravel()
        status = str(stats.get("return_status", ""))
        ok = bool(stats.get("success", False)) or status in ("Solve_Succeeded",
                                                             "Solved_To_Acceptable_Level")
        info = {"solver_status": status, "iterations": int(stats.get("iter_count", -1)),
                "cost": float(sol["f"]), "max_slack_m": float(w[self.nlp.s_index].max()),
                "solver_time_s": solver_time_s}
        if ok:
            self._solved(sol)
        return MPCSolution(ok, w[self.nlp.x_index], w[self.nlp.u_index], info)


class IpoptBackend(_NLPBackend):
    """IPOPT on the multiple-shooting NLP, warm-started from the shifted plan and the previous
    solve's multipliers (with ``MPCConfig.ipopt_options``)."""

    plugin = "ipopt"

    def __init__(self, ocp: OptimalControlProblem):
        super().__init__(ocp, build_nlp(ocp), {"ipopt": dict(ocp.config.ipopt_options)})

    def reset(self) -> None:
        self._lam_x: np.ndarray | None = None
        self._lam_g: np.ndarray | None = None

    def _bounds(self, prob: MPCProblem) -> tuple[np.ndarray, np.ndarray]:
        lbx, ubx = super()._bounds(prob)
        ui, si = self.nlp.u_index, self.nlp.s_index
        lbx[ui] = self.ocp.u_min
        ubx[ui] = self.ocp.u_max
        lbx[ui[0]] = prob.u_lo0
        ubx[ui[0]] = prob.u_hi0
        lbx[si] = 0.0
        ubx[si] = np.inf if self.ocp.config.soft_obstacles else 0.0
        return lbx, ubx

    def _dual_guess(self) -> dict[str, np.ndarray]:
        return {} if self._lam_x is None else {"lam_x0": self._lam_x, "lam_g0": self._lam_g}

    def _solved(self, sol: dict[str, Any]) -> None:
        self._lam_x = np.asarray(sol["lam_x"]).ravel()
        self._lam_g = np.asarray(sol["lam_g"]).ravel()


class FatropBackend(_NLPBackend):
    """fatrop on the stage-wise NLP (every bound a row), primal warm start only."""

    plugin = "fatrop"

    def __init__(self, ocp: OptimalControlProblem):
        nlp = build_nlp_stagewise(ocp)
        super().__init__(ocp, nlp, {"structure_detection": "auto", "equality": list(nlp.equality),
                                    "fatrop": dict(ocp.config.fatrop_options)})

    def _primal_guess(self, prob: MPCProblem, warm: WarmStart) -> np.ndarray:
        w0 = super()._primal_guess(prob, warm)
        carried = np.vstack([prob.u_prev, w0[self.nlp.u_index]])  # z_k carries u_{k-1}
        w0[self.nlp.x_index[:, :1] + 3] = carried[:, :1]
        w0[self.nlp.x_index[:, :1] + 4] = carried[:, 1:2]
        return w0


class OsqpRtiBackend:
    """The real-time iteration: the OCP linearised along the warm start, one sparse QP solved by
    OSQP (``osqp_iterations`` > 1 re-linearises at the QP's solution, SQP-style). The QP's
    variables are the multiple-shooting ones, z = (x_0 .. x_N, u_0 .. u_{N-1}, s_1 .. s_N); its
    cost is :meth:`OptimalControlProblem.cost_hessian` / ``cost_gradient``; the circle rows
    become the half-planes tangent to the inflated circles at the warm start's positions."""

    def __init__(self, ocp: OptimalControlProblem):
        self.ocp = ocp
        c = ocp.config
        n, k = c.horizon, c.max_circles
        # batched Jacobians of the dynamics along the horizon
        xs, us = ca.SX.sym("x", 3), ca.SX.sym("u", 2)
        fx = ocp.dynamics(xs, us)
        self._lin = ca.Function("lin", [xs, us], [fx, ca.jacobian(fx, xs), ca.jacobian(fx, us)]).map(n)
        self._P = ocp.cost_hessian()
        # the fixed sparsity of the constraint matrix A; entries are listed row by row in the
        # order in which _constraints fills their values
        nx = 3 * (n + 1)
        self._nz = nx + 3 * n
        scol = lambda i: nx + 2 * n + i - 1  # noqa: E731  slack of stage i >= 1
        xcol = lambda i, j: 3 * i + j  # noqa: E731
        ucol = lambda i, j: nx + 2 * i + j  # noqa: E731
        rows, cols = [], []
        r = 0
        # x_0 = x0
        for j in range(3):
            rows.append(r + j); cols.append(xcol(0, j))  # noqa: E702
        r += 3
        # dynamics: x_{i+1} - A x_i - B u_i = c
        for i in range(n):
            for a in range(3):
                rows.append(r + a); cols.append(xcol(i + 1, a))  # noqa: E702
                for b in range(3):
                    rows.append(r + a); cols.append(xcol(i, b))  # noqa: E702
                for b in range(2):
                    rows.append(r + a); cols.append(ucol(i, b))  # noqa: E702
            r += 3
        # input box, then rate rows u_i - u_{i-1} (i >= 1)
        self._box_row0 = r
        for i in range(n):
            for j in range(2):
                rows.append(r); cols.append(ucol(i, j)); r += 1  # noqa: E702
        for i in range(1, n):
            for j in range(2):
                rows += [r, r]; cols += [ucol(i, j), ucol(i - 1, j)]; r += 1  # noqa: E702
        # obstacles: one half-plane per stage and circle slot, one per stage for the field, each
        # relaxed by the stage's slack; then the slack bounds
        for i in range(1, n + 1):
            for _j in range(k + 1):
                rows += [r, r, r]; cols += [xcol(i, 0), xcol(i, 1), scol(i)]; r += 1  # noqa: E702
        for i in range(1, n + 1):
            rows.append(r); cols.append(scol(i)); r += 1  # noqa: E702
        self._m = r
        rows_a, cols_a = np.asarray(rows), np.asarray(cols)
        order = np.lexsort((rows_a, cols_a))
        self._A_order = order
        indptr = np.concatenate([[0], np.cumsum(np.bincount(cols_a, minlength=self._nz))])
        self._A_indices, self._A_indptr = rows_a[order], indptr
        self.reset()

    def reset(self) -> None:
        # OSQP keeps duals and its adapted step size between solves; a fresh setup (a few ms,
        # once per episode or after a failure) makes a reset controller deterministic
        self._qp: osqp.OSQP | None = None

    def _constraints(self, prob: MPCProblem, Xl: np.ndarray, Ul: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Values of A (in CSC order) and the bounds lo <= A z <= hi, linearised at (Xl, Ul)."""
        ocp = self.ocp
        n, k = ocp.horizon, ocp.config.max_circles
        fx, A, B = self._lin(Xl[:-1].T, Ul.T)
        fx = np.asarray(fx).T  # (N, 3)
        A = np.asarray(A).reshape(3, n, 3).transpose(1, 0, 2)  # (N, 3, 3) from the 3 x 3N map
        B = np.asarray(B).reshape(3, n, 2).transpose(1, 0, 2)
        cvec = fx - np.einsum("nij,nj->ni", A, Xl[:-1]) - np.einsum("nij,nj->ni", B, Ul)
        data = [np.ones(3)]
        blk = np.concatenate([np.ones((n, 3, 1)), -A, -B], axis=2)  # per row: [1, -A_row, -B_row]
        data.append(blk.reshape(-1))
        data.append(np.ones(2 * n))
        data.append(np.tile([1.0, -1.0], 2 * (n - 1)))
        # circle half-planes n.(p - o) >= R linearised at the previous plan's positions
        p_lin = Xl[1:, :2]
        diff = p_lin[:, None, :] - prob.obs_xy  # (N, K, 2)
        dist = np.linalg.norm(diff, axis=2, keepdims=True)
        normal = diff / np.maximum(dist, 1e-9)
        lo_c = np.einsum("nkj,nkj->nk", normal, prob.obs_xy) + prob.obs_r
        lo_c = np.where(prob.obs_r[None, :] > 0, lo_c, -np.inf)
        obs_coef = np.concatenate([normal, prob.dist_g[:, None, :]], axis=1)  # (N, K+1, 2)
        data.append(np.concatenate([obs_coef, np.ones((n, k + 1, 1))], axis=2).reshape(-1))
        data.append(np.ones(n))
        Ax = np.concatenate(data)[self._A_order]
        lo = np.concatenate([prob.x0, cvec.ravel(), np.tile(ocp.u_min, n),
                             np.tile(-ocp.du, n - 1),
                             np.concatenate([lo_c, prob.dist_b[:, None]], axis=1).ravel(),
                             np.zeros(n)])
        hi = np.concatenate([prob.x0, cvec.ravel(), np.tile(ocp.u_max, n),
                             np.tile(ocp.du, n - 1), np.full(n * (k + 1), np.inf),
                             np.full(n, np.inf if ocp.config.soft_obstacles else 0.0)])
        lo[self._box_row0:self._box_row0 + 2] = prob.u_lo0
        hi[self._box_row0:self._box_row0 + 2] = prob.u_hi0
        return Ax, lo, hi

    def solve(self, problem: MPCProblem, warm_start: WarmStart) -> MPCSolution:
        c = self.ocp.config
        n = c.horizon
        nx = 3 * (n + 1)
        Xl, Ul = warm_start.states_xytheta, warm_start.commands
        q = self.ocp.cost_gradient(problem)
        info: dict[str, Any] = {}
        for _ in range(max(1, c.osqp_iterations)):
            Ax, lo, hi = self._constraints(problem, Xl, Ul)
            if self._qp is None:
                A = sp.csc_matrix((Ax, self._A_indices, self._A_indptr), shape=(self._m, self._nz))
                self._qp = osqp.OSQP()
                self._qp.setup(self._P, q, A, lo, hi, verbose=False, polishing=False, warm_starting=True,
                               eps_abs=c.osqp_eps, eps_rel=c.osqp_eps, max_iter=4000,
                               check_termination=10, adaptive_rho=True)
            else:
                self._qp.update(q=q, l=lo, u=hi, Ax=Ax)
            self._qp.warm_start(x=np.concatenate([Xl.ravel(), Ul.ravel(), np.zeros(n)]))
            t0 = time.perf_counter()
            res = self._qp.solve(raise_error=False)
            info = {"solver_status": res.info.status, "iterations": int(res.info.iter),
                    "solver_time_s": time.perf_counter() - t0}
            if res.info.status_val not in _OSQP_OK:
                return MPCSolution(False, None, None, info)
            z = res.x
            Xl = z[:nx].reshape(-1, 3)
            Ul = z[nx:nx + 2 * n].reshape(-1, 2)
            info["max_slack_m"] = float(z[nx + 2 * n:].max())
        return MPCSolution(True, Xl, Ul, info)


#: solver name (``MPCConfig.solver``) -> backend class, constructed with the OCP
BACKENDS: dict[str, Callable[[OptimalControlProblem], MPCBackend]] = {
    "ipopt": IpoptBackend, "osqp": OsqpRtiBackend, "fatrop": FatropBackend}


# --------------------------------------------------------------------------- the controller


class MPCController:
    """Warm-started MPC: the OCP and its backend built once (engine state: the backend's solver
    and the previous plan)."""

    def __init__(self, config: MPCConfig = MPCConfig()):
        self.config = config
        self.name = "mpc" if config.solver == "ipopt" else f"mpc_{config.solver}"
        self.ocp = OptimalControlProblem.of(config)
        self.backend: MPCBackend = BACKENDS[config.solver](self.ocp)
        self._rollout = self.ocp.dynamics.mapaccum(config.horizon)
        self.reset()

    def reset(self) -> None:
        self._X: np.ndarray | None = None  # (N+1, 3) previous plan
        self._U = np.zeros((self.config.horizon, 2))
        self.backend.reset()

    def warm_start(self, x0: np.ndarray, u_prev: np.ndarray) -> WarmStart:
        """The previous plan's inputs shifted by one stage (the last repeated; the last command
        held before any plan) rolled out from ``x0``."""
        n = self.config.horizon
        if self._X is None:
            U = np.tile(np.clip(u_prev, self.ocp.u_min, self.ocp.u_max), (n, 1))
        else:
            U = np.vstack([self._U[1:], self._U[-1:]])
        X = np.zeros((n + 1, 3))
        X[0] = x0
        X[1:] = np.asarray(self._rollout(x0, U.T)).T
        X.setflags(write=False)
        U.setflags(write=False)
        return WarmStart(X, U)

    def problem(self, state: RobotState, reference: Reference, world: LocalWorld) -> MPCProblem:
        """The numbers of this cycle's OCP (also used by the benchmark's reference build)."""
        return self.ocp.instantiate(state, reference, world, self.warm_start(state.world_xytheta_body, state.command))

    def compute(self, state: RobotState, reference: Reference, world: LocalWorld) -> ControlOutput:
        if not state.finite:
            self.reset()
            return non_finite_brake()
        t0 = time.perf_counter()
        c = self.config
        if np.linalg.norm(reference.goal_xy_m - state.world_xytheta_body[:2]) <= c.goal_tolerance_m:
            cmd = brake_command(state.command, *c.du_max_per_s, c.dt_s)
            self.reset()
            return ControlOutput(cmd, ControlStatus.GOAL_REACHED, solve_time_s=time.perf_counter() - t0)
        warm = self.warm_start(state.world_xytheta_body, state.command)
        prob = self.ocp.instantiate(state, reference, world, warm)
        try:
            sol = self.backend.solve(prob, warm)
        except (RuntimeError, ValueError, osqp.OSQPException) as exc:  # never raise in the loop
            sol = MPCSolution(False, None, None, {"solver_status": f"exception: {exc}"})
        X, U = sol.states_xytheta, sol.commands
        if not sol.success or X is None or not np.all(np.isfinite(U)):
            self.reset()
            cmd = brake_command(state.command, *c.du_max_per_s, c.dt_s)
            return ControlOutput(cmd, ControlStatus.FALLBACK_BRAKE, predicted_xytheta=X,
                                 predicted_commands=U, solve_time_s=time.perf_counter() - t0,
                                 info=dict(sol.info))
        self._X, self._U = X, U
        cmd = np.clip(U[0], prob.u_lo0, prob.u_hi0)  # exact projection onto limits and rates
        return ControlOutput(cmd, ControlStatus.OK, predicted_xytheta=X, predicted_commands=U,
                             solve_time_s=time.perf_counter() - t0,
                             info={**sol.info, "reference_xytheta": prob.ref})
