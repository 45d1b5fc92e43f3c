"""The reference MPC for ``slamkit bench control``: the same optimal control problem as
:mod:`slamkit.control.mpc` written the way the CasADi documentation teaches it -- a
``casadi.Opti`` stack with parameters, default IPOPT options (only the console output silenced),
no warm start of primal or dual variables. Benchmarks time it against the tuned build in the same
run, so the reported ratios say what the tuning (warm start, barrier strategy, the QP fast path)
buys on identical problems.

It writes the cost and constraints out itself instead of calling the OCP's CasADi functions, on
purpose: ``tests/control/test_mpc.py`` uses it as an independent oracle for the tuned build (same
first input to 1e-3), and its timing stays that of the textbook formulation.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from slamkit.control.mpc import MPCConfig, MPCProblem, discrete_dynamics


class OptiMPC:
    def __init__(self, config: MPCConfig = MPCConfig()):
        c = self.config = config
        n, k = c.horizon, c.max_circles
        f = discrete_dynamics(c)
        opti = self.opti = ca.Opti()
        X = self.X = opti.variable(3, n + 1)
        U = self.U = opti.variable(2, n)
        S = opti.variable(n)
        self.p = {"x0": opti.parameter(3), "u_prev": opti.parameter(2), "ref": opti.parameter(3, n),
                  "obs_xy": opti.parameter(2, n * k), "obs_r": opti.parameter(k),
                  "dist_g": opti.parameter(2, n), "dist_b": opti.parameter(n),
                  "lo0": opti.parameter(2), "hi0": opti.parameter(2)}
        p = self.p
        du = np.asarray(c.du_max_per_s) * c.dt_s
        r_u, r_du = np.asarray(c.r_u), np.asarray(c.r_du)
        cost = 0
        opti.subject_to(X[:, 0] == p["x0"])
        for i in range(n):
            opti.subject_to(X[:, i + 1] == f(X[:, i], U[:, i]))
            prev = p["u_prev"] if i == 0 else U[:, i - 1]
            if i > 0:
                opti.subject_to(opti.bounded(-du, U[:, i] - prev, du))
            opti.subject_to(opti.bounded(np.asarray(c.u_min), U[:, i], np.asarray(c.u_max)))
            cost += ca.sumsqr(np.sqrt(r_u) * U[:, i]) + ca.sumsqr(np.sqrt(r_du) * (U[:, i] - prev))
            e = X[:, i + 1] - p["ref"][:, i]
            last = i == n - 1
            cost += (c.q_xy_terminal if last else c.q_xy) * ca.sumsqr(e[:2])
            cost += (c.q_theta_terminal if last else c.q_theta) * e[2] ** 2
            cost += c.slack_weight * S[i] + c.slack_weight * S[i] ** 2
            for j in range(k):
                d = X[:2, i + 1] - p["obs_xy"][:, i * k + j]
                opti.subject_to(ca.sqrt(ca.sumsqr(d) + 1e-9) - p["obs_r"][j] + S[i] >= 0)
            if c.use_distance_field:
                opti.subject_to(ca.dot(p["dist_g"][:, i], X[:2, i + 1]) - p["dist_b"][i] + S[i] >= 0)
        opti.subject_to(opti.bounded(p["lo0"], U[:, 0], p["hi0"]))
        opti.subject_to(S >= 0 if c.soft_obstacles else S == 0)
        opti.minimize(cost)
        opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes"})

    def solve(self, prob: MPCProblem) -> tuple[bool, np.ndarray, float]:
        """(success, u_0, wall time of ``opti.solve`` in seconds)."""
        c = self.config
        n, k = c.horizon, c.max_circles
        o, p = self.opti, self.p
        o.set_value(p["x0"], prob.x0)
        o.set_value(p["u_prev"], prob.u_prev)
        o.set_value(p["ref"], prob.ref.T)
        o.set_value(p["obs_xy"], prob.obs_xy.reshape(n * k, 2).T)
        o.set_value(p["obs_r"], prob.obs_r)
        o.set_value(p["dist_g"], prob.dist_g.T)
        o.set_value(p["dist_b"], prob.dist_b)
        o.set_value(p["lo0"], prob.u_lo0)
        o.set_value(p["hi0"], prob.u_hi0)
        t0 = time.perf_counter()
        try:
            sol = o.solve()
            ok, u0 = True, np.asarray(sol.value(self.U[:, 0])).ravel()
        except RuntimeError:
            ok, u0 = False, np.asarray(o.debug.value(self.U[:, 0])).ravel()
        return ok, u0, time.perf_counter() - t0
