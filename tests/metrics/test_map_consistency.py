"""Map consistency without ground truth (slamkit.metrics.map_consistency) on a known scene: a
12 m x 8 m hall with a 8 m x 4 m block in the middle (a 2 m wide corridor loop), scanned by a
181-beam, 180 deg lidar (1 cm range noise) from poses every 0.3 m along the corridor's centre
line, two laps. Exact poses make a consistent map; the second lap moved by (0.2, 0.2) m draws
every wall twice, 0.2 m apart; 3 m apart, beyond the distance cap, half the map is seen once only."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import DataError
from slamkit.metrics.map_consistency import map_consistency, world_end_points

OUTER = [(0, 0, 12, 0), (12, 0, 12, 8), (12, 8, 0, 8), (0, 8, 0, 0)]
INNER = [(2, 2, 10, 2), (10, 2, 10, 6), (10, 6, 2, 6), (2, 6, 2, 2)]
ANGLES = np.deg2rad(np.linspace(-90.0, 90.0, 181))


def cast(pose: np.ndarray, segments=OUTER + INNER, max_range_m: float = 20.0) -> np.ndarray:
    """Exact ranges from ``pose`` to the nearest segment along every beam (NaN: none in range)."""
    a = pose[2] + ANGLES
    d = np.column_stack([np.cos(a), np.sin(a)])
    best = np.full(len(a), np.inf)
    for x0, y0, x1, y1 in segments:
        e = np.array([x1 - x0, y1 - y0], float)
        w = np.array([x0, y0], float) - pose[:2]
        den = d[:, 0] * (-e[1]) - d[:, 1] * (-e[0])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[0] * (-e[1]) - w[1] * (-e[0])) / den
            u = (d[:, 0] * w[1] - d[:, 1] * w[0]) / den
        ok = (np.abs(den) > 1e-12) & (t > 1e-9) & (u >= 0) & (u <= 1)
        best = np.where(ok & (t < best), t, best)
    return np.where(best <= max_range_m, best, np.nan)


def tour(laps: int = 2, step_m: float = 0.3) -> np.ndarray:
    """Poses every ``step_m`` along the corridor's centre line, heading along it."""
    corners = np.array([(1, 1), (11, 1), (11, 7), (1, 7), (1, 1)], float)
    pts = []
    for _ in range(laps):
        for p, q in zip(corners[:-1], corners[1:]):
            n = int(round(np.hypot(*(q - p)) / step_m))
            s = np.arange(n)[:, None] / n
            heading = np.arctan2(*(q - p)[::-1])
            pts.append(np.column_stack([p + s * (q - p), np.full(n, heading)]))
    return np.concatenate(pts)


@pytest.fixture(scope="module")
def scans():
    poses = tour()
    rng = np.random.default_rng(0)
    ranges = [cast(p) + rng.normal(0.0, 0.01, len(ANGLES)) for p in poses]
    return poses, [ANGLES] * len(poses), ranges


def test_consistent_map_scores_the_range_noise(scans):
    poses, angles, ranges = scans
    c = map_consistency(poses, angles, ranges)
    # measured: 0.0125 m mean, 0.041 m 95th percentile (the 1 cm range noise of two end points,
    # across the other visit's wall), every end point seen twice
    assert c.mean_m < 0.02 and c.p95_m < 0.06
    assert c.overlap > 0.99
    # the same figure along one pass (pieces within 5 m of travel): measured 0.0102 m
    assert c.same_pass_mean_m < 0.015


def test_doubled_walls_raise_the_figure(scans):
    poses, angles, ranges = scans
    moved = poses.copy()
    moved[len(poses) // 2:, :2] += 0.2  # the second lap, 0.2 m off in x and y
    c0 = map_consistency(poses, angles, ranges)
    c = map_consistency(moved, angles, ranges)
    # measured: 0.159 m mean, 0.210 m 95th percentile (0.05 m off: 0.042 m; 0.1 m: 0.081 m; 0.5 m:
    # 0.379 m): the pairs across the two laps see the 0.2 m, those within a lap the noise
    assert c.mean_m > 5 * c0.mean_m and 0.12 < c.mean_m < 0.2
    assert 0.18 < c.p95_m < 0.25
    # along each lap nothing moved: the floor stays the range noise (measured 0.0133 m, 0.0102 m in
    # place; the pairs across the laps' seam see the 0.2 m), so the doubling reads as 12x its floor
    assert c.same_pass_mean_m < 0.02 and c.mean_m > 8 * c.same_pass_mean_m


def test_rougher_surfaces_raise_the_figure_and_its_floor_together():
    """A scene whose surfaces scatter the end points more (3 cm range noise instead of 1 cm, the
    walls in place) raises the figure over different visits and the same-pass floor alike -- what
    a hedge or a cluttered shelf does to a real log -- while doubled walls raise only the first."""
    poses = tour()
    rng = np.random.default_rng(0)
    ranges = [cast(p) + rng.normal(0.0, 0.03, len(ANGLES)) for p in poses]
    c = map_consistency(poses, [ANGLES] * len(poses), ranges)
    # measured: 0.0185 m over visits, 0.0159 m along a pass (1 cm: 0.0125 / 0.0102 m)
    assert 0.016 < c.mean_m < 0.022 and 0.013 < c.same_pass_mean_m < 0.019
    assert c.mean_m / c.same_pass_mean_m < 1.4


def test_larger_doubling_than_the_cap_lowers_overlap(scans):
    poses, angles, ranges = scans
    moved = poses.copy()
    moved[len(poses) // 2:, :2] += 3.0
    c0, c = map_consistency(poses, angles, ranges), map_consistency(moved, angles, ranges)
    # measured: 0.54 of the end points have another visit within 1 m (1.0 in place)
    assert c.overlap < 0.7 * c0.overlap


def test_query_sample_keeps_the_figure(scans):
    poses, angles, ranges = scans
    full, sample = map_consistency(poses, angles, ranges), map_consistency(poses, angles, ranges, query_every=3)
    assert sample.mean_m == pytest.approx(full.mean_m, rel=0.1)


def test_end_points_and_bad_input():
    pose = np.array([[1.0, 2.0, np.pi / 2]])
    xy, kf, direction, normal = world_end_points(pose, [np.array([0.0, np.pi / 2])], [np.array([2.0, np.nan])])
    np.testing.assert_allclose(xy, [[1.0, 4.0]], atol=1e-12)
    assert kf.tolist() == [0] and direction == pytest.approx([np.pi / 2])
    with pytest.raises(DataError):
        map_consistency(pose, [ANGLES, ANGLES], [ANGLES])
    with pytest.raises(DataError):
        map_consistency(np.array([[np.nan, 0, 0]]), [ANGLES], [ANGLES])
    with pytest.raises(DataError):
        map_consistency(pose, [ANGLES], [ANGLES], max_distance_m=0.0)


def test_normals_are_across_the_wall():
    # a scan of the wall y = 2 from the origin: normals along y, none at the ends
    angles = np.deg2rad([75.0, 90.0, 105.0])
    ranges = 2.0 / np.sin(angles)
    _, _, _, normal = world_end_points(np.zeros((1, 3)), [angles], [ranges])
    assert np.isnan(normal[[0, 2]]).all()
    np.testing.assert_allclose(np.abs(normal[1]), [0.0, 1.0], atol=1e-12)
