"""Augmented MCL injecting around the current mean: a tracking filter whose robot was pushed
0.25 m sideways (confident and wrong) finds it again; plain tracking MCL does not."""

from __future__ import annotations

import numpy as np

from slamkit.data.estimate import Prior
from slamkit.estimation._common import NoiseParams
from slamkit.estimation.lidar_mcl import LidarMCL, LidarMCLConfig
from slamkit.experiments.navigation import make_navigation_scenario
from slamkit.models.lidar import LikelihoodFieldModel
from slamkit.sim.navigation_world import NavigationPlant


def _errors_after_kidnap(config: LidarMCLConfig, before: int = 20, after: int = 30) -> np.ndarray:
    """Position errors of the ``after`` updates that follow a 0.25 m sideways kidnap of a robot
    driving at 0.2 m/s (``before`` updates tracked it where it was)."""
    sc = make_navigation_scenario(0, "passage", n_obstacles=0)
    plant = NavigationPlant(sc, np.random.default_rng(1), odometry_sigma_v_mps=0.02, odometry_sigma_omega_radps=0.02)
    mcl = LidarMCL(sc.grid, NoiseParams(sigma_v_mps=0.02, sigma_omega_radps=0.02), config, np.random.default_rng(2))
    mcl.reset(Prior(plant.world_xytheta_body.copy(), np.diag([1e-4, 1e-4, 1e-4])))
    errors = []
    for k in range(before + after):
        if k == before:
            plant.world_xytheta_body[1] += 0.25
        t = 0.1 * (k + 1)
        mcl.step(plant.advance(np.array([0.2, 0.0]), 0.1, t))
        mcl.step(plant.scan(t))
        errors.append(np.linalg.norm(mcl._pose_and_covariance()[0][:2] - plant.world_xytheta_body[:2]))
    return np.array(errors[before:])


def test_local_injection_recovers_a_short_kidnap_plain_tracking_does_not():
    base = dict(n_min=300, n_max=300, global_init=False, max_beams=30, likelihood_exponent=0.3,
                likelihood=LikelihoodFieldModel(z_hit=0.9, z_rand=0.1, sigma_hit_m=0.05), roughening_k=0.05)
    plain = _errors_after_kidnap(LidarMCLConfig(**base))
    aug = _errors_after_kidnap(LidarMCLConfig(**base, alpha_slow=0.01, alpha_fast=0.2, inject_sigma_xy_m=0.3))
    # measured: plain 0.266 -> 0.235 m over the 30 updates (the belief creeps, it never jumps);
    # injecting around the mean (sigma 0.3 m) 0.029 m at the first update, at most 0.030 m after
    assert plain[-10:].min() > 0.15
    assert aug[-10:].max() < 0.05
