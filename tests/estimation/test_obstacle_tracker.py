"""The lidar obstacle detector and the constant-velocity tracker on scripted scans, with exact
expectations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slamkit.errors import ConfigError
from slamkit.estimation.obstacle_tracker import (ConstantVelocityTracker, DetectorConfig, Detection, TrackerConfig,
                                                 cluster_points, cv_matrices, merge_overlapping, scan_clusters,
                                                 unexplained_points)
from slamkit.maps.raycast import cast_circles


def _wall_distance(points: np.ndarray) -> np.ndarray:
    """A map with one wall, the line x = 5: distance of points to it."""
    return np.abs(points[:, 0] - 5.0)


def test_points_the_map_explains_are_dropped():
    # robot at the origin facing +x; beams at 0 and 90 degrees: the first ends on the wall x = 5,
    # the second 2 m up (free space), the third returns nothing
    pts = unexplained_points([0.0, 0.0, 0.0], np.array([0.0, math.pi / 2, math.pi]),
                             np.array([5.0, 2.0, np.nan]), 10.0, _wall_distance, 0.25)
    np.testing.assert_allclose(pts, [[0.0, 2.0]], atol=1e-12)


def test_a_disc_seen_by_the_lidar_becomes_one_detection_at_its_centre():
    # a 0.3 m disc 3 m ahead, 1 degree beams (11 hit it, +-5 degrees: y within +-0.262 m): one
    # disc of radius half the points' bounding-box diagonal, centred that far behind the nearest point (2.7 m)
    angles = np.deg2rad(np.arange(-30.0, 30.0, 1.0))
    r = cast_circles(np.zeros((len(angles), 2)), angles, np.array([[3.0, 0.0]]), np.array([0.3]), 10.0)
    pts = unexplained_points([0.0, 0.0, 0.0], angles, r, 10.0, lambda p: np.full(len(p), 10.0), 0.25)
    det = cluster_points(pts, np.zeros(2), DetectorConfig())
    assert len(det.xy_m) == 1 and det.n_points[0] == len(pts) == 11
    assert det.radius_m[0] == pytest.approx(0.5 * np.linalg.norm(np.ptp(pts, axis=0)), abs=1e-12)
    assert det.radius_m[0] == pytest.approx(3.0 * math.sin(math.radians(5.0)), abs=0.01)
    assert det.xy_m[0] == pytest.approx([2.7 + det.radius_m[0], 0.0], abs=1e-9)


def test_clusters_split_at_gaps_and_small_ones_are_noise():
    pts = np.array([[1.0, 0.0], [1.0, 0.05], [1.0, 0.1],       # cluster A (3 points)
                    [1.0, 1.0], [1.0, 1.05],                   # 2 points: noise
                    [2.0, 3.0], [2.05, 3.0], [2.1, 3.0], [2.15, 3.0]])  # cluster B (4 points)
    det = cluster_points(pts, np.zeros(2), DetectorConfig(cluster_gap_m=0.3, min_points=3, min_radius_m=0.05))
    np.testing.assert_array_equal(det.n_points, [3, 4])
    # A: extent 0.1 -> radius 0.05 (the floor); nearest point (1, 0) at 1 m; centre 1.05 m out
    # along the direction of the mean (1, 0.05)
    assert det.radius_m[0] == pytest.approx(0.05)
    away = np.array([1.0, 0.05]) / np.linalg.norm([1.0, 0.05])
    assert det.xy_m[0] == pytest.approx(1.05 * away)
    assert det.radius_m[1] == pytest.approx(0.075)


def test_a_stray_return_inside_a_discs_arc_cuts_it_in_two_unless_bridged():
    """A 0.3 m disc 1 m ahead (beams 1 deg apart: +-17 deg hit it, 35 points) whose beam at +3 deg
    returned short, at 0.3 m: the classic rule sees two pieces of the arc (20 and 14 points; the
    stray point alone is noise), each a disc of its own chord, and reports the disc enclosing both,
    0.162 m off the true centre (radius 0.282 m); bridging one point sees the one arc: 0.029 m off
    (radius 0.271 m, the chord of the visible arc)."""
    angles = np.deg2rad(np.arange(-30.0, 31.0, 1.0))
    r = cast_circles(np.zeros((len(angles), 2)), angles, np.array([[1.0, 0.0]]), np.array([0.3]), 10.0)
    r[np.flatnonzero(np.isclose(angles, np.deg2rad(3.0)))] = 0.3
    pts = unexplained_points([0.0, 0.0, 0.0], angles, r, 10.0, lambda p: np.full(len(p), 10.0), 0.25)
    assert len(pts) == 35
    assert np.bincount(scan_clusters(pts, 0.3, 0)).tolist() == [20, 1, 14]
    assert np.bincount(scan_clusters(pts, 0.3, 1)).tolist() == [34, 1]
    for bridged, off_m, radius_m in ((0, 0.1620, 0.2823), (1, 0.0295, 0.2706)):
        det = cluster_points(pts, np.zeros(2), DetectorConfig(bridged_points=bridged))
        np.testing.assert_array_equal(det.n_points, [34])
        assert np.linalg.norm(det.xy_m[0] - [1.0, 0.0]) == pytest.approx(off_m, abs=1e-4)
        assert det.radius_m[0] == pytest.approx(radius_m, abs=1e-4)


@pytest.mark.parametrize("seed", range(20))
def test_bridging_only_joins_the_classic_clusters_and_numbers_them_in_scan_order(seed):
    """Random scan-ordered points: each cluster with ``bridged_points`` k + 1 is a union of
    clusters with k (bridging joins, never cuts), k = 0 is the neighbour rule, and labels count
    up from 0 in the order of each cluster's first point."""
    rng = np.random.default_rng(seed)
    pts = np.cumsum(rng.normal(0.0, 0.2, (60, 2)), axis=0)
    previous = None
    for k in range(4):
        labels = scan_clusters(pts, 0.3, k)
        firsts = [int(np.flatnonzero(labels == c)[0]) for c in range(labels.max() + 1)]
        assert firsts == sorted(firsts) and set(labels) == set(range(labels.max() + 1))
        if previous is not None:
            assert all(len(set(labels[previous == c])) == 1 for c in set(previous))
        else:
            gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1) > 0.3
            wrap = np.linalg.norm(pts[-1] - pts[0]) <= 0.3
            assert labels.max() + 1 == int(gaps.sum()) + 1 - (bool(wrap) and gaps.any())
        previous = labels


@pytest.mark.parametrize("bad", [-1, 11, 1.5, float("nan")])
def test_bridged_points_is_checked(bad):
    assert scan_clusters(np.zeros((0, 2)), 0.3, 1).shape == (0,)
    with pytest.raises(ConfigError, match="bridged_points must be a whole number in"):
        DetectorConfig(bridged_points=bad)


def test_overlapping_discs_merge_into_the_smallest_enclosing_one():
    det = merge_overlapping(np.array([[0.0, 0.0], [0.3, 0.0], [5.0, 5.0]]), np.array([0.2, 0.2, 0.1]),
                            np.array([4, 5, 3]), max_radius_m=1.0)
    # discs of 0.2 at x = 0 and 0.3 overlap: enclosing disc from -0.2 to 0.5 -> centre 0.15, r 0.35
    np.testing.assert_allclose(det.xy_m, [[0.15, 0.0], [5.0, 5.0]], atol=1e-12)
    np.testing.assert_allclose(det.radius_m, [0.35, 0.1])
    np.testing.assert_array_equal(det.n_points, [9, 3])


def test_constant_velocity_matrices():
    F, Q = cv_matrices(0.5, 2.0)
    np.testing.assert_allclose(F[0], [1, 0, 0.5, 0])
    # q [[dt^3/3, dt^2/2], [dt^2/2, dt]] = 2 * [[1/24, 1/8], [1/8, 1/2]]
    np.testing.assert_allclose(Q[np.ix_([0, 2], [0, 2])], [[1 / 12, 1 / 4], [1 / 4, 1.0]])
    np.testing.assert_allclose(Q[0, 1], 0.0)


def test_tracker_recovers_a_constant_velocity_and_confirms_after_two_hits():
    tr = ConstantVelocityTracker(TrackerConfig(confirm_hits=2))
    v = np.array([0.5, -0.2])
    for k in range(40):
        t = 0.1 * k
        tr.update(t, Detection(np.array([[1.0, 2.0]]) + t * v, np.array([0.3]), np.array([10])))
        if k == 0:
            assert len(tr.tracks().ids) == 0      # tentative
        if k == 1:
            assert len(tr.tracks().ids) == 1      # confirmed
    out = tr.tracks()
    assert out.ids.tolist() == [0]
    np.testing.assert_allclose(out.velocity_mps[0], v, atol=1e-3)
    np.testing.assert_allclose(out.xy_m[0], np.array([1.0, 2.0]) + 3.9 * v, atol=1e-3)
    assert out.radius_m[0] == pytest.approx(0.3)


def test_two_crossing_tracks_keep_their_identities_and_a_lost_one_is_deleted():
    tr = ConstantVelocityTracker(TrackerConfig(max_misses=3))
    for k in range(10):
        t = 0.1 * k
        tr.update(t, Detection(np.array([[0.0, 0.3 * t], [3.0, -0.3 * t]]), np.array([0.2, 0.3]), np.array([5, 5])))
    assert tr.tracks().ids.tolist() == [0, 1]
    assert tr.tracks().xy_m[1] == pytest.approx([3.0, -0.27], abs=1e-3)
    for k in range(10, 14):  # the second obstacle is no longer seen: 4 misses > 3 -> deleted
        t = 0.1 * k
        tr.update(t, Detection(np.array([[0.0, 0.3 * t]]), np.array([0.2]), np.array([5])))
    assert tr.tracks().ids.tolist() == [0]


def test_a_shuttling_track_keeps_its_seen_span_typical_speed_and_counts_its_reversals():
    # a disc shuttling along y = 2 between x = 1 and x = 3 at 0.4 m/s (5 s per leg), seen at 10 Hz
    # for 12 s: out to x = 3 (t = 5), back to x = 1 (t = 10), out again to x = 1.8 (t = 12)
    tr = ConstantVelocityTracker()
    for k in range(121):
        t = 0.1 * k
        s = 0.4 * t % 4.0
        x = 1.0 + (s if s <= 2.0 else 4.0 - s)
        tr.update(t, Detection(np.array([[x, 2.0]]), np.array([0.3]), np.array([10])))
    out = tr.tracks()
    assert out.ids.tolist() == [0]
    # two turns, each counted once although the filtered speed passes through 0 in between
    assert out.reversals.tolist() == [2]
    # the seen span: the filter's estimates reach (almost: it lags a turn by a few cm) both ends
    span_x = np.sort(out.span_xy_m[0, :, 0])
    np.testing.assert_allclose(span_x, [1.0, 3.0], atol=0.1)
    np.testing.assert_allclose(out.span_xy_m[0, :, 1], [2.0, 2.0], atol=0.02)
    # the typical speed stays near 0.4 m/s (an exponential average, 0.1 per scan)
    assert 0.3 < out.speed_typical_mps[0] < 0.45
    # a track made from positions alone (no history) has none: its speed is its typical speed
    from slamkit.estimation.obstacle_tracker import Tracks
    bare = Tracks(np.arange(1), np.array([[1.0, 2.0]]), np.array([[0.3, 0.4]]), np.array([0.2]), np.eye(4)[None])
    assert bare.reversals.tolist() == [0] and bare.speed_typical_mps.tolist() == [0.5]
    np.testing.assert_allclose(bare.span_xy_m, [[[1.0, 2.0], [1.0, 2.0]]])


def test_a_standing_track_has_no_reversals():
    # detection noise of 3 cm around a fixed point: the span stays below reverse_span_m (0.3 m)
    rng = np.random.default_rng(0)
    tr = ConstantVelocityTracker()
    for k in range(100):
        tr.update(0.1 * k, Detection(np.array([[1.0, 2.0]]) + 0.03 * rng.standard_normal((1, 2)),
                                     np.array([0.3]), np.array([10])))
    out = tr.tracks()
    assert out.reversals.tolist() == [0]
    assert np.linalg.norm(out.span_xy_m[0, 1] - out.span_xy_m[0, 0]) < 0.3


def test_a_track_that_leaves_its_span_line_starts_a_new_span_and_keeps_its_reversals():
    # the shuttler above (span x 1..3 along y = 2, 2 reversals) at x = 1.8 at t = 12 s; from then
    # on its detections go straight down (-y) at 0.4 m/s for 3 s, to (1.8, 0.8) -- a turn, or a
    # track that took over another obstacle's detections where two lanes meet
    def run(config: TrackerConfig):
        tr = ConstantVelocityTracker(config)
        for k in range(151):
            t = 0.1 * k
            s = 0.4 * t % 4.0
            xy = [1.0 + (s if s <= 2.0 else 4.0 - s), 2.0] if k <= 120 else [1.8, 2.0 - 0.4 * (t - 12.0)]
            tr.update(t, Detection(np.array([xy]), np.array([0.3]), np.array([10])))
        return tr.tracks()

    out = run(TrackerConfig())
    # the filtered estimate (lagging the turn) is 0.319 m below y = 2 at t = 12.8 s, more than
    # span_restart_m = 0.3 m: the span starts again there and runs down to the last estimate
    np.testing.assert_allclose(out.span_xy_m[0], [[1.801, 1.681], [1.8, 0.8]], atol=2e-3)
    assert out.reversals.tolist() == [2]  # still a track seen reversing (its prediction is hedged)
    # without the restart the span stays the old lane, 1.2 m away from where the track now moves
    stale = run(TrackerConfig(span_restart_m=None))
    np.testing.assert_allclose(stale.span_xy_m[0], [[1.0, 2.0], [3.0, 2.0]], atol=2e-3)


def _shuttle_x(t: float) -> float:
    """The shuttler above: along y = 2 between x = 1 and 3 at 0.4 m/s (5 s per leg)."""
    s = 0.4 * t % 4.0
    return 1.0 + (s if s <= 2.0 else 4.0 - s)


def test_a_shuttler_hidden_long_enough_to_lose_its_track_gets_its_lane_back():
    # seen 12 s (2 reversals, span x 1..3), hidden for 3 s (30 scans > max_misses 5: the track is
    # deleted), seen again for 1 s from t = 15 s (x 3 -> 2.6, a new track)
    def run(config: TrackerConfig, hidden_s: float = 3.0):
        tr = ConstantVelocityTracker(config)
        for k in range(121):
            tr.update(0.1 * k, Detection(np.array([[_shuttle_x(0.1 * k), 2.0]]), np.array([0.3]), np.array([10])))
        t0 = 12.0 + hidden_s
        for k in range(121, int(round(10 * t0))):
            tr.update(0.1 * k, Detection(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=int)))
        for k in range(int(round(10 * t0)), int(round(10 * t0)) + 11):
            tr.update(0.1 * k, Detection(np.array([[_shuttle_x(0.1 * k), 2.0]]), np.array([0.3]), np.array([10])))
        return tr.tracks()

    out = run(TrackerConfig(lane_memory_s=30.0))
    assert out.ids.tolist() == [1]
    # the new track continues the lane: two reversals, the span x 1..3, the typical speed ~0.4
    assert out.reversals.tolist() == [2]
    np.testing.assert_allclose(np.sort(out.span_xy_m[0, :, 0]), [1.0, 3.0], atol=0.1)
    assert 0.3 < out.speed_typical_mps[0] < 0.45
    # without the memory it knows only its own second: no reversal, a span of ~0.3 m
    bare = run(TrackerConfig())
    assert bare.reversals.tolist() == [0]
    assert np.ptp(bare.span_xy_m[0, :, 0]) < 0.45
    # a lane remembered for 2 s is forgotten by the time the shuttler comes back after 3
    forgot = run(TrackerConfig(lane_memory_s=2.0))
    assert forgot.reversals.tolist() == [0]


def test_a_track_lost_to_a_split_cluster_gives_its_lane_to_its_successor():
    # the shuttler above, seen for 12 s (2 reversals, span x 1..3); at t = 12.1 s its cluster
    # splits (near a wall part of it is explained by the map): one fragment 0.1 m ahead of it,
    # which the track takes, one 0.2 m behind, which starts a new track; from then on it is seen
    # 0.15 m behind its centre, nearer the new track, and the old one is starved and deleted
    def run(config: TrackerConfig):
        tr = ConstantVelocityTracker(config)
        for k in range(121):
            tr.update(0.1 * k, Detection(np.array([[_shuttle_x(0.1 * k), 2.0]]), np.array([0.3]), np.array([10])))
        x = _shuttle_x(12.1)
        tr.update(12.1, Detection(np.array([[x + 0.1, 2.0], [x - 0.2, 2.0]]), np.array([0.15, 0.15]),
                                  np.array([5, 5])))
        for k in range(122, 131):
            tr.update(0.1 * k, Detection(np.array([[_shuttle_x(0.1 * k) - 0.15, 2.0]]), np.array([0.3]),
                                         np.array([10])))
        return tr.tracks()

    out = run(TrackerConfig(lane_memory_s=30.0))
    assert out.ids.tolist() == [1]  # the successor alone (the old track missed 6 scans > max_misses 5)
    # ... with the history it could not have seen itself: two reversals, the span from x = 1 to 3
    assert out.reversals.tolist() == [2]
    np.testing.assert_allclose(np.sort(out.span_xy_m[0, :, 0]), [1.0, 3.0], atol=0.1)
    assert 0.3 < out.speed_typical_mps[0] < 0.45
    # without the memory it knows only its own 0.9 s
    bare = run(TrackerConfig())
    assert bare.reversals.tolist() == [0] and np.ptp(bare.span_xy_m[0, :, 0]) < 0.45


def test_lane_memory_and_span_restart_refuse_nan_and_non_positive_values():
    import pytest

    from slamkit.errors import ConfigError

    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ConfigError):
            TrackerConfig(lane_memory_s=bad)
        with pytest.raises(ConfigError):
            TrackerConfig(span_restart_m=bad)
    assert TrackerConfig(lane_memory_s=None).lane_memory_s is None


def test_the_known_radius_fit_recovers_a_circle_from_its_near_arc():
    from slamkit.estimation.obstacle_tracker import fit_centre_known_radius

    # noise-free points on the near side (+-40 degrees about the line of sight) of a 0.35 m
    # circle centred at (3, 1), seen from the origin: from a start 0.2 m short and 0.1 m aside
    # (where an under-stated radius puts it) the fit lands on the centre
    centre = np.array([3.0, 1.0])
    back = math.atan2(-1.0, -3.0)  # the direction from the centre to the sensor
    phi = back + np.deg2rad(np.linspace(-40.0, 40.0, 9))
    arc = centre + 0.35 * np.column_stack([np.cos(phi), np.sin(phi)])
    fit = fit_centre_known_radius(arc, 0.35, centre + [-0.2, 0.1], np.zeros(2))
    np.testing.assert_allclose(fit, centre, atol=1e-9)
    # from a start in front of the arc it would find the mirror circle, nearer the sensor than the
    # arc: refused, the start is kept
    start = np.array([2.0, 2.0 / 3.0])
    np.testing.assert_allclose(fit_centre_known_radius(arc, 0.35, start, np.zeros(2)), start)


def _passing_disc_errors(seed: int, fit: bool = False,
                         config: TrackerConfig | None = None) -> tuple[float, float, float]:
    """A 0.35 m disc passing 2 m in front of a lidar at the origin (1 degree beams, 2 cm range
    noise) along y = 2 at 0.5 m/s for 6 s: the RMS centre and velocity errors of its track from
    1 s on, and its mean radius."""
    rng = np.random.default_rng(seed)
    angles = np.deg2rad(np.arange(-180.0, 180.0, 1.0))
    tracker = ConstantVelocityTracker(config or TrackerConfig(known_radius_fit=fit))
    centre_err, velocity_err, radius = [], [], []
    for k in range(60):
        t = 0.1 * k
        centre = np.array([-1.5 + 0.5 * t, 2.0])
        r = cast_circles(np.zeros((len(angles), 2)), angles, centre[None], np.array([0.35]), 10.0)
        r = r + 0.02 * rng.standard_normal(len(r))
        pts = unexplained_points([0.0, 0.0, 0.0], angles, r, 10.0, lambda p: np.full(len(p), 10.0), 0.25)
        tracker.update(t, cluster_points(pts, np.zeros(2), DetectorConfig()))
        tracks = tracker.tracks()
        if t >= 1.0:
            assert len(tracks.ids) == 1
            centre_err.append(tracks.xy_m[0] - centre)
            velocity_err.append(tracks.velocity_mps[0] - [0.5, 0.0])
            radius.append(tracks.radius_m[0])
    rms = lambda e: float(np.sqrt(np.mean(np.sum(np.square(e), axis=1))))  # noqa: E731
    return rms(centre_err), rms(velocity_err), float(np.mean(radius))


@pytest.mark.parametrize("seed", range(5))
def test_the_known_radius_fit_halves_a_passing_discs_centre_and_velocity_errors(seed):
    # measured over seeds 0-9: centre RMS 0.036-0.042 m without the fit, 0.006-0.016 m with it;
    # velocity RMS 0.039-0.051 against 0.019-0.023 m/s; the radius 0.334-0.335 m (the arc's
    # extent under-states it) against 0.352-0.362 m (its 0.9 quantile)
    centre, velocity, radius = _passing_disc_errors(seed, fit=False)
    assert centre > 0.03 and velocity > 0.035 and radius < 0.34
    centre, velocity, radius = _passing_disc_errors(seed, fit=True)
    assert centre < 0.02 and velocity < 0.03 and 0.345 < radius < 0.37


def test_a_detection_keeps_the_points_it_was_found_from():
    # one cluster of 3 points: its points and the sensor are kept; two overlapping discs merged
    # join their points
    pts = np.array([[3.0, -0.1], [3.0, 0.0], [3.0, 0.1]])
    det = cluster_points(pts, np.array([0.5, 0.0]), DetectorConfig())
    assert len(det.points_xy_m) == 1
    np.testing.assert_allclose(det.points_xy_m[0], pts)
    np.testing.assert_allclose(det.sensor_xy_m, [0.5, 0.0])
    merged = merge_overlapping(np.array([[0.0, 0.0], [0.3, 0.0]]), np.array([0.2, 0.2]), np.array([2, 3]), 1.0,
                               [np.zeros((2, 2)), np.ones((3, 2))])
    assert merged.n_points.tolist() == [5] and merged.points_xy_m[0].shape == (5, 2)


@pytest.mark.parametrize("bad", [dict(radius_quantile=1.0), dict(radius_quantile=float("nan")),
                                 dict(radius_step_m=0.0)])
def test_the_radius_quantile_settings_are_checked(bad):
    with pytest.raises(ConfigError, match="radius_quantile"):
        TrackerConfig(**bad)


def _near_arc(centre: np.ndarray, radius_m: float, from_deg: float, to_deg: float, n: int,
              noise_m: float = 0.0, seed: int = 0) -> np.ndarray:
    """n points on a circle between from_deg and to_deg about its side facing the origin, each
    ``noise_m`` (1 sigma) off it radially."""
    back = math.atan2(-centre[1], -centre[0])
    phi = back + np.deg2rad(np.linspace(from_deg, to_deg, n))
    r = radius_m + noise_m * np.random.default_rng(seed).standard_normal(n)
    return centre + r[:, None] * np.column_stack([np.cos(phi), np.sin(phi)])


@pytest.mark.parametrize("seed", range(20))
def test_a_free_circle_fit_is_exact_on_any_noise_free_arc(seed):
    from slamkit.estimation.obstacle_tracker import fit_circle

    rng = np.random.default_rng(seed)
    centre = rng.uniform(-8.0, 8.0, 2)
    radius = rng.uniform(0.1, 1.0)
    span = rng.uniform(20.0, 180.0)
    arc = _near_arc(centre, radius, -span / 2, span / 2, int(rng.integers(3, 40)))
    xy, r, rms = fit_circle(arc)
    np.testing.assert_allclose(xy, centre, atol=1e-7)
    assert r == pytest.approx(radius, abs=1e-7) and rms < 1e-7
    # shifted far away (the algebraic start is computed about the points' mean: no cancellation)
    xy, r, _ = fit_circle(arc + 1e4)
    np.testing.assert_allclose(xy, centre + 1e4, atol=1e-6)


def test_a_free_circle_fit_of_a_line_or_two_points_is_nan():
    from slamkit.estimation.obstacle_tracker import fit_circle

    line = np.column_stack([np.linspace(0.0, 1.0, 10), np.full(10, 2.0)])
    assert math.isnan(fit_circle(line)[1]) and math.isnan(fit_circle(line[:2])[1])


def test_a_centre_in_front_of_the_arc_is_not_behind_it_even_past_a_stray_return():
    from slamkit.estimation.obstacle_tracker import behind_arc

    # a 0.35 m circle at (3, 1) seen from the origin; its mirror image through the arc's middle is
    # 2.53 m away, the arc's points 2.81-2.86 m; two short returns 0.6 m in front of the arc are
    # nearer than the mirror (2.30 m): the nearest point no longer tells the two apart, the median does
    centre = np.array([3.0, 1.0])
    arc = _near_arc(centre, 0.35, -40.0, 40.0, 15)
    mirror = 2.0 * arc.mean(axis=0) - centre
    u = arc[-1] / np.linalg.norm(arc[-1])
    with_strays = np.vstack([arc, arc[-1] - 0.6 * u, arc[-1] - 0.55 * u])
    assert np.linalg.norm(with_strays, axis=1).min() < np.linalg.norm(mirror) < np.linalg.norm(arc, axis=1).min()
    assert behind_arc(centre, with_strays, np.zeros(2)) and not behind_arc(mirror, with_strays, np.zeros(2))
    assert not behind_arc(mirror, arc, np.zeros(2))


@pytest.mark.parametrize("seed", range(10))
def test_the_robust_known_radius_fit_ignores_two_short_returns_in_front_of_a_half_arc(seed):
    from slamkit.estimation.obstacle_tracker import fit_centre_known_radius

    # the half of a 0.35 m disc's near side (the other half hidden, as beside a wall), 2 cm range
    # noise, and two short returns 0.25 and 0.3 m in front of its end joined to its cluster (the
    # office development episode 3048 at 19.7 s): started 7 cm from the centre (a track's
    # prediction), least squares lands 0.16-0.31 m off (seeds 0-19), Cauchy's loss at 3 cm
    # 0.003-0.065 m off
    centre = np.array([3.0, 1.0])
    arc = _near_arc(centre, 0.35, -60.0, 0.0, 10, noise_m=0.02, seed=seed)
    u = arc[-1] / np.linalg.norm(arc[-1])
    pts = np.vstack([arc, arc[-1] - 0.25 * u, arc[-1] - 0.3 * u])
    start = centre + [0.05, -0.05]
    least_squares = fit_centre_known_radius(pts, 0.35, start, np.zeros(2))
    robust = fit_centre_known_radius(pts, 0.35, start, np.zeros(2), robust_scale_m=0.03)
    assert np.linalg.norm(least_squares - centre) > 0.12
    assert np.linalg.norm(robust - centre) < 0.08


@pytest.mark.parametrize("seed", range(5))
def test_a_tracks_radius_from_circle_fits_is_the_discs_within_a_centimetre(seed):
    # the passing disc above (0.35 m, 2 cm range noise): over seeds 0-9 the mean radius 0.344-0.349 m
    # with circle fits (0.352-0.362 m with the extent's 0.9 quantile), the centre 0.006-0.010 m RMS,
    # the velocity 0.016-0.020 m/s RMS (robust loss at 3 cm)
    config = TrackerConfig(known_radius_fit=True, radius_source="circle_fit", fit_robust_scale_m=0.03)
    centre, velocity, radius = _passing_disc_errors(seed, config=config)
    assert 0.34 < radius < 0.355 and centre < 0.015 and velocity < 0.025


@pytest.mark.parametrize("bad", [dict(radius_source="fit"), dict(circle_fit_min_points=2), dict(circle_fit_window=0),
                                 dict(circle_fit_window=20.5), dict(circle_fit_window=True),
                                 dict(circle_fit_min_points=6.5),
                                 dict(circle_fit_max_rms_m=0.0), dict(circle_fit_max_radius_m=float("nan")),
                                 dict(fit_robust_scale_m=0.0), dict(fit_robust_scale_m=float("nan"))])
def test_the_circle_fit_settings_are_checked(bad):
    with pytest.raises(ConfigError, match=next(iter(bad))):
        TrackerConfig(**bad)


def test_a_track_is_born_at_its_first_detections_circle_fit():
    # a noise-free arc (+-40 degrees) of a 0.35 m disc at (3, 1): the detector puts the centre
    # half the extent (0.22 m) behind the nearest point, 0.13 m short; a track with circle fits
    # starts at the disc's centre and radius, one with the extent where the detection is
    centre = np.array([3.0, 1.0])
    det = cluster_points(_near_arc(centre, 0.35, -40.0, 40.0, 15), np.zeros(2), DetectorConfig())
    assert np.linalg.norm(det.xy_m[0] - centre) == pytest.approx(0.13, abs=0.01)
    fitted = ConstantVelocityTracker(TrackerConfig(known_radius_fit=True, radius_source="circle_fit"))
    fitted.update(0.0, det)
    xy, _, radius = fitted.states()
    np.testing.assert_allclose(xy[0], centre, atol=1e-6)
    assert radius[0] == pytest.approx(0.35, abs=1e-6)
    extent = ConstantVelocityTracker(TrackerConfig(known_radius_fit=True))
    extent.update(0.0, det)
    np.testing.assert_allclose(extent.states()[0][0], det.xy_m[0])


@pytest.mark.parametrize("fit", ["fit_circle", "fit_centre_known_radius"])
def test_the_circle_fits_refuse_points_that_are_not_finite(fit):
    import slamkit.estimation.obstacle_tracker as tracker_module
    from slamkit.errors import DataError

    pts = np.array([[0.0, 1.0], [1.0, 2.0], [np.nan, 3.0], [2.0, np.inf]])
    args = (pts,) if fit == "fit_circle" else (pts, 0.3, np.zeros(2), np.array([5.0, 5.0]))
    with pytest.raises(DataError, match=f"{fit}: the points must be finite, got 2"):
        getattr(tracker_module, fit)(*args)
