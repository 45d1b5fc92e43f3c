"""Range-only updates of the localisation filters (ekf, ukf, pf): a worked EKF example, the
same gate in every filter, and a Range event being ignored by filters without a range update."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data.estimate import Prior
from slamkit.data.noise import NoiseParams
from slamkit.data.sequence import Range
from slamkit.estimation.ekf import EKFLocalization
from slamkit.estimation.particle_filter import ParticleFilterConfig, ParticleFilterLocalization
from slamkit.estimation.ukf import UKFLocalization

NOISE = NoiseParams(sigma_range_m=1.0, range_gate_m=3.0)
BEACONS = {7: np.array([100.0, 0.0])}
PRIOR = Prior(np.zeros(3), np.diag([1.0, 1.0, 0.01]))


def _filters():
    return [EKFLocalization(BEACONS, NOISE), UKFLocalization(BEACONS, NOISE),
            ParticleFilterLocalization(BEACONS, NOISE, ParticleFilterConfig(n_particles=20000),
                                       rng=np.random.default_rng(1))]


def test_ekf_range_update_worked_example():
    # predicted range 100, measured 99: H = (-1, 0, 0), S = 1 + 1 = 2, K = (-0.5, 0, 0),
    # x = 0 + K (99 - 100) = (0.5, 0, 0), P_xx = 1 - 0.5 = 0.5, NIS = 1 / 2
    ekf = EKFLocalization(BEACONS, NOISE)
    ekf.reset(PRIOR)
    ekf.step(Range(0.0, np.array([7]), np.array([99.0])))
    est = ekf.estimate()
    np.testing.assert_allclose(est.trajectory.xytheta()[-1], [0.5, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(est.pose_covariances[-1], np.diag([0.5, 1.0, 0.01]), atol=1e-12)
    np.testing.assert_allclose(est.nis, [0.5])
    assert est.extras["rejected_ranges"] == 0


@pytest.mark.parametrize("index", [0, 1, 2], ids=["ekf", "ukf", "pf"])
def test_every_filter_agrees_with_the_worked_example_and_gates_alike(index):
    f = _filters()[index]
    f.reset(PRIOR)
    f.step(Range(0.0, np.array([7]), np.array([99.0])))
    # a range 5 m off the prediction lies outside the 3 m gate: rejected, the pose unchanged
    f.step(Range(1.0, np.array([7]), np.array([94.5])))
    # a beacon not in the map: rejected too
    f.step(Range(2.0, np.array([3]), np.array([50.0])))
    est = f.estimate()
    # the UKF's sigma points see the range's curvature (E[r] = 100 - x + E[y^2] / 200, so x moves
    # by ~0.0025 m more), the PF samples
    tol = (1e-9, 5e-3, 0.05)[index]
    np.testing.assert_allclose(est.trajectory.xytheta()[-1, :2], [0.5, 0.0], atol=tol)
    assert est.pose_covariances[-1][0, 0] == pytest.approx(0.5, abs=(1e-9, 5e-3, 0.03)[index])
    assert est.extras["rejected_ranges"] == 2
