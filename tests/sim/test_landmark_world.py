"""Landmark-world simulator: seeded, consistent with its own noise promises, presets differ."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data.sequence import Odometry, RangeBearing
from slamkit.errors import ConfigError
from slamkit.geometry.angles import wrap_angle
from slamkit.models.range_bearing import RangeBearingSensor, observe
from slamkit.sim import paths
from slamkit.sim.landmark_world import (LandmarkScenario, mildly_nonlinear,
                                        simulate_landmark_sequence, strongly_nonlinear)


def _true_controls(gt_xytheta, dt):
    """Invert the exact arc between consecutive poses: (v, omega) held over dt."""
    d = np.diff(gt_xytheta[:, :2], axis=0)
    dtheta = wrap_angle(np.diff(gt_xytheta[:, 2]))
    chord = np.linalg.norm(d, axis=1)
    arc = chord / np.sinc(0.5 * dtheta / np.pi)
    return np.column_stack([arc / dt, dtheta / dt])


def _flatten(seq):
    out = []
    for e in seq:
        if isinstance(e, Odometry):
            out.append(("o", e.stamp_s, e.dt_s, e.v_mps, e.omega_radps))
        else:
            out.append(("r", e.stamp_s, tuple(e.landmark_ids), tuple(e.range_m), tuple(e.bearing_rad)))
    return out


def test_same_seed_same_sequence_other_seed_differs():
    cfg = mildly_nonlinear(duration_s=20.0)
    a = simulate_landmark_sequence(cfg, np.random.default_rng(7))
    b = simulate_landmark_sequence(cfg, np.random.default_rng(7))
    c = simulate_landmark_sequence(cfg, np.random.default_rng(8))
    assert _flatten(a) == _flatten(b)
    assert np.array_equal(a.ground_truth.world_t_body, b.ground_truth.world_t_body)
    assert _flatten(a) != _flatten(c)


def test_odometry_noise_matches_metadata_and_motion_is_the_exact_arc():
    cfg = mildly_nonlinear(duration_s=200.0)
    seq = simulate_landmark_sequence(cfg, np.random.default_rng(1))
    odo = seq.of_type(Odometry)
    gt = seq.ground_truth.xytheta()
    assert len(odo) == len(gt) - 1 == 2000
    np.testing.assert_allclose([o.stamp_s for o in odo], seq.ground_truth.stamps_s[1:])
    u_true = _true_controls(gt, 0.1)
    u_meas = np.array([[o.v_mps, o.omega_radps] for o in odo])
    resid = u_meas - u_true
    sigma = np.array(seq.metadata["odometry_sigma"])
    np.testing.assert_allclose(sigma, [0.05, np.deg2rad(2.0)])
    # 2000 samples: the sample std lies within 5% of sigma, the mean within 4 standard errors
    np.testing.assert_allclose(resid.std(axis=0), sigma, rtol=0.05)
    assert np.all(np.abs(resid.mean(axis=0)) < 4 * sigma / np.sqrt(2000))
    # the robot really drives: a 20 m x 12 m stadium at about 1 m/s
    assert 180 < seq.ground_truth.path_length_m() < 205
    assert gt[:, 0].max() - gt[:, 0].min() == pytest.approx(20.0, abs=0.6)


def test_range_bearing_noise_visibility_and_ids():
    cfg = mildly_nonlinear(duration_s=100.0)
    seq = simulate_landmark_sequence(cfg, np.random.default_rng(2))
    lm = seq.world_p_landmarks
    assert len(lm) == 40
    gt = dict(zip(np.round(seq.ground_truth.stamps_s, 9), seq.ground_truth.xytheta()))
    resid = []
    for e in seq.of_type(RangeBearing):
        pose = gt[round(e.stamp_s, 9)]
        z = observe(pose, np.array([lm[int(i)] for i in e.landmark_ids]).reshape(-1, 2))
        resid.append(np.column_stack([e.range_m - z[:, 0], wrap_angle(e.bearing_rad - z[:, 1])]))
        # every visible landmark is reported (no dropout in this preset)
        all_lm = np.array(list(lm.values()))
        dist = np.linalg.norm(all_lm - pose[:2], axis=1)
        assert len(e.landmark_ids) == np.sum(dist <= 8.0)
    resid = np.vstack(resid)
    assert len(resid) > 5000
    np.testing.assert_allclose(resid.std(axis=0), seq.metadata["range_bearing_sigma"], rtol=0.05)
    # odometry first, then the observation, at a shared stamp
    kinds = [type(e).__name__ for e in seq.events[:5]]
    assert kinds == ["RangeBearing", "Odometry", "RangeBearing", "Odometry", "RangeBearing"]


def test_strong_preset_is_sparser_noisier_and_respects_the_field_of_view():
    mild = simulate_landmark_sequence(mildly_nonlinear(duration_s=60.0), np.random.default_rng(3))
    strong = simulate_landmark_sequence(strongly_nonlinear(duration_s=60.0), np.random.default_rng(3))
    assert strong.metadata["odometry_sigma"][1] > 5 * mild.metadata["odometry_sigma"][1]
    per_obs = lambda s: np.mean([len(e.range_m) for e in s.of_type(RangeBearing)])  # noqa: E731
    assert per_obs(strong) < 0.3 * per_obs(mild)
    bearings = np.concatenate([e.bearing_rad for e in strong.of_type(RangeBearing)])
    # +-60 degrees plus at most 5 sigma of bearing noise
    assert np.all(np.abs(bearings) <= np.deg2rad(60.0) + 5 * np.deg2rad(3.0))
    assert len(strong.of_type(RangeBearing)) == 301  # 5 Hz for 60 s, plus t = 0


def test_unknown_correspondences_hide_ids():
    seq = simulate_landmark_sequence(mildly_nonlinear(duration_s=5.0, known_correspondences=False),
                                     np.random.default_rng(0))
    ids = np.concatenate([e.landmark_ids for e in seq.of_type(RangeBearing)])
    assert len(ids) > 0 and np.all(ids == -1)


def test_velocity_profile_worked_example():
    # 2 s straight at 1 m/s, a quarter turn in place (2 s at pi/4 rad/s), then 1 m straight
    cfg = LandmarkScenario(path="profile", profile=((2.0, 1.0, 0.0), (2.0, 0.0, np.pi / 4),
                                                    (1.0, 1.0, 0.0)),
                           odometry_sigma_v_mps=0.0, odometry_sigma_omega_radps=0.0)
    seq = simulate_landmark_sequence(cfg, np.random.default_rng(0))
    gt = seq.ground_truth.xytheta()
    assert len(gt) == 51
    np.testing.assert_allclose(gt[20], [2.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(gt[40], [2.0, 0.0, np.pi / 2], atol=1e-12)
    np.testing.assert_allclose(gt[50], [2.0, 1.0, np.pi / 2], atol=1e-12)
    odo = seq.of_type(Odometry)
    assert odo[0].v_mps == 1.0 and odo[25].omega_radps == pytest.approx(np.pi / 4)


def test_random_waypoints_path_reaches_its_goal():
    drive = paths.pure_pursuit(np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 5.0]]), False, 60.0, 0.1)
    assert np.linalg.norm(drive.world_xytheta_body[-1, :2] - [5.0, 5.0]) < 0.3
    assert len(drive.controls) < 600  # stopped at the goal, did not use the whole minute
    # pose_at is exact on the arcs and agrees with the stored poses at control stamps
    np.testing.assert_allclose(drive.pose_at(drive.stamps_s[:-1]), drive.world_xytheta_body[:-1],
                               atol=1e-12)


@pytest.mark.parametrize("bad", [
    dict(path="spiral"), dict(landmarks="grid"), dict(path="profile"),
    dict(odometry_rate_hz=10.0, sensor=RangeBearingSensor(rate_hz=3.0)),
    dict(num_landmarks=-1),
])
def test_invalid_scenarios_raise_config_error(bad):
    with pytest.raises(ConfigError):
        LandmarkScenario(**bad)


def test_same_seed_gives_byte_identical_sequence_files(tmp_path):
    import hashlib

    from slamkit.data.formats.sequence import load_sequence, save_sequence

    cfg = strongly_nonlinear(duration_s=30.0)
    digests = []
    for name in ("a", "b"):
        seq = simulate_landmark_sequence(cfg, np.random.default_rng(42))
        digests.append(hashlib.sha256(save_sequence(tmp_path / f"{name}.slamseq", seq).read_bytes()).hexdigest())
    assert digests[0] == digests[1]
    other = simulate_landmark_sequence(cfg, np.random.default_rng(43))
    assert hashlib.sha256(save_sequence(tmp_path / "c.slamseq", other).read_bytes()).hexdigest() != digests[0]
    back = load_sequence(tmp_path / "a.slamseq")
    assert _flatten(back) == _flatten(seq)
    assert back.metadata["scenario"]["sensor"]["fov_rad"] == pytest.approx(np.deg2rad(120.0))


def test_optional_gps_fixes_and_unchanged_other_streams():
    from slamkit.data.sequence import Gps
    from slamkit.models.gps import Gps as GpsModel

    base = mildly_nonlinear(duration_s=100.0)
    with_gps = mildly_nonlinear(duration_s=100.0, gps=GpsModel(sigma_m=0.5, rate_hz=2.0))
    a = simulate_landmark_sequence(base, np.random.default_rng(9))
    b = simulate_landmark_sequence(with_gps, np.random.default_rng(9))
    fixes = b.of_type(Gps)
    assert len(fixes) == 200 and b.metadata["gps_sigma_m"] == 0.5
    # GPS draws from its own stream: odometry and observations are the same as without GPS
    assert _flatten([e for e in b if not isinstance(e, Gps)]) == _flatten(a)
    gt = b.ground_truth
    idx = np.searchsorted(gt.stamps_s, [f.stamp_s - 1e-9 for f in fixes])
    err = np.array([f.world_p_body for f in fixes]) - gt.xytheta()[idx, :2]
    assert np.std(err) == pytest.approx(0.5, rel=0.15)
    # a fix shares its stamp with the odometry that ends there and comes after it
    i = next(k for k, e in enumerate(b.events) if isinstance(e, Gps))
    assert isinstance(b.events[i - 2], Odometry) and b.events[i - 2].stamp_s == b.events[i].stamp_s
