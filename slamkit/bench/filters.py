"""``slamkit bench filters``: the filters against references measured in the same run.

Cases (``run(quick=False) -> list[BenchCase]``):

* ``pf_step_n1000`` / ``pf_step_n10000``: one particle-filter step (predict with sampled
  velocity noise, weight on ``PF_LANDMARKS_PER_STEP`` range-bearing measurements, NIS, resample
  every step, posterior mean and covariance) of :class:`ParticleFilterLocalization`, in steps per
  second, against the same step written as a per-particle Python loop (``math`` module scalar
  code, the strongest loop one would write without numpy). Goals: >= 10x the loop, and
  >= 500 steps/s at N = 10000.
* ``ekf_slam_update_l500``: one EKF-SLAM measurement update with 500 landmarks in the state
  (n = 1003): :func:`slamkit.estimation.ekf_slam.sparse_update` (O(n^2)) against the naive
  dense (I - K H) P update (O(n^3)), in ms. Goal: >= 5x.
* Smoother latency (iSAM2, fixed-lag): see :func:`estimator_latency_cases` -- the estimation
  layer may not import ``slamkit.backend``, so those cases are produced by calling that
  function with smoother factories from a layer that may (the CLI or ``slamkit.experiments``)
  and appended to this suite's cases there. ``run`` takes them through ``extra_estimators``.
"""

from __future__ import annotations

import math
import time
from typing import Callable, Mapping

import numpy as np

from slamkit.data.estimate import Estimator, Prior
from slamkit.data.sequence import Odometry, RangeBearing, Sequence
from slamkit.estimation._common import NoiseParams
from slamkit.estimation.ekf_slam import dense_update, sparse_update
from slamkit.estimation.particle_filter import ParticleFilterConfig, ParticleFilterLocalization
from slamkit.models import range_bearing
from slamkit.bench.cases import BenchCase, best_of, compare

PF_LANDMARKS_PER_STEP = 5


# --------------------------------------------------------------------------------------------
# particle filter
# --------------------------------------------------------------------------------------------
def _pf_problem(rng: np.random.Generator):
    landmarks = {i: rng.uniform(-10.0, 10.0, 2) for i in range(20)}
    ids = np.arange(PF_LANDMARKS_PER_STEP)
    lm = np.array([landmarks[i] for i in ids])
    z = range_bearing.observe(np.zeros((len(ids), 3)), lm) + rng.normal(0, [0.1, 0.02], (len(ids), 2))
    odometry = Odometry(0.1, 0.1, 1.0, 0.1)
    observation = RangeBearing(0.1, ids, z[:, 0], z[:, 1])
    return landmarks, lm, odometry, observation


def _python_loop_step(particles: tuple[list[float], list[float], list[float]], lm: np.ndarray,
                      z: np.ndarray, noise: NoiseParams, u: tuple[float, float], dt: float,
                      rng: np.random.Generator) -> tuple[list[float], list[float], list[float]]:
    """The reference: the same PF step as scalar Python over particles (exact arc, Gaussian
    likelihood with wrapped bearing, weighted mean, systematic resampling). Particles are three
    flat float lists (x, y, theta) -- a list per particle would spend most of its time in the
    garbage collector at N = 10000, which would flatter the vectorised filter."""
    xs, ys, ths = particles
    n = len(xs)
    sv, sw = noise.sigma_v_mps, noise.sigma_omega_radps
    sr2, sb2 = noise.sigma_range_m**2, noise.sigma_bearing_rad**2
    draws = rng.standard_normal((n, 2))
    ev, ew = draws[:, 0].tolist(), draws[:, 1].tolist()
    lms = [(float(a), float(b)) for a, b in lm]
    zs = [(float(a), float(b)) for a, b in z]
    two_pi, pi = 2.0 * math.pi, math.pi
    nx, ny, nth, log_w = [0.0] * n, [0.0] * n, [0.0] * n, [0.0] * n
    for i in range(n):
        th = ths[i]
        v = u[0] + sv * ev[i]
        w = u[1] + sw * ew[i]
        a = w * dt
        s = math.sin(0.5 * a) / (0.5 * a) if abs(a) > 1e-12 else 1.0
        phi = th + 0.5 * a
        x = xs[i] + v * dt * s * math.cos(phi)
        y = ys[i] + v * dt * s * math.sin(phi)
        th = (th + a + pi) % two_pi - pi
        nx[i], ny[i], nth[i] = x, y, th
        ll = 0.0
        for (mx, my), (zr, zb) in zip(lms, zs):
            dx, dy = mx - x, my - y
            dr = zr - math.hypot(dx, dy)
            db = (zb - (math.atan2(dy, dx) - th) + pi) % two_pi - pi
            ll -= 0.5 * (dr * dr / sr2 + db * db / sb2)
        log_w[i] = ll
    top = max(log_w)
    weights = [math.exp(v - top) for v in log_w]
    total = sum(weights)
    weights = [v / total for v in weights]
    _mean = (sum(wi * x for wi, x in zip(weights, nx)), sum(wi * y for wi, y in zip(weights, ny)))
    ox, oy, oth = [0.0] * n, [0.0] * n, [0.0] * n
    c, j = weights[0], 0
    u0 = rng.random() / n
    for k in range(n):
        pos = u0 + k / n
        while pos > c and j < n - 1:
            j += 1
            c += weights[j]
        ox[k], oy[k], oth[k] = nx[j], ny[j], nth[j]
    return ox, oy, oth


def _pf_cases(quick: bool) -> list[BenchCase]:
    rng = np.random.default_rng(0)
    landmarks, lm, odometry, observation = _pf_problem(rng)
    noise = NoiseParams()
    z = np.column_stack([observation.range_m, observation.bearing_rad])
    cases = []
    for n in (1000, 10000):
        pf = ParticleFilterLocalization(landmarks, noise, ParticleFilterConfig(n_particles=n, ess_threshold=1.0),
                                        rng=np.random.default_rng(1))
        pf.reset(Prior(np.zeros(3), np.diag([0.05, 0.05, 0.01])))
        steps = 20 if quick else 100
        clock = [0.0]

        def vectorised() -> None:
            # a new stamp every step, so the posterior summary (mean, covariance) that the
            # trajectory records once per stamp is part of the measured step
            for _ in range(steps):
                clock[0] += odometry.dt_s
                t = clock[0]
                pf.step(Odometry(t, odometry.dt_s, odometry.v_mps, odometry.omega_radps))
                pf.step(RangeBearing(t, observation.landmark_ids, observation.range_m,
                                     observation.bearing_rad))

        vectorised()  # warm-up
        t_vec, _ = best_of(vectorised, repeat=3)
        rate = steps / t_vec

        particles = tuple(pf.particles[:, k].tolist() for k in range(3))
        loop_rng = np.random.default_rng(2)
        loop_steps = 1 if (quick or n > 1000) else 3

        def loop() -> None:
            nonlocal particles
            for _ in range(loop_steps):
                particles = _python_loop_step(particles, lm, z, noise, (odometry.v_mps, odometry.omega_radps),
                                              odometry.dt_s, loop_rng)

        t_loop, _ = best_of(loop, repeat=1 if n > 1000 else 2)
        ref_rate = loop_steps / t_loop
        goal = ">= 10" if n == 1000 else ">= 10 and >= 500 steps/s"
        cases.append(compare(f"pf_step_n{n}", rate, "steps/s", "per-particle python loop", ref_rate,
                             goal=goal, higher_is_better=True, n_particles=n,
                             landmarks_per_step=PF_LANDMARKS_PER_STEP,
                             ms_per_step=1e3 / rate, meets_500_steps_per_s=bool(rate >= 500)))
    return cases


# --------------------------------------------------------------------------------------------
# EKF-SLAM update
# --------------------------------------------------------------------------------------------
def _ekf_slam_case(quick: bool) -> BenchCase:
    rng = np.random.default_rng(3)
    n_landmarks = 500
    n = 3 + 2 * n_landmarks
    x = np.concatenate([[0.0, 0.0, 0.1], rng.uniform(-30, 30, 2 * n_landmarks)])
    A = rng.standard_normal((n, n)) / np.sqrt(n)
    P = A @ A.T * 0.01 + 1e-3 * np.eye(n)
    R = np.diag([0.01, 0.0004])
    j = 3 + 2 * 250
    z = range_bearing.observe(x[:3], x[j:j + 2]) + np.array([0.05, 0.01])
    reps = 3 if quick else 10

    def sparse() -> None:
        xs, Ps = x.copy(), P.copy()
        sparse_update(xs, Ps, n, j, z, R)

    def copies_only() -> None:
        x.copy(), P.copy()

    def dense() -> None:
        dense_update(x.copy(), P.copy(), j, z, R)

    t_copy, _ = best_of(copies_only, repeat=reps)
    t_sparse, _ = best_of(sparse, repeat=reps)
    t_dense, _ = best_of(dense, repeat=max(2, reps // 3))
    # both timings include the same state copies (so that every repeat starts from the same
    # state); subtracting them would flatter neither side much but we report them as measured
    return compare("ekf_slam_update_l500", 1e3 * t_sparse, "ms", "dense (I - K H) P update",
                   1e3 * t_dense, goal=">= 5", state_dim=n, copy_ms=1e3 * t_copy)


# --------------------------------------------------------------------------------------------
# per-step latency of any online estimator (used for the smoothers from outside this layer)
# --------------------------------------------------------------------------------------------
def estimator_latency_cases(factories: Mapping[str, Callable[[], Estimator]], sequence: Sequence,
                            prior: Prior, reference: str = "ekf_slam") -> list[BenchCase]:
    """Median per-step latency (ms) of each estimator on ``sequence``; every case is compared
    with the ``reference`` entry of ``factories`` (ratio = reference latency / latency), so the
    iSAM2 and fixed-lag rows read as "x times the cost of EKF-SLAM" on the same data."""
    medians: dict[str, float] = {}
    p95: dict[str, float] = {}
    for name, make in factories.items():
        est = make()
        est.reset(prior)
        lat = []
        for event in sequence:
            t0 = time.perf_counter()
            est.step(event)
            lat.append(time.perf_counter() - t0)
        medians[name] = 1e3 * float(np.median(lat))
        p95[name] = 1e3 * float(np.percentile(lat, 95))
    ref = medians.get(reference)
    cases = []
    for name, value in medians.items():
        if ref is None or name == reference:
            cases.append(BenchCase(f"{name}_step_latency_median", value, "ms",
                                   extra={"p95_ms": p95[name], "events": len(sequence)}))
        else:
            cases.append(compare(f"{name}_step_latency_median", value, "ms", f"{reference} step latency",
                                 ref, p95_ms=p95[name], events=len(sequence)))
    return cases


def run(quick: bool = False, extra_estimators: Mapping[str, Callable[[], Estimator]] | None = None,
        latency_sequence: Sequence | None = None, latency_prior: Prior | None = None) -> list[BenchCase]:
    """All filter cases. The iSAM2 / fixed-lag latency rows belong here too: pass their
    factories as ``extra_estimators`` (with an ``ekf_slam`` factory as the reference) together
    with the sequence and prior to time them on -- the caller lives in a layer allowed to import
    slamkit.backend (see module doc)."""
    cases = _pf_cases(quick)
    cases.append(_ekf_slam_case(quick))
    # ---- smoother latency (iSAM2, fixed-lag): supplied by the caller, see module doc ----
    if extra_estimators and latency_sequence is not None and latency_prior is not None:
        cases.extend(estimator_latency_cases(extra_estimators, latency_sequence, latency_prior))
    return cases
