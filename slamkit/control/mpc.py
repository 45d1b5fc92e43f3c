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

The NLP is built ONCE as a parametric ``casadi.nlpsol`` (initial state, last command, reference,
obstacle positions and the distance-field linearisation are parameters), so a control cycle is
only a solve, warm-started from the previous solution shifted by one stage together with its
multipliers. Solvers:

* ``ipopt`` (default): the interior-point NLP solver with options chosen for warm-started MPC
  (see ``MPCConfig.ipopt_options``).
* ``osqp`` (the fast path): one real-time-iteration step (Diehl et al., "Real-time optimization
  and nonlinear model predictive control of processes governed by DAEs", J. Proc. Control 12, 2002):
  dynamics and obstacle constraints are linearised around the shifted previous solution and the
  resulting sparse QP is solved by OSQP (Stellato et al., Math. Prog. Comp. 12, 2020), whose matrix
  pattern is fixed at construction so a cycle only updates numbers.
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
from typing import Any

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


def discrete_dynamics(config: MPCConfig) -> ca.Function:
    """x+ = f(x, u) with the midpoint rule (see the module docstring); a casadi Function (3,2)->3."""
    x = ca.SX.sym("x", 3)
    u = ca.SX.sym("u", 2)
    dt = config.dt_s
    w = u[1] if config.model == "unicycle" else u[0] * ca.tan(u[1]) / config.wheelbase_m
    phi = x[2] + 0.5 * w * dt
    xn = ca.vertcat(x[0] + u[0] * dt * ca.cos(phi), x[1] + u[0] * dt * ca.sin(phi), x[2] + w * dt)
    return ca.Function("f", [x, u], [xn], ["x", "u"], ["x_next"])


class _Layout:
    """Parameter vector layout shared by the NLP and the Opti reference."""

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


@dataclass
class _Problem:
    """Numeric data of one cycle (shared by every solver)."""

    x0: np.ndarray
    u_prev: np.ndarray
    ref: np.ndarray          # (N, 3) for stages 1..N
    obs_xy: np.ndarray       # (N, K, 2) predicted centres for stages 1..N
    obs_r: np.ndarray        # (K,) radii inflated by robot radius + margin
    dist_g: np.ndarray       # (N, 2)
    dist_b: np.ndarray       # (N,)
    u_lo0: np.ndarray        # (2,) bounds of u_0 from limits and rate
    u_hi0: np.ndarray

    def vector(self, layout: _Layout) -> np.ndarray:
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


def build_nlp(config: MPCConfig) -> dict[str, Any]:
    """The parametric NLP {x, p, f, g} with its constraint bounds and the index maps from the
    flat variable vector w = (x_0 .. x_N, u_0 .. u_{N-1}, s_1 .. s_N) to states, inputs, slacks."""
    n, k = config.horizon, config.max_circles
    lay = _Layout(n, k)
    f = discrete_dynamics(config)
    X = [ca.SX.sym(f"x{i}", 3) for i in range(n + 1)]
    U = [ca.SX.sym(f"u{i}", 2) for i in range(n)]
    S = ca.SX.sym("s", n)
    P = ca.SX.sym("p", lay.size)
    sl = lay.slices
    x0 = P[sl["x0"]]
    u_prev = P[sl["u_prev"]]
    ref = ca.reshape(P[sl["ref"]], 3, n)
    obs = ca.reshape(P[sl["obs_xy"]], 2, n * k)
    obs_r = P[sl["obs_r"]]
    dist_g = ca.reshape(P[sl["dist_g"]], 2, n)
    dist_b = P[sl["dist_b"]]
    du = np.asarray(config.du_max_per_s) * config.dt_s
    r_u, r_du = np.asarray(config.r_u), np.asarray(config.r_du)

    cost = 0
    g, lbg, ubg = [X[0] - x0], [np.zeros(3)], [np.zeros(3)]
    for i in range(n):
        g.append(X[i + 1] - f(X[i], U[i]))
        lbg.append(np.zeros(3))
        ubg.append(np.zeros(3))
        prev = u_prev if i == 0 else U[i - 1]
        if i > 0:  # u_0's rate limit is a variable bound (see MPCController._bounds)
            g.append(U[i] - prev)
            lbg.append(-du)
            ubg.append(du)
        cost += ca.sumsqr(np.sqrt(r_u) * U[i]) + ca.sumsqr(np.sqrt(r_du) * (U[i] - prev))
        xk = X[i + 1]
        e = xk - ref[:, i]
        last = i == n - 1
        cost += (config.q_xy_terminal if last else config.q_xy) * ca.sumsqr(e[:2])
        cost += (config.q_theta_terminal if last else config.q_theta) * e[2] ** 2
        # exact L1 penalty (plus a small quadratic for a unique minimiser) on the stage's slack
        cost += config.slack_weight * S[i] + config.slack_weight * S[i] ** 2
        for j in range(k):
            d = xk[:2] - obs[:, i * k + j]
            # distance (not squared) so the slack is in metres like the distance-field row
            g.append(ca.sqrt(ca.sumsqr(d) + 1e-9) - obs_r[j] + S[i])
            lbg.append(np.zeros(1))
            ubg.append(np.full(1, np.inf))
        if config.use_distance_field:
            g.append(ca.dot(dist_g[:, i], xk[:2]) - dist_b[i] + S[i])
            lbg.append(np.zeros(1))
            ubg.append(np.full(1, np.inf))
    wv = ca.vertcat(*X, *U, S)
    nx = 3 * (n + 1)
    idx = np.arange(wv.shape[0])
    return {"nlp": {"x": wv, "p": P, "f": cost, "g": ca.vertcat(*g)},
            "lbg": np.concatenate(lbg), "ubg": np.concatenate(ubg),
            "x_index": idx[:nx].reshape(n + 1, 3), "u_index": idx[nx:nx + 2 * n].reshape(n, 2),
            "s_index": idx[nx + 2 * n:], "layout": lay}


def build_nlp_stagewise(config: MPCConfig) -> dict[str, Any]:
    """The same OCP for fatrop: w = (z_0, v_0, z_1, v_1, ..., z_N) with z_k = (x_k, u_{k-1}) and
    v_k = (u_k, s_k); constraints ordered stage by stage, each involving one stage (plus z_{k+1}
    in the dynamics), with an ``equality`` flag per row for fatrop's structure detection."""
    n, k = config.horizon, config.max_circles
    lay = _Layout(n, k)
    f = discrete_dynamics(config)
    Z = [ca.SX.sym(f"z{i}", 5) for i in range(n + 1)]
    V = [ca.SX.sym(f"v{i}", 3) for i in range(n)]
    P = ca.SX.sym("p", lay.size)
    sl = lay.slices
    ref = ca.reshape(P[sl["ref"]], 3, n)
    obs = ca.reshape(P[sl["obs_xy"]], 2, n * k)
    obs_r = P[sl["obs_r"]]
    dist_g = ca.reshape(P[sl["dist_g"]], 2, n)
    dist_b = P[sl["dist_b"]]
    du = np.asarray(config.du_max_per_s) * config.dt_s
    r_u, r_du = np.asarray(config.r_u), np.asarray(config.r_du)
    s_hi = np.inf if config.soft_obstacles else 0.0
    g, lbg, ubg = [], [], []

    def add(expr, lo, hi):
        g.append(expr)
        lbg.append(np.atleast_1d(np.asarray(lo, float)))
        ubg.append(np.atleast_1d(np.asarray(hi, float)))

    cost = 0
    w = []
    for i in range(n + 1):
        w.append(Z[i])
        if i < n:
            w.append(V[i])
            u, slack = V[i][:2], V[i][2]
            add(Z[i + 1] - ca.vertcat(f(Z[i][:3], u), u), np.zeros(5), np.zeros(5))
        if i == 0:
            add(Z[0] - ca.vertcat(P[sl["x0"]], P[sl["u_prev"]]), np.zeros(5), np.zeros(5))
        if i < n:
            # u_0's window is also bounded by the parameters lo0/hi0 through z_0 = (x0, u_prev)
            add(u - Z[i][3:5], -du, du)
            add(u, np.asarray(config.u_min), np.asarray(config.u_max))
            add(slack, 0.0, s_hi)
            cost += ca.sumsqr(np.sqrt(r_u) * u) + ca.sumsqr(np.sqrt(r_du) * (u - Z[i][3:5]))
            cost += config.slack_weight * slack + config.slack_weight * slack ** 2
        if i >= 1:
            xk = Z[i][:3]
            if i < n:
                for j in range(k):
                    d = xk[:2] - obs[:, (i - 1) * k + j]
                    add(ca.sqrt(ca.sumsqr(d) + 1e-9) - obs_r[j] + slack, 0.0, np.inf)
                if config.use_distance_field:
                    add(ca.dot(dist_g[:, i - 1], xk[:2]) - dist_b[i - 1] + slack, 0.0, np.inf)
            e = xk - ref[:, i - 1]
            last = i == n
            cost += (config.q_xy_terminal if last else config.q_xy) * ca.sumsqr(e[:2])
            cost += (config.q_theta_terminal if last else config.q_theta) * e[2] ** 2
    lbg_a, ubg_a = np.concatenate(lbg), np.concatenate(ubg)
    base = 8 * np.arange(n + 1)
    return {"nlp": {"x": ca.vertcat(*w), "p": P, "f": cost, "g": ca.vertcat(*g)},
            "lbg": lbg_a, "ubg": ubg_a, "equality": [bool(e) for e in lbg_a == ubg_a],
            "x_index": base[:, None] + np.arange(3), "u_index": base[:n, None] + 5 + np.arange(2),
            "s_index": base[:n] + 7, "layout": lay}


class MPCController:
    """Warm-started MPC; holds the built solver and the previous solution (engine state)."""

    def __init__(self, config: MPCConfig = MPCConfig()):
        self.config = config
        self.name = "mpc" if config.solver == "ipopt" else f"mpc_{config.solver}"
        self._f = discrete_dynamics(config)
        n = config.horizon
        self._rollout = self._f.mapaccum(n)
        self._du = np.asarray(config.du_max_per_s) * config.dt_s
        self._umin = np.asarray(config.u_min, dtype=float)
        self._umax = np.asarray(config.u_max, dtype=float)
        if config.solver == "ipopt":
            built = build_nlp(config)
            self._layout = built["layout"]
            self._lbg, self._ubg = built["lbg"], built["ubg"]
            self._xi, self._ui, self._si = built["x_index"], built["u_index"], built["s_index"]
            self._nw = built["nlp"]["x"].shape[0]
            opts = {"ipopt": dict(config.ipopt_options), "print_time": False}
            self._solver = ca.nlpsol("mpc", "ipopt", built["nlp"], opts)
        elif config.solver == "fatrop":
            built = build_nlp_stagewise(config)
            self._layout = built["layout"]
            self._lbg, self._ubg = built["lbg"], built["ubg"]
            self._xi, self._ui, self._si = built["x_index"], built["u_index"], built["s_index"]
            self._nw = built["nlp"]["x"].shape[0]
            opts = {"structure_detection": "auto", "equality": built["equality"], "print_time": False,
                    "fatrop": dict(config.fatrop_options)}
            self._solver = ca.nlpsol("mpc", "fatrop", built["nlp"], opts)
        else:
            self._build_qp()
        # batched Jacobians of the dynamics for the OSQP linearisation
        xs, us = ca.SX.sym("x", 3), ca.SX.sym("u", 2)
        fx = self._f(xs, us)
        self._lin = ca.Function("lin", [xs, us], [fx, ca.jacobian(fx, xs), ca.jacobian(fx, us)]).map(n)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        n = self.config.horizon
        self._X: np.ndarray | None = None  # (N+1, 3) previous solution
        self._U = np.zeros((n, 2))
        self._lam_x: np.ndarray | None = None
        self._lam_g: np.ndarray | None = None
        # OSQP keeps duals and its adapted step size between solves; a fresh setup (a few ms,
        # once per episode or after a failure) makes a reset controller deterministic
        if self.config.solver == "osqp":
            self._qp = None

    # ------------------------------------------------------------------ problem data
    def problem(self, state: RobotState, reference: Reference, world: LocalWorld) -> _Problem:
        """The numbers of this cycle's OCP (also used by the benchmark's reference build)."""
        c = self.config
        n, k = c.horizon, c.max_circles
        x0 = state.pose_xytheta.copy()
        u_prev = state.command.copy()
        spacing = max(reference.speed_mps, 1e-3) * c.dt_s
        ref = path_reference(reference.path_xy_m, x0[:2], spacing, n, x0[2])
        # the previous plan (shifted) is where the constraints are linearised and what warm-starts
        guess = self._initial_guess(x0, u_prev)
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
            p_lin = guess[0][1:, :2]
            d, grad = world.distance.query(p_lin)
            norm = np.linalg.norm(grad, axis=1, keepdims=True)
            g_unit = np.where(norm > 1e-9, grad / np.maximum(norm, 1e-9), 0.0)
            # only constrain stages within reach of an obstacle; elsewhere the row stays inactive
            active = (norm[:, 0] > 1e-9) & (d < inflate + 1.0)
            dist_g = np.where(active[:, None], g_unit, 0.0)
            dist_b = np.where(active, inflate - d + np.einsum("ij,ij->i", g_unit, p_lin), -1.0)
        lo0 = np.clip(u_prev - self._du, self._umin, self._umax)
        hi0 = np.clip(u_prev + self._du, self._umin, self._umax)
        return _Problem(x0, u_prev, ref, obs_xy, obs_r, dist_g, dist_b, lo0, hi0)

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

    def _initial_guess(self, x0: np.ndarray, u_prev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = self.config.horizon
        if self._X is None:
            U = np.tile(np.clip(u_prev, self._umin, self._umax), (n, 1))
        else:
            U = np.vstack([self._U[1:], self._U[-1:]])
        # roll the shifted inputs out from the measured state: a dynamically consistent guess
        X = np.zeros((n + 1, 3))
        X[0] = x0
        Xs = np.asarray(self._rollout(x0, U.T)).T
        X[1:] = Xs
        return X, U

    # ------------------------------------------------------------------ control
    def compute(self, state: RobotState, reference: Reference, world: LocalWorld) -> ControlOutput:
        if not state.finite:
            self.reset()
            return non_finite_brake()
        t0 = time.perf_counter()
        c = self.config
        if np.linalg.norm(reference.goal_xy_m - state.pose_xytheta[:2]) <= c.goal_tolerance_m:
            cmd = brake_command(state.command, *c.du_max_per_s, c.dt_s)
            self.reset()
            return ControlOutput(cmd, ControlStatus.GOAL_REACHED, solve_time_s=time.perf_counter() - t0)
        prob = self.problem(state, reference, world)
        try:
            if c.solver == "osqp":
                ok, X, U, info = self._solve_qp(prob)
            else:
                ok, X, U, info = self._solve_nlp(prob)
        except (RuntimeError, ValueError, osqp.OSQPException) as exc:  # never raise in the loop
            ok, X, U, info = False, None, None, {"solver_status": f"exception: {exc}"}
        if not ok or X is None or not np.all(np.isfinite(U)):
            self.reset()
            cmd = brake_command(state.command, *c.du_max_per_s, c.dt_s)
            return ControlOutput(cmd, ControlStatus.FALLBACK_BRAKE, predicted_xytheta=X,
                                 predicted_commands=U, solve_time_s=time.perf_counter() - t0,
                                 info=info)
        self._X, self._U = X, U
        cmd = np.clip(U[0], prob.u_lo0, prob.u_hi0)  # exact projection onto limits and rates
        return ControlOutput(cmd, ControlStatus.OK, predicted_xytheta=X, predicted_commands=U,
                             solve_time_s=time.perf_counter() - t0,
                             info={**info, "reference_xytheta": prob.ref})

    # ------------------------------------------------------------------ NLP (ipopt)
    def _bounds(self, prob: _Problem) -> tuple[np.ndarray, np.ndarray]:
        lbx = np.full(self._nw, -np.inf)
        ubx = np.full(self._nw, np.inf)
        if self.config.solver == "fatrop":  # every bound is a constraint row there
            return lbx, ubx
        lbx[self._ui] = self._umin
        ubx[self._ui] = self._umax
        lbx[self._ui[0]] = prob.u_lo0
        ubx[self._ui[0]] = prob.u_hi0
        lbx[self._si] = 0.0
        ubx[self._si] = np.inf if self.config.soft_obstacles else 0.0
        return lbx, ubx

    def _solve_nlp(self, prob: _Problem) -> tuple[bool, np.ndarray, np.ndarray, dict]:
        X0, U0 = self._initial_guess(prob.x0, prob.u_prev)
        w0 = np.zeros(self._nw)
        w0[self._xi] = X0
        w0[self._ui] = np.clip(U0, self._umin, self._umax)
        if self.config.solver == "fatrop":  # the carried last input of every stage
            w0[self._xi[:, :1] + 3] = np.vstack([prob.u_prev, w0[self._ui]])[:, :1]
            w0[self._xi[:, :1] + 4] = np.vstack([prob.u_prev, w0[self._ui]])[:, 1:2]
        lbx, ubx = self._bounds(prob)
        args = {"x0": w0, "p": prob.vector(self._layout), "lbx": lbx, "ubx": ubx,
                "lbg": self._lbg, "ubg": self._ubg}
        if self._lam_x is not None and self.config.solver == "ipopt":
            args["lam_x0"], args["lam_g0"] = self._lam_x, self._lam_g
        t0 = time.perf_counter()
        sol = self._solver(**args)
        solver_time_s = time.perf_counter() - t0
        stats = self._solver.stats()
        w = np.asarray(sol["x"]).ravel()
        status = str(stats.get("return_status", ""))
        ok = bool(stats.get("success", False)) or status in ("Solve_Succeeded",
                                                             "Solved_To_Acceptable_Level")
        info = {"solver_status": status, "iterations": int(stats.get("iter_count", -1)),
                "cost": float(sol["f"]), "max_slack_m": float(w[self._si].max()),
                "solver_time_s": solver_time_s}
        if ok:
            self._lam_x = np.asarray(sol["lam_x"]).ravel()
            self._lam_g = np.asarray(sol["lam_g"]).ravel()
        return ok, w[self._xi], w[self._ui], info

    # ------------------------------------------------------------------ QP fast path (osqp)
    def _build_qp(self) -> None:
        """Fixed sparsity of the linearised OCP; z = (x_0 .. x_N, u_0 .. u_{N-1}, s_1 .. s_N)."""
        c = self.config
        n, k = c.horizon, c.max_circles
        nx = 3 * (n + 1)
        self._nz = nx + 3 * n
        scol = lambda i: nx + 2 * n + i - 1  # noqa: E731  slack of stage i >= 1
        xcol = lambda i, j: 3 * i + j  # noqa: E731
        ucol = lambda i, j: nx + 2 * i + j  # noqa: E731
        # cost: diagonal state weights + R + R_d (tridiagonal in u)
        wx = np.zeros(nx)
        for i in range(1, n + 1):
            last = i == n
            wx[3 * i:3 * i + 2] = c.q_xy_terminal if last else c.q_xy
            wx[3 * i + 2] = c.q_theta_terminal if last else c.q_theta
        r_u, r_du = np.asarray(c.r_u), np.asarray(c.r_du)
        D = sp.eye(2 * n, format="csc") - sp.eye(2 * n, k=-2, format="csc")  # u_k - u_{k-1}
        Pu = sp.diags(np.tile(r_u, n)) + D.T @ sp.diags(np.tile(r_du, n)) @ D
        Ps = sp.diags(np.full(n, c.slack_weight))
        self._P = sp.triu(2.0 * sp.block_diag([sp.diags(wx), Pu, Ps]), format="csc")
        self._wx, self._r_du = wx, r_du
        rows, cols = [], []
        r = 0
        # x_0 = x0
        for j in range(3):
            rows.append(r + j); cols.append(xcol(0, j))  # noqa: E702
        r += 3
        # dynamics: x_{i+1} - A x_i - B u_i = c; entries in a fixed order, filled in _fill_A
        self._dyn_row0 = r
        for i in range(n):
            for a in range(3):
                rows.append(r + a); cols.append(xcol(i + 1, a))  # noqa: E702
                for b in range(3):
                    rows.append(r + a); cols.append(xcol(i, b))  # noqa: E702
                for b in range(2):
                    rows.append(r + a); cols.append(ucol(i, b))  # noqa: E702
            r += 3
        self._n_dyn_entries = n * 3 * (1 + 3 + 2)
        # input box, then rate rows u_i - u_{i-1} (i >= 1)
        self._box_row0 = r
        for i in range(n):
            for j in range(2):
                rows.append(r); cols.append(ucol(i, j)); r += 1  # noqa: E702
        self._rate_row0 = r
        for i in range(1, n):
            for j in range(2):
                rows += [r, r]; cols += [ucol(i, j), ucol(i - 1, j)]; r += 1  # noqa: E702
        # obstacles: one half-plane per stage and circle slot, one per stage for the field, each
        # relaxed by the stage's slack; then the slack bounds
        self._obs_row0 = r
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
        self._qp = None

    def _fill_qp(self, prob: _Problem, Xl: np.ndarray, Ul: np.ndarray):
        c = self.config
        n, k = c.horizon, c.max_circles
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
        lo = np.concatenate([prob.x0, cvec.ravel(), np.tile(self._umin, n),
                             np.tile(-self._du, n - 1),
                             np.concatenate([lo_c, prob.dist_b[:, None]], axis=1).ravel(),
                             np.zeros(n)])
        hi = np.concatenate([prob.x0, cvec.ravel(), np.tile(self._umax, n),
                             np.tile(self._du, n - 1), np.full(n * (k + 1), np.inf),
                             np.full(n, np.inf if c.soft_obstacles else 0.0)])
        lo[self._box_row0:self._box_row0 + 2] = prob.u_lo0
        hi[self._box_row0:self._box_row0 + 2] = prob.u_hi0
        # linear cost: -2 W ref for states, -2 R_d u_prev for u_0
        q = np.zeros(self._nz)
        ref_full = np.vstack([prob.x0, prob.ref]).ravel()
        q[:3 * (n + 1)] = -2.0 * self._wx * ref_full
        q[3 * (n + 1):3 * (n + 1) + 2] = -2.0 * self._r_du * prob.u_prev
        q[3 * (n + 1) + 2 * n:] = c.slack_weight
        return Ax, q, lo, hi

    def _solve_qp(self, prob: _Problem) -> tuple[bool, np.ndarray, np.ndarray, dict]:
        c = self.config
        Xl, Ul = self._initial_guess(prob.x0, prob.u_prev)
        info: dict[str, Any] = {}
        for _ in range(max(1, c.osqp_iterations)):
            Ax, q, lo, hi = self._fill_qp(prob, Xl, Ul)
            if self._qp is None:
                A = sp.csc_matrix((Ax, self._A_indices, self._A_indptr), shape=(self._m, self._nz))
                self._qp = osqp.OSQP()
                self._qp.setup(self._P, q, A, lo, hi, verbose=False, polishing=False, warm_starting=True,
                               eps_abs=c.osqp_eps, eps_rel=c.osqp_eps, max_iter=4000,
                               check_termination=10, adaptive_rho=True)
            else:
                self._qp.update(q=q, l=lo, u=hi, Ax=Ax)
            z0 = np.concatenate([Xl.ravel(), Ul.ravel(), np.zeros(c.horizon)])
            self._qp.warm_start(x=z0)
            t0 = time.perf_counter()
            res = self._qp.solve(raise_error=False)
            info = {"solver_status": res.info.status, "iterations": int(res.info.iter),
                    "solver_time_s": time.perf_counter() - t0}
            if res.info.status_val not in _OSQP_OK:
                return False, None, None, info
            z = res.x
            Xl = z[:3 * (c.horizon + 1)].reshape(-1, 3)
            Ul = z[3 * (c.horizon + 1):3 * (c.horizon + 1) + 2 * c.horizon].reshape(-1, 2)
            info["max_slack_m"] = float(z[3 * (c.horizon + 1) + 2 * c.horizon:].max())
        return True, Xl, Ul, info
