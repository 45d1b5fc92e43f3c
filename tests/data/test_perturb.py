"""Seeded twins of a Sequence (slamkit.data.perturb): what each kind changes, exactly, and that
the same (seed, index) gives the same twin."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from slamkit.data.perturb import PerturbationConfig, jitter_ranges, perturb, shuffle_simultaneous, start_later
from slamkit.data.sequence import Odometry, RangeBearing, Scan, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError
from slamkit.models import diff_drive


def _log(n_scans: int = 6, with_truth: bool = False) -> Sequence:
    """Odometry (0.5 m/s, 0.1 rad/s over 0.1 s) then a 4-beam scan, every 0.1 s; the odometry and
    its scan share a stamp, as in a CARMEN log."""
    events, poses, pose = [], [np.zeros(3)], np.zeros(3)
    angles = np.array([-1.0, 0.0, 1.0, 2.0])
    for k in range(1, n_scans + 1):
        t = 0.1 * k
        events.append(Odometry(t, 0.1, 0.5, 0.1))
        pose = np.asarray(diff_drive.motion(pose, np.array([0.5, 0.1]), 0.1))
        poses.append(pose)
        events.append(Scan(t, angles, np.array([1.0 + k, np.nan, 2.0, 3.0]), 10.0))
    truth = Trajectory.from_se2(0.1 * np.arange(n_scans + 1), np.array(poses)) if with_truth else None
    return Sequence("log", tuple(events), truth, initial_world_xytheta_body=np.zeros(3))


def test_index_zero_is_the_sequence_itself() -> None:
    seq = _log()
    assert perturb(seq, 0, PerturbationConfig(count=5)) is seq


def test_start_offset_drops_everything_before_the_kth_scan_and_moves_the_initial_pose() -> None:
    seq = _log()
    later = start_later(seq, 2)
    # scans at 0.1 and 0.2 s are gone, and the odometry up to 0.3 s: it brought the robot to where
    # the new first scan (0.3 s) was taken, which is the new initial pose
    assert [type(e).__name__ for e in later.events[:2]] == ["Scan", "Odometry"]
    assert later.events[0].stamp_s == pytest.approx(0.3)
    assert len(later.of_type(Scan)) == 4 and len(later.of_type(Odometry)) == 3
    # no truth: the initial pose is the odometry integrated over the three dropped steps
    expected = np.zeros(3)
    for _ in range(3):
        expected = np.asarray(diff_drive.motion(expected, np.array([0.5, 0.1]), 0.1))
    np.testing.assert_allclose(later.initial_world_xytheta_body, expected, atol=1e-15)


def test_start_offset_with_truth_starts_at_the_true_pose_and_trims_the_truth() -> None:
    seq = _log(with_truth=True)
    later = start_later(seq, 3)
    assert later.ground_truth.stamps_s[0] == pytest.approx(0.4)
    np.testing.assert_array_equal(later.initial_world_xytheta_body, seq.ground_truth.xytheta()[4])
    assert later.events[0].stamp_s == pytest.approx(0.4) and isinstance(later.events[0], Scan)


def test_start_offset_past_the_end_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="has 6"):
        start_later(_log(), 6)


def test_range_jitter_moves_every_finite_range_by_micrometres_and_keeps_nan() -> None:
    seq = _log(n_scans=200)
    twin = jitter_ranges(seq, 1e-6, np.random.default_rng(0))
    before = np.array([e.ranges_m for e in seq.of_type(Scan)])
    after = np.array([e.ranges_m for e in twin.of_type(Scan)])
    assert np.array_equal(np.isnan(before), np.isnan(after))
    d = (after - before)[np.isfinite(before)]
    # 600 N(0, 1e-6) draws: none beyond 6 sigma, spread within 10% of sigma
    assert np.all(d != 0) and np.max(np.abs(d)) < 6e-6
    assert np.std(d) == pytest.approx(1e-6, rel=0.1)
    # odometry untouched, the same objects
    assert all(a is b for a, b in zip(seq.of_type(Odometry), twin.of_type(Odometry)))


def test_range_jitter_reaches_range_bearing_measurements() -> None:
    seq = Sequence("rb", (RangeBearing(0.0, np.array([1, 2]), np.array([3.0, 4.0]), np.array([0.1, 0.2])),))
    twin = jitter_ranges(seq, 1e-6, np.random.default_rng(1))
    assert np.all(np.abs(twin.events[0].range_m - [3.0, 4.0]) < 6e-6)
    assert not np.array_equal(twin.events[0].range_m, [3.0, 4.0])
    np.testing.assert_array_equal(twin.events[0].bearing_rad, [0.1, 0.2])


def test_event_order_shuffles_only_within_a_stamp() -> None:
    seq = _log(n_scans=50)
    twin = shuffle_simultaneous(seq, np.random.default_rng(2))
    stamps = [e.stamp_s for e in twin.events]
    assert stamps == sorted(stamps)
    assert sorted(map(id, twin.events)) == sorted(map(id, seq.events))
    # 50 pairs each flipped with probability 1/2: some were, some were not
    flipped = sum(isinstance(twin.events[2 * k], Scan) for k in range(50))
    assert 5 < flipped < 45


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), index=st.integers(1, 4))
def test_the_same_seed_and_index_give_the_same_twin(seed: int, index: int) -> None:
    seq = _log()
    config = PerturbationConfig(count=4, kinds=("start_offset", "range_jitter", "event_order"), seed=seed)
    a, b = perturb(seq, index, config), perturb(seq, index, config)
    assert len(a.events) == len(b.events) == len(seq.events) - 2 * index - 1
    for x, y in zip(a.events, b.events):
        assert type(x) is type(y) and x.stamp_s == y.stamp_s
        if isinstance(x, Scan):
            np.testing.assert_array_equal(x.ranges_m, y.ranges_m)
    assert a.metadata["perturbation"] == {"index": index, "kinds": list(config.kinds), "seed": seed,
                                          "range_jitter_m": 1e-6}


def test_bad_configs_are_refused() -> None:
    with pytest.raises(ConfigError, match="unknown"):
        PerturbationConfig(kinds=("start_offset", "shake"))
    with pytest.raises(ConfigError, match="count"):
        PerturbationConfig(count=-1)
    with pytest.raises(ConfigError, match="range_jitter_m"):
        PerturbationConfig(range_jitter_m=float("nan"))
    with pytest.raises(ConfigError, match="range_jitter_m"):
        PerturbationConfig(range_jitter_m=0.5)  # no longer a change a good algorithm ignores
    with pytest.raises(ConfigError, match="count"):
        PerturbationConfig(count=10**9)
    with pytest.raises(ConfigError, match="seed"):
        PerturbationConfig(seed=-1)


def test_start_offset_counts_steps_of_the_densest_stream() -> None:
    """A landmark world: odometry at 10 Hz, sightings at 2 Hz. One step later is 0.1 s later,
    not one sighting (0.5 s) later: the odometry step that ends at 0.1 s goes, the sighting
    taken at 0.1 s stays, and the robot starts where that step ended."""
    events, poses, pose = [RangeBearing(0.0, np.array([1]), np.array([2.0]), np.array([0.1]))], [np.zeros(3)], np.zeros(3)
    for k in range(1, 21):
        t = 0.1 * k
        events.append(Odometry(t, 0.1, 1.0, 0.0))
        pose = np.asarray(diff_drive.motion(pose, np.array([1.0, 0.0]), 0.1))
        poses.append(pose)
        if k % 5 == 0 or k == 1:
            events.append(RangeBearing(t, np.array([1]), np.array([2.0 - t]), np.array([0.1])))
    truth = Trajectory.from_se2(0.1 * np.arange(21), np.array(poses))
    seq = Sequence("lm", tuple(events), truth, initial_world_xytheta_body=np.zeros(3))
    later = start_later(seq, 1)
    assert isinstance(later.events[0], RangeBearing) and later.events[0].stamp_s == pytest.approx(0.1)
    assert len(later.of_type(Odometry)) == 19 and len(later.of_type(RangeBearing)) == 5
    np.testing.assert_allclose(later.initial_world_xytheta_body, [0.1, 0.0, 0.0], atol=1e-12)
    assert later.ground_truth.stamps_s[0] == pytest.approx(0.1)
