"""One reader of a Sequence's noise metadata (NoiseParams) and one start prior (prior_of) for
filters and smoothers alike (issue 18)."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data.noise import NoiseParams, prior_of
from slamkit.data.sequence import Odometry, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError


def _sequence(initial=None, ground_truth=True, metadata=None) -> Sequence:
    gt = Trajectory.from_se2(np.array([0.0, 1.0]), np.array([[2.0, -1.0, 0.5], [3.0, -1.0, 0.5]]))
    return Sequence("s", (Odometry(1.0, 1.0, 1.0, 0.0),), gt if ground_truth else None,
                    initial_world_xytheta_body=initial, metadata=metadata or {})


def test_metadata_keys_and_overrides() -> None:
    noise = NoiseParams.from_metadata({"odometry_sigma": [0.2, 0.03], "range_bearing_sigma": (0.5, 0.04),
                                       "initial_pose_sigma": [0.1, 0.2, 0.01]}, sigma_range_m=0.7)
    assert noise == NoiseParams(0.2, 0.03, 0.7, 0.04, (0.1, 0.2, 0.01))
    np.testing.assert_allclose(noise.control_cov, np.diag([0.04, 0.0009]))
    np.testing.assert_allclose(noise.range_bearing_cov, np.diag([0.49, 0.0016]))
    # the field names directly; a None entry keeps the default
    assert NoiseParams.from_metadata({"sigma_v_mps": 0.3, "odometry_sigma": None}) == NoiseParams(sigma_v_mps=0.3)
    assert NoiseParams.from_metadata({}) == NoiseParams()


@pytest.mark.parametrize("metadata, text", [
    ({"odometry_sigma": [0.1]}, "metadata field odometry_sigma must have 2 values, got 1"),
    ({"initial_pose_sigma": [0.1, 0.1]}, "metadata field initial_pose_sigma must have 3 values, got 2"),
    ({"range_bearing_sigma": [0.0, 0.1]}, "NoiseParams.sigma_range_m must be positive and finite, got 0.0"),
    ({"initial_pose_sigma": [0.1, -0.1, 0.0]}, "NoiseParams.initial_pose_sigma must be 3 finite sigmas >= 0"),
])
def test_bad_metadata_names_the_field(metadata, text) -> None:
    with pytest.raises(ConfigError, match=text):
        NoiseParams.from_metadata(metadata)


def test_prior_of_worked_example() -> None:
    # the declared start, the metadata sigmas squared on the diagonal
    prior = prior_of(_sequence(initial=np.array([1.0, 2.0, 0.3]),
                               metadata={"initial_pose_sigma": [0.1, 0.2, 0.01]}))
    np.testing.assert_array_equal(prior.world_xytheta_body, [1.0, 2.0, 0.3])
    np.testing.assert_allclose(prior.covariance, np.diag([0.01, 0.04, 1e-4]), rtol=1e-15)
    # no declared start: the ground truth's first pose; no metadata: 1e-3 on each axis
    prior = prior_of(_sequence())
    np.testing.assert_allclose(prior.world_xytheta_body, [2.0, -1.0, 0.5], atol=1e-15)
    np.testing.assert_allclose(prior.covariance, np.diag([1e-6] * 3), rtol=1e-15)
    np.testing.assert_array_equal(prior_of(_sequence(ground_truth=False)).world_xytheta_body, [0.0, 0.0, 0.0])


def test_prior_of_options_keep_the_batch_smoothers_numbers() -> None:
    """The runner floors the sigmas at 1e-6 and starts at the true first pose when none is
    declared; the batch smoother's solve() does neither (see prior_of)."""
    seq = _sequence(metadata={"initial_pose_sigma": [0.0, 1e-7, 0.1]})
    runner = prior_of(seq)
    np.testing.assert_allclose(runner.world_xytheta_body, [2.0, -1.0, 0.5], atol=1e-15)
    np.testing.assert_allclose(np.diag(runner.covariance), [1e-12, 1e-12, 1e-2], rtol=1e-15)
    batch = prior_of(seq, NoiseParams(initial_pose_sigma=(0.3, 1e-7, 0.1)), sigma_floor=0.0,
                     start_from_ground_truth=False)
    np.testing.assert_array_equal(batch.world_xytheta_body, [0.0, 0.0, 0.0])
    np.testing.assert_allclose(np.diag(batch.covariance), [0.09, 1e-14, 1e-2], rtol=1e-15)
