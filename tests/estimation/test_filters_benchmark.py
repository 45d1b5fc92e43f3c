"""The filters benchmark compares like with like: its per-particle Python reference computes the
same step as the vectorised particle filter functions, and its dense EKF-SLAM reference the
same update as the sparse one (speed itself is only reported by ``slamkit bench filters``)."""

from __future__ import annotations

import numpy as np

from slamkit.estimation._common import NoiseParams
from slamkit.bench.filters import _pf_problem, _python_loop_step, estimator_latency_cases
from slamkit.estimation.particle_filter import range_bearing_log_likelihood, systematic_resample
from slamkit.models import diff_drive


def test_python_reference_step_equals_vectorised_step():
    rng = np.random.default_rng(0)
    _, lm, odo, obs = _pf_problem(rng)
    z = np.column_stack([obs.range_m, obs.bearing_rad])
    noise = NoiseParams()
    particles = rng.normal(0, 0.2, (300, 3))
    # reference: consumes standard normals (n, 2), then one uniform for the resampling offset
    out = _python_loop_step(tuple(particles[:, k].tolist() for k in range(3)), lm, z, noise, (odo.v_mps, odo.omega_radps), odo.dt_s,
                            np.random.default_rng(5))
    draws = np.random.default_rng(5)
    eps = draws.standard_normal((300, 2))
    u = np.array([odo.v_mps, odo.omega_radps]) + eps * [noise.sigma_v_mps, noise.sigma_omega_radps]
    moved = diff_drive.motion(particles, u, odo.dt_s)
    ll, _ = range_bearing_log_likelihood(moved, lm, z, noise.range_bearing_cov)
    w = np.exp(ll - ll.max())
    idx = systematic_resample(w / w.sum(), offset=draws.random() / 300)
    np.testing.assert_allclose(np.array(out).T, moved[idx], atol=1e-9)


def test_latency_cases_ratio_against_reference():
    from estimation_sim import NOISE, exact_prior, ring_world, simulate

    from slamkit.estimation.ekf import EKFLocalization
    from slamkit.estimation.ekf_slam import EKFSLAM

    world = ring_world(np.random.default_rng(1))
    seq = simulate(np.random.default_rng(2), world, n_steps=20)
    cases = estimator_latency_cases({"ekf_slam": lambda: EKFSLAM(NOISE),
                                     "ekf": lambda: EKFLocalization(world, NOISE)}, seq, exact_prior(seq))
    by_name = {c.name: c for c in cases}
    assert set(by_name) == {"ekf_slam_step_latency_median", "ekf_step_latency_median"}
    ekf = by_name["ekf_step_latency_median"]
    assert ekf.unit == "ms" and ekf.reference == "ekf_slam step latency"
    assert ekf.ratio == ekf.reference_value / ekf.value
    assert ekf.extra["events"] == len(seq)
