"""The Plaza reader against the files themselves: counts, first and last rows, the GT heading
convention and the measured range scale (values read from Plaza{1,2}_DR.txt / _TD.txt / _.mat)."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data import registry
from slamkit.data.formats.plaza import load_plaza_sequence
from slamkit.data.noise import NoiseParams
from slamkit.data.sequence import Odometry, Range
from slamkit.errors import DataError

pytestmark = pytest.mark.skipif(not registry.is_available(registry.get("plaza1")),
                                reason="the gtsam wheel's Plaza files are not available")


@pytest.fixture(scope="module")
def plaza1():
    return load_plaza_sequence("plaza1")


@pytest.fixture(scope="module")
def plaza2():
    return load_plaza_sequence("plaza2")


def test_plaza1_counts_and_first_last_rows(plaza1):
    odo, ranges = plaza1.of_type(Odometry), plaza1.of_type(Range)
    assert (len(odo), len(ranges), len(plaza1.ground_truth)) == (9657, 3529, 9658)
    t0 = 3856.8573460579
    assert plaza1.metadata["time_offset_s"] == pytest.approx(t0, abs=1e-9)
    # DR row 1: 3857.0532019138 0.00023483858154428326 -5.2000000000163027e-05, after GT row 1
    first = odo[0]
    assert first.stamp_s == pytest.approx(3857.0532019138336 - t0, abs=1e-9)
    assert first.dt_s == pytest.approx(first.stamp_s, abs=1e-12)
    assert first.v_mps * first.dt_s == pytest.approx(2.3483858154428326e-04, rel=1e-12)
    assert first.omega_radps * first.dt_s == pytest.approx(-5.2000000000163027e-05, rel=1e-12)
    # DR last row: 5790.2992548942566 1.7622697994741719e-04 4.6000000000046004e-05
    last = odo[-1]
    assert last.stamp_s == pytest.approx(5790.2992548942566 - t0, abs=1e-9)
    assert last.v_mps * last.dt_s == pytest.approx(1.7622697994741719e-04, rel=1e-12)
    assert last.omega_radps * last.dt_s == pytest.approx(4.6000000000046004e-05, rel=1e-12)
    # TD first row: 3858.0620000362396 2 5 65.466007843625079; last: ... 2 1 61.841339643006052
    assert ranges[0].stamp_s == pytest.approx(3858.0620000362396 - t0, abs=1e-9)
    assert ranges[0].landmark_ids.tolist() == [5]
    assert ranges[0].range_m[0] == 65.466007843625079
    assert ranges[-1].landmark_ids.tolist() == [1]
    assert ranges[-1].range_m[0] == 61.841339643006052
    # GT first row (0, 0, 4.222432), last (-5.575932, 47.009076, -0.387163); heading as recorded
    gt = plaza1.ground_truth.xytheta()
    np.testing.assert_allclose(gt[0], [0.0, 0.0, 4.222432 - 2 * np.pi], atol=1e-9)
    np.testing.assert_allclose(gt[-1], [-5.575932, 47.009076, -0.387163], atol=1e-6)
    assert plaza1.metadata["ground_truth_heading_offset_rad"] == 0.0
    # TL: beacon 0 at (-46.623234, 11.025549), beacon 5 at (-17.664893, 59.009181)
    np.testing.assert_allclose(plaza1.world_p_landmarks[0], [-46.623234, 11.025549], atol=1e-6)
    np.testing.assert_allclose(plaza1.world_p_landmarks[5], [-17.664893, 59.009181], atol=1e-6)
    assert sorted(plaza1.world_p_landmarks) == [0, 1, 5, 6]
    np.testing.assert_allclose(plaza1.initial_world_xytheta_body, gt[0])


def test_plaza2_heading_points_along_the_motion(plaza2):
    odo, ranges = plaza2.of_type(Odometry), plaza2.of_type(Range)
    assert (len(odo), len(ranges), len(plaza2.ground_truth)) == (4090, 1816, 4091)
    assert ranges[0].landmark_ids.tolist() == [1]
    assert ranges[0].range_m[0] == 47.260574538515279
    assert ranges[-1].range_m[0] == 58.662150683311602
    # GT row 1 is (-34.208649, 45.300764, -2.021089): the recorded heading points backwards, the
    # reader turns it by pi
    assert plaza2.metadata["heading_offset_median_rad"] == pytest.approx(3.1063, abs=1e-4)
    assert plaza2.metadata["ground_truth_heading_offset_rad"] == pytest.approx(np.pi)
    np.testing.assert_allclose(plaza2.ground_truth.xytheta()[0], [-34.208649, 45.300764, np.pi - 2.021089],
                               atol=1e-6)
    # integrating the odometry from the GT start follows the GT for the first 10 s (< 0.3 m)
    from slamkit.models import diff_drive

    x = plaza2.initial_world_xytheta_body.copy()
    for e in odo[:100]:
        x = diff_drive.motion(x, np.array([e.v_mps, e.omega_radps]), e.dt_s)
    assert np.hypot(*(x[:2] - plaza2.ground_truth.xytheta()[100, :2])) < 0.3


def test_range_scale_fit_and_calibration(plaza1, plaza2):
    assert plaza1.metadata["range_scale_fit"] == pytest.approx(1.0694, abs=1e-4)
    assert plaza2.metadata["range_scale_fit"] == pytest.approx(1.0696, abs=1e-4)
    scaled = load_plaza_sequence("plaza2", range_scale=2.0, max_duration_s=5.0)
    assert scaled.of_type(Range)[0].range_m[0] == pytest.approx(47.260574538515279 / 2.0)
    assert max(e.stamp_s for e in scaled) <= 5.0
    assert scaled.metadata["range_scale_sigma"] == 0.0     # a number: calibrated, s not estimated


def test_range_scale_estimate_mode():
    """``range_scale: estimate``: the ranges as recorded, the scale declared unknown (prior sigma
    0.1), which every range-only estimator reads through NoiseParams."""
    seq = load_plaza_sequence("plaza2", range_scale="estimate", max_duration_s=5.0)
    assert seq.of_type(Range)[0].range_m[0] == pytest.approx(47.260574538515279)
    assert seq.metadata["range_scale"] == "estimate"
    assert NoiseParams.from_metadata(seq.metadata).range_scale_sigma == 0.1
    for bad in ("estimated", -1.0):
        with pytest.raises(DataError, match="range_scale"):
            load_plaza_sequence("plaza2", range_scale=bad, max_duration_s=5.0)


def test_noise_metadata_reaches_every_estimator(plaza2):
    noise = NoiseParams.from_metadata(plaza2.metadata)
    assert (noise.sigma_v_mps, noise.sigma_omega_radps, noise.sigma_range_m, noise.range_gate_m) == \
        (0.1, 0.02, 0.6, 3.0)
    assert noise.range_rejected(3.5) and not noise.range_rejected(-2.9)
