"""``slamkit bench filters``: the estimation layer's cases plus per-step latency of iSAM2 and the
fixed-lag smoother against EKF-SLAM on the same simulated sequence (the estimation layer may not
import the back-end, so the smoother rows are assembled here)."""

from __future__ import annotations

import numpy as np

from slamkit.bench import filters as filter_benchmark
from slamkit.experiments.estimators import factory, prior_of
from slamkit.sim.landmark_world import mildly_nonlinear, simulate_landmark_sequence
from slamkit.bench.cases import BenchCase

LATENCY_ESTIMATORS = {"ekf_slam": {}, "isam2": {}, "fixed_lag": {"lag_s": 5.0}}


def run(quick: bool = False) -> list[BenchCase]:
    duration_s = 20.0 if quick else 60.0
    sequence = simulate_landmark_sequence(mildly_nonlinear(duration_s=duration_s),
                                          np.random.default_rng(0))
    factories = {name: (lambda build=factory(name, params): build(sequence))
                 for name, params in LATENCY_ESTIMATORS.items()}
    return filter_benchmark.run(quick, extra_estimators=factories, latency_sequence=sequence,
                                latency_prior=prior_of(sequence))
