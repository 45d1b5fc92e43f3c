"""End-to-end localization on a simulated ring world: accuracy, NIS, unknown correspondences,
and MCL's global localization and kidnapping recovery."""

from __future__ import annotations

import numpy as np
import pytest
from estimation_sim import NOISE, ate_rmse_m, position_errors, ring_world, run, simulate

from slamkit.data.estimate import Prior
from slamkit.estimation.ekf import EKFLocalization, EKFLocalizationConfig
from slamkit.estimation.mcl import MCLConfig, MonteCarloLocalization, kld_sample_bound, kld_sample_count
from slamkit.estimation.particle_filter import ParticleFilterConfig, ParticleFilterLocalization
from slamkit.estimation.ukf import UKFLocalization


@pytest.fixture(scope="module")
def world():
    return ring_world(np.random.default_rng(1))


@pytest.fixture(scope="module")
def unknown_ids_sequence(world):
    return simulate(np.random.default_rng(5), world, n_steps=150, known_ids=False)


@pytest.mark.parametrize("make", [
    lambda lm: EKFLocalization(lm, NOISE),
    lambda lm: UKFLocalization(lm, NOISE),
    lambda lm: ParticleFilterLocalization(lm, NOISE, ParticleFilterConfig(n_particles=500),
                                          rng=np.random.default_rng(0)),
], ids=["ekf", "ukf", "pf"])
def test_unknown_correspondences_localize(world, unknown_ids_sequence, make):
    est = run(make(world), unknown_ids_sequence)
    # with ~10 landmarks in view at 0.1 m / 0.02 rad noise the pose is known to a few cm
    assert ate_rmse_m(est, unknown_ids_sequence) < 0.05


def test_ekf_nis_is_chi_square_on_a_well_modelled_run(world):
    seq = simulate(np.random.default_rng(11), world, n_steps=300)
    est = run(EKFLocalization(world, NOISE), seq)
    assert set(est.nis_dof.tolist()) == {2}
    # ~3000 NIS samples of dof 2: the mean is 2 with standard error ~0.04
    assert 1.85 < est.nis.mean() < 2.15
    assert est.pose_covariances.shape == (len(est.trajectory), 3, 3)


def test_kld_bound_matches_fox_2003():
    # Fox (2003) Fig. 3: epsilon = 0.05, delta = 0.01 -> about 100 samples for k = 10 bins
    # (the chi-square quantile chi2_{9, 0.99} / (2 * 0.05) = 21.67 / 0.1 = 216.7 exactly; the
    # Wilson-Hilferty approximation gives 217)
    assert kld_sample_bound(10, 0.05, 0.01) == pytest.approx(217, abs=1)
    assert kld_sample_bound(1, 0.05, 0.01) == 1


def test_kld_sample_count_grows_with_spread():
    rng = np.random.default_rng(0)
    bins = np.array([0.5, 0.5, np.deg2rad(10)])
    tight = rng.normal(0, 0.05, (20000, 3))
    wide = rng.uniform(-10, 10, (20000, 3))
    n_tight = kld_sample_count(tight, bins, 0.05, 0.01, n_min=50)
    n_wide = kld_sample_count(wide, bins, 0.05, 0.01, n_min=50)
    assert n_tight < 300
    assert n_wide == 20000  # capped: the uniform spread occupies thousands of bins


# Global localization and kidnapping. The robot circles (radius 5 m); at step 150 it is carried
# to (4, 4, pi/2) without the odometry knowing. Stated bounds ("localized" = position error
# < 0.5 m and staying so): localized within 30 updates from a uniform prior, and again within
# 40 updates after the kidnap. Trajectory row i is the posterior after step i + 1.
KIDNAP_STEP = 150
GLOBAL_STEPS = 30
RECOVERY_STEPS = 40
LOCALIZED_M = 0.5


def _kidnap_run(world, seed):
    seq = simulate(np.random.default_rng(seed), world, n_steps=300, kidnap_at=KIDNAP_STEP,
                   kidnap_pose=np.array([4.0, 4.0, np.pi / 2]))
    mcl = MonteCarloLocalization(world, NOISE, MCLConfig(n_max=5000), rng=np.random.default_rng(seed + 1))
    # a deliberately wrong prior: global initialisation must ignore it
    est = run(mcl, seq, Prior(np.array([-8.0, 8.0, 0.0]), np.eye(3) * 0.01))
    return seq, est, position_errors(est, seq)


def _settled(err: np.ndarray) -> int:
    """Index from which the error stays below LOCALIZED_M (len(err) if it never settles)."""
    bad = np.flatnonzero(err >= LOCALIZED_M)
    return 0 if len(bad) == 0 else int(bad[-1] + 1)


def _check_global_and_recovery(est, err):
    before, after = err[:KIDNAP_STEP - 1], err[KIDNAP_STEP - 1:]
    assert _settled(before) < GLOBAL_STEPS
    assert after[0] > 3.0  # the kidnap really moved the robot away from the belief
    assert _settled(after) <= RECOVERY_STEPS


@pytest.fixture(scope="module")
def kidnapped(world):
    return _kidnap_run(world, 3)


def test_mcl_localizes_globally_and_recovers_from_kidnapping(kidnapped):
    _, est, err = kidnapped
    _check_global_and_recovery(est, err)


def test_mcl_injects_after_kidnap_and_kld_shrinks_the_set(kidnapped):
    _, est, err = kidnapped
    p = est.extras["injection_probabilities"]
    # the augmented-MCL rule injects random particles soon after the kidnap ...
    assert p[KIDNAP_STEP - 1:KIDNAP_STEP + 9].max() > 0.5
    # ... and not while the robot is tracked
    assert np.mean(p[60:KIDNAP_STEP - 1] > 0) < 0.1
    # KLD-sampling: the full n_max while the belief is uniform, n_min-sized once concentrated
    counts = est.extras["particle_counts"]
    assert counts.max() == 5000 and np.median(counts[60:KIDNAP_STEP - 1]) == 200


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(10, 20))
def test_mcl_global_and_kidnap_over_seeds(world, seed):
    _, est, err = _kidnap_run(world, seed)
    _check_global_and_recovery(est, err)


def test_pf_without_recovery_stays_lost_after_kidnapping(world):
    """The contrast that motivates augmented MCL: a plain PF does not recover."""
    seq = simulate(np.random.default_rng(3), world, n_steps=220, kidnap_at=KIDNAP_STEP,
                   kidnap_pose=np.array([4.0, 4.0, np.pi / 2]))
    est = run(ParticleFilterLocalization(world, NOISE, ParticleFilterConfig(n_particles=1000),
                                         rng=np.random.default_rng(4)), seq)
    assert position_errors(est, seq)[-1] > 1.0


def test_ekf_stacked_and_sequential_updates_agree(world):
    """One stacked linearisation per event vs Table 7.2's per-measurement loop: on this data the
    two trajectories differ by far less than their error (~1.5 cm)."""
    seq = simulate(np.random.default_rng(12), world, n_steps=100)
    stacked = run(EKFLocalization(world, NOISE), seq)
    sequential = run(EKFLocalization(world, NOISE, EKFLocalizationConfig(sequential_updates=True)), seq)
    diff = np.linalg.norm(stacked.trajectory.world_t_body - sequential.trajectory.world_t_body, axis=1)
    assert diff.max() < 2e-3
    assert len(stacked.nis) == len(sequential.nis)


@pytest.mark.parametrize("make", [
    lambda lm: EKFLocalization(lm, NOISE),
    lambda lm: UKFLocalization(lm, NOISE),
    lambda lm: ParticleFilterLocalization(lm, NOISE, ParticleFilterConfig(n_particles=2000),
                                          rng=np.random.default_rng(0)),
], ids=["ekf", "ukf", "pf"])
def test_gps_fixes_pull_a_wrong_prior_to_the_truth(world, make):
    """Odometry plus 1 Hz GPS (sigma 0.5 m), no landmarks in range: starting 3 m off, the
    estimate ends within 0.6 m of the truth and the GPS NIS is recorded (dof 2)."""
    from slamkit.data.sequence import Gps, Sequence

    seq = simulate(np.random.default_rng(8), world, n_steps=200, max_range_m=0.0)
    gt = seq.ground_truth
    rng = np.random.default_rng(9)
    fixes = [Gps(float(t), gt.world_t_body[k, :2] + rng.normal(0, 0.5, 2), 0.5)
             for k, t in enumerate(gt.stamps_s) if k % 10 == 0 and k > 0]
    seq = Sequence.from_events("gps", list(seq.events) + fixes, ground_truth=gt,
                               initial_world_xytheta_body=seq.initial_world_xytheta_body)
    prior = Prior(seq.initial_world_xytheta_body + np.array([3.0, 0.0, 0.0]), np.diag([9.0, 9.0, 0.01]))
    est = run(make(world), seq, prior)
    assert position_errors(est, seq)[-1] < 0.6
    assert len(est.nis) >= len(fixes) - 1 and set(est.nis_dof.tolist()) == {2}
