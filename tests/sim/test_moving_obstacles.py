"""Moving obstacles: closed-form shuttle motion and seeded crossing generation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import DataError
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.moving_obstacles import MovingObstacles, crossing_obstacles


def _one(phase=0.0):
    # A = (0, 0), B = (4, 0), 1 m/s: at B after 4 s, back at A after 8 s
    return MovingObstacles([[0.0, 0.0]], [[4.0, 0.0]], [1.0], [0.3], [phase])


def test_shuttle_positions_and_velocities():
    obs = _one()
    np.testing.assert_allclose(obs.position_at(0.0), [[0.0, 0.0]])
    np.testing.assert_allclose(obs.position_at(1.5), [[1.5, 0.0]])
    np.testing.assert_allclose(obs.position_at(5.0), [[3.0, 0.0]])   # 4 m out, 1 m back
    np.testing.assert_allclose(obs.position_at(8.0), [[0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(obs.velocity_at(1.0), [[1.0, 0.0]])
    np.testing.assert_allclose(obs.velocity_at(5.0), [[-1.0, 0.0]])
    # phase 0.5 starts half way
    np.testing.assert_allclose(_one(0.5).position_at(0.0), [[2.0, 0.0]])


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 30.0), st.floats(0.0, 1.99))
def test_velocity_is_derivative_of_position(t, phase):
    obs = _one(phase)
    h = 1e-6
    fd = (obs.position_at(t + h) - obs.position_at(t - h)) / (2 * h)
    # away from the turning points the finite difference equals the reported velocity
    s = (phase + t / 4.0) % 2.0
    if min(abs(s - 1.0), s, 2.0 - s) > 1e-4:
        np.testing.assert_allclose(fd, obs.velocity_at(t), atol=1e-5)
    # and the obstacle never leaves its segment
    assert 0.0 - 1e-12 <= obs.position_at(t)[0, 0] <= 4.0 + 1e-12


def test_bad_lengths_raise():
    with pytest.raises(DataError):
        MovingObstacles([[0, 0]], [[1, 0], [2, 0]], [1.0], [0.3], [0.0])


def test_crossing_obstacles_cross_the_path_on_time():
    """Straight path y = 0 from x = 0 to 10, nominal 0.5 m/s, no jitter: each obstacle is on the
    path (|y| < 1e-9) when the robot arrives at its crossing x, i.e. at t = x / 0.5."""
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    obs = crossing_obstacles(path, 3, np.random.default_rng(7), timing_jitter_s=0.0)
    assert len(obs) == 3
    crossing_x = 0.5 * (obs.a_xy_m[:, 0] + obs.b_xy_m[:, 0])
    np.testing.assert_allclose(obs.a_xy_m[:, 0], obs.b_xy_m[:, 0])  # perpendicular to the path
    assert np.all((crossing_x >= 2.0) & (crossing_x <= 8.0))
    for i, x in enumerate(crossing_x):
        p = obs.position_at(x / 0.5)[i]
        assert abs(p[1]) < 1e-9 and p[0] == pytest.approx(x)
    # same seed, same obstacles
    again = crossing_obstacles(path, 3, np.random.default_rng(7), timing_jitter_s=0.0)
    np.testing.assert_array_equal(obs.a_xy_m, again.a_xy_m)


def test_crossing_segments_stay_in_free_space():
    """A 2 m wide corridor (walls at |y| >= 1): every segment is cut so the disc stays free,
    i.e. |y| + r <= 1 along the whole segment."""
    res = 0.05
    occ = np.zeros((80, 240), dtype=bool)
    ys = (np.arange(80) + 0.5) * res - 2.0
    occ[np.abs(ys) >= 1.0, :] = True
    grid = OccupancyGrid(occ, res, np.array([-1.0, -2.0]))
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    obs = crossing_obstacles(path, 4, np.random.default_rng(1), grid=grid, radius_m=(0.2, 0.3))
    assert len(obs) >= 2
    ends = np.concatenate([obs.a_xy_m, obs.b_xy_m])
    radii = np.concatenate([obs.radius_m, obs.radius_m])
    assert np.all(np.abs(ends[:, 1]) + radii <= 1.0)
