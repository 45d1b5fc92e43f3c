"""Ray casting: worked examples, the vectorised caster against the per-beam loop (bit-identical)
and the loop against dense sampling along the ray."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from slamkit.errors import DataError
from slamkit.maps.generators import office, random_free_poses
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.maps.raycast import RayCaster, cast_ray_loop, cast_rays, cast_scan, scan_endpoints


def _room(res=0.1):
    """4 m x 3 m room (40 x 30 cells), one-cell walls, origin (-1, -1)."""
    occ = np.zeros((30, 40), bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    return OccupancyGrid(occ, res, np.array([-1.0, -1.0]))


def test_worked_example_room():
    grid = _room()
    # robot at world (0.55, 0.05), i.e. 1.55 m from the left edge of the grid, 1.05 m above the
    # bottom. Walls: inner faces at x = -0.9 and 2.9, y = -0.9 and 1.9.
    origin = np.array([[0.55, 0.05]])
    angles = np.array([0.0, np.pi / 2, np.pi, -np.pi / 2, np.pi / 4])
    r = cast_rays(grid, np.repeat(origin, 5, axis=0), angles, max_range_m=10.0)
    np.testing.assert_allclose(r[:4], [2.35, 1.85, 1.45, 0.95], atol=1e-9)
    # 45 degrees: the top wall (y = 1.9) is reached first, after 1.85 * sqrt(2)
    assert r[4] == pytest.approx(1.85 * np.sqrt(2), abs=1e-9)
    # max range shorter than the wall distance: no hit -> NaN, or the value asked for
    short = cast_rays(grid, origin, np.array([0.0]), max_range_m=2.0)
    assert np.isnan(short[0])
    assert cast_rays(grid, origin, np.array([0.0]), 2.0, no_hit=2.0)[0] == 2.0
    # inside a wall: range 0
    assert cast_rays(grid, np.array([[-0.95, 0.0]]), np.array([0.3]), 5.0)[0] == 0.0


def test_scan_shapes_sensor_offset_and_endpoints():
    grid = _room()
    poses = np.array([[0.55, 0.05, 0.0], [0.0, 0.0, np.pi / 2]])
    beams = np.array([0.0, np.pi / 2])
    r = cast_scan(grid, poses, beams, 10.0)
    assert r.shape == (2, 2)
    np.testing.assert_allclose(r[0], [2.35, 1.85], atol=1e-9)
    np.testing.assert_allclose(r[1], [1.9, 0.9], atol=1e-9)  # facing +y: forward 1.9, left 0.9
    # a sensor 0.2 m ahead of the body: forward beam shorter by 0.2
    r_off = cast_scan(grid, poses[:1], beams[:1], 10.0, body_p_sensor_xy_m=np.array([0.2, 0.0]))
    assert r_off[0, 0] == pytest.approx(2.15)
    end = scan_endpoints(poses, beams, r)
    np.testing.assert_allclose(end[0, 0], [2.9, 0.05], atol=1e-9)
    np.testing.assert_allclose(end[1, 1], [-0.9, 0.0], atol=1e-9)


def test_bad_input_raises_data_error():
    with pytest.raises(DataError):
        cast_rays(_room(), np.zeros((2, 2)), np.zeros(3), 1.0)
    with pytest.raises(DataError):
        cast_rays(_room(), np.array([[np.nan, 0.0]]), np.zeros(1), 1.0)


@settings(max_examples=60, deadline=None)
@given(occ=arrays(bool, st.tuples(st.integers(1, 12), st.integers(1, 12)),
                  elements=st.booleans()),
       res=st.sampled_from([0.05, 0.1, 0.5, 1.0]),
       seed=st.integers(0, 2**31 - 1),
       max_range=st.floats(0.0, 20.0))
def test_vectorised_equals_per_beam_loop(occ, res, seed, max_range):
    grid = OccupancyGrid(occ, res, np.array([0.3, -0.7]))
    rng = np.random.default_rng(seed)
    n = 40
    h, w = occ.shape
    # origins inside and outside the grid, some axis-aligned and diagonal beams
    origins = grid.origin_xy_m + rng.uniform(-2, [w * res + 2, h * res + 2], size=(n, 2))
    angles = rng.uniform(-np.pi, np.pi, n)
    angles[:8] = [0.0, np.pi / 2, np.pi, -np.pi / 2, np.pi / 4, 3 * np.pi / 4, -np.pi / 4, -3 * np.pi / 4]
    vec = RayCaster(grid, chunk=3).cast(origins, angles, max_range)
    loop = np.array([cast_ray_loop(grid, origins[i], angles[i], max_range) for i in range(n)])
    np.testing.assert_array_equal(vec, loop)


def test_loop_agrees_with_dense_sampling_on_a_generated_office():
    grid = office(np.random.default_rng(3))
    rng = np.random.default_rng(4)
    poses = random_free_poses(grid, rng, 30, clearance_m=0.3)
    beams = np.linspace(-np.pi, np.pi, 24, endpoint=False)
    ranges = RayCaster(grid).scan(poses, beams, 12.0)
    step = 0.002
    t = np.arange(0, 12.0, step)
    checked = 0
    for p, pose in enumerate(poses):
        for b, beam in enumerate(beams):
            a = pose[2] + beam
            pts = pose[:2] + t[:, None] * np.array([np.cos(a), np.sin(a)])
            free = grid.is_free_world(pts) | ~grid.in_bounds(grid.world_to_cell(pts))
            first = np.argmax(~free) if (~free).any() else None
            if first is None:
                assert np.isnan(ranges[p, b])
            else:
                # the sampled first hit lies within one sampling step after the exact entry
                assert ranges[p, b] == pytest.approx(t[first], abs=step + 1e-9)
            checked += 1
    assert checked == 720


def test_raycaster_is_reusable_and_empty_grid_gives_no_hits():
    grid = OccupancyGrid(np.zeros((10, 10), bool), 0.5)
    caster = RayCaster(grid)
    r = caster.cast(np.array([[2.5, 2.5], [1.0, 1.0]]), np.array([0.1, 2.0]), 100.0)
    assert np.all(np.isnan(r))
    assert caster.cast(np.zeros((0, 2)), np.zeros(0), 5.0).shape == (0,)


def test_cast_circles_worked_example():
    from slamkit.maps.raycast import cast_circles

    origins = np.zeros((4, 2))
    angles = np.array([0.0, np.pi / 2, np.pi, np.arctan2(1.0, 4.0)])
    centers = np.array([[3.0, 0.0], [0.0, 10.0]])
    radii = np.array([0.5, 1.0])
    r = cast_circles(origins, angles, centers, radii, max_range_m=8.0)
    assert r[0] == pytest.approx(2.5)          # straight at the first disc
    assert np.isnan(r[1])                       # second disc at 9 m: beyond max range
    assert np.isnan(r[2])                       # behind the robot
    # grazing: the line through (4, 1) passes at distance |4*0 - 1*3| / sqrt(17) = 0.728 m > 0.5
    assert np.isnan(r[3])
    assert cast_circles(np.array([[3.2, 0.0]]), np.array([1.0]), centers, radii, 8.0)[0] == 0.0
    assert cast_circles(origins[1:2], angles[1:2], np.array([[0.0, 10.0]]), radii[1:], 20.0)[0] == pytest.approx(9.0)


def test_bench_raycast_cases_compare_equal_work():
    from slamkit.bench.raycast import run

    cases = run(quick=True)
    assert [c.name for c in cases] == ["raycast_office_1000x1000", "raycast_warehouse_1000x1000",
                                       "raycast_clutter_1000x1000"]
    for c in cases:
        assert c.unit == "beams/s" and c.goal == ">= 30"
        assert c.extra["identical_to_reference"] is True  # the ratio compares equal results
        assert 0.0 <= c.extra["no_hit_fraction"] < 0.2 and 2.0 < c.extra["mean_range_m"] < 15.0
