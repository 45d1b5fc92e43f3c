"""``slamkit bench control``: closed-loop quality of the local planners and solver timing.

Part 1 -- closed loop over seeded scenarios (>= 50 unless ``quick``; office, warehouse and open
maps in turn, three crossing obstacles each): success rate, time to goal, path length, minimum
clearance, collisions and jerk for potential fields, DWA, MPC (IPOPT) and the MPC fast path
(OSQP). These cases have no reference (there is no "slower" baseline for a success rate).

Part 2 -- timing on identical problems. A closed-loop run of the IPOPT MPC records the OCP of
every cycle; the cycles are then replayed in order through

* the tuned MPC (IPOPT, built once, warm-started)            goal: median < 6 ms, p99 < 20 ms
* the MPC fast path (one OSQP QP per cycle)                  goal: median <= 2 ms
* the same NLP solved by fatrop (Riccati-structured IPM)     reported beside them
* DWA on the same states and worlds                          goal: median < 10 ms per cycle
* the reference: ``casadi.Opti`` + default IPOPT, cold start (``slamkit.control.mpc_reference``)

and every case prints ``ratio`` = reference time / its time, measured in the same run. Times are
whole control cycles (problem set-up + solve), i.e. what the loop pays, in wall-clock time as the
goals state; ``extra`` adds the process CPU time of the same cycles and the 1-minute load
average, because on a shared machine preemption inflates wall times of multi-millisecond calls
(measured: a pure-Python loop ran at 1/3 of its CPU time in wall time at load 7.5 on 2 cores).
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np

from slamkit.control.dwa import DWAController
from slamkit.control.mpc import MPCConfig, MPCController
from slamkit.bench.mpc_reference import OptiMPC
from slamkit.control.protocols import Reference, RobotState
from slamkit.control.registry import make_controller
from slamkit.experiments.closed_loop import ClosedLoopConfig, Episode, make_scenario, perceive, run_episode
from slamkit.bench.cases import BenchCase, compare

KINDS = ("office", "warehouse", "open")
#: the registry names (slamkit.control.registry) the closed-loop part compares
CLOSED_LOOP_CONTROLLERS = ("potential_fields", "dwa", "mpc", "mpc_osqp")
METRICS = (("success", "", "success_rate"), ("time_to_goal_s", "s", "time_to_goal_mean_s"),
           ("path_length_m", "m", "path_length_mean_m"), ("min_clearance_m", "m", "min_clearance_mean_m"),
           ("collisions", "", "collision_rate"), ("jerk_rms_mps3", "m/s^3", "jerk_rms_mean_mps3"))


def _load() -> float:
    try:
        return float(os.getloadavg()[0])
    except OSError:
        return float("nan")


def closed_loop_cases(n_scenarios: int, controllers=CLOSED_LOOP_CONTROLLERS, kinds=KINDS
                      ) -> tuple[list[BenchCase], list[Episode]]:
    scenarios = [make_scenario(seed, kinds[seed % len(kinds)]) for seed in range(n_scenarios)]
    cases, episodes = [], []
    for name in controllers:
        ctl = make_controller(name)
        eps = [run_episode(sc, ctl) for sc in scenarios]
        episodes += eps
        for metric, unit, label in METRICS:
            values = np.array([e.metrics[metric] for e in eps], dtype=float)
            ok = values[np.isfinite(values)]
            cases.append(BenchCase(f"{label}_{name}", float(ok.mean()) if len(ok) else float("nan"), unit,
                                   extra={"n": int(len(ok)), "scenarios": n_scenarios}))
    return cases, episodes


def _record_cycles(n_scenarios: int, max_cycles: int) -> list[tuple[RobotState, Reference, Any]]:
    """(state, reference, world) of every cycle of closed-loop IPOPT-MPC runs, in order."""
    loop = ClosedLoopConfig(max_time_s=min(ClosedLoopConfig().max_time_s, max_cycles * ClosedLoopConfig().dt_s))
    cycles: list[tuple[RobotState, Reference, Any]] = []

    class _Rec:
        def __init__(self, sc):
            self.sc, self.u, self.x = sc, np.zeros(2), sc.start_xytheta

        def on_episode(self, *_a):
            pass

        def on_step(self, snap):
            t = snap.t_s - loop.dt_s
            cycles.append((RobotState(self.x, self.u, t), Reference(self.sc.path_xy_m, loop.reference_speed_mps),
                           perceive(self.sc, self.x, t, loop)))
            self.x, self.u = snap.world_xytheta_body, snap.output.command

    ctl = MPCController(MPCConfig())
    for seed in range(n_scenarios):
        sc = make_scenario(100 + seed, KINDS[seed % len(KINDS)])
        run_episode(sc, ctl, loop, [_Rec(sc)])
        if len(cycles) >= max_cycles:
            break
    return cycles[:max_cycles]


def timing_cases(cycles) -> list[BenchCase]:
    ipopt = MPCController(MPCConfig(solver="ipopt"))
    fast = MPCController(MPCConfig(solver="osqp"))
    fatrop = MPCController(MPCConfig(solver="fatrop"))
    dwa = DWAController()
    ref = OptiMPC(MPCConfig())
    t_ipopt, t_fast, t_dwa, t_ref, t_solver = [], [], [], [], []
    cpu: dict[str, list[float]] = {"ipopt": [], "osqp": [], "fatrop": [], "dwa": [], "ref": []}
    t_fatrop = []
    ref_fail = 0

    def timed(key, fn):
        c0 = time.process_time()
        res = fn()
        cpu[key].append(time.process_time() - c0)
        return res

    for state, reference, world in cycles:
        if state.t_s == 0.0:  # a new episode: engines start cold, as in the loop
            ipopt.reset()
            fast.reset()
            fatrop.reset()
        # the reference gets exactly the problem the tuned build solves this cycle (taken before
        # compute() moves the warm start, which is also the distance-field linearisation point)
        prob = ipopt.problem(state, reference, world)
        out = timed("ipopt", lambda: ipopt.compute(state, reference, world))
        t_ipopt.append(out.solve_time_s)
        t_solver.append(out.info.get("solver_time_s", np.nan))
        t_fast.append(timed("osqp", lambda: fast.compute(state, reference, world)).solve_time_s)
        t_fatrop.append(timed("fatrop", lambda: fatrop.compute(state, reference, world)).solve_time_s)
        t_dwa.append(timed("dwa", lambda: dwa.compute(state, reference, world)).solve_time_s)
        ok, _u, t = timed("ref", lambda: ref.solve(prob))
        t_ref.append(t)
        ref_fail += not ok
    ms = lambda a: 1e3 * np.asarray(a)  # noqa: E731
    ti, tf, td, tr = ms(t_ipopt), ms(t_fast), ms(t_dwa), ms(t_ref)
    c = {k: ms(v) for k, v in cpu.items()}
    ref_name = "casadi.Opti + default IPOPT, cold start, same problem"
    extra = {"cycles": len(cycles), "load_avg_1min": _load(), "reference_failures": ref_fail,
             "reference_cpu_median_ms": float(np.median(c["ref"]))}
    return [
        compare("mpc_ipopt_n20_median", float(np.median(ti)), "ms", ref_name, float(np.median(tr)),
                goal="< 6 ms", **extra, cpu_median_ms=float(np.median(c["ipopt"])),
                solver_only_median_ms=float(np.nanmedian(ms(t_solver)))),
        compare("mpc_ipopt_n20_p99", float(np.percentile(ti, 99)), "ms", ref_name,
                float(np.percentile(tr, 99)), goal="< 20 ms", **extra,
                cpu_p99_ms=float(np.percentile(c["ipopt"], 99))),
        compare("mpc_osqp_n20_median", float(np.median(tf)), "ms", ref_name, float(np.median(tr)),
                goal="<= 2 ms", **extra, p99_ms=float(np.percentile(tf, 99)),
                cpu_median_ms=float(np.median(c["osqp"]))),
        compare("mpc_fatrop_n20_median", float(np.median(ms(t_fatrop))), "ms", ref_name, float(np.median(tr)),
                **extra, p99_ms=float(np.percentile(ms(t_fatrop), 99)),
                cpu_median_ms=float(np.median(c["fatrop"])), cpu_p99_ms=float(np.percentile(c["fatrop"], 99))),
        compare("dwa_cycle_median", float(np.median(td)), "ms", ref_name, float(np.median(tr)),
                goal="< 10 ms", **extra, p99_ms=float(np.percentile(td, 99)),
                cpu_median_ms=float(np.median(c["dwa"]))),
    ]


def run(quick: bool = False) -> list[BenchCase]:
    n_closed = 6 if quick else 51
    cases, _ = closed_loop_cases(n_closed)
    # the reference takes ~0.1-0.3 s per cycle, so the replay is capped at 400 cycles
    cycles = _record_cycles(2 if quick else 4, 150 if quick else 400)
    return cases + timing_cases(cycles)
