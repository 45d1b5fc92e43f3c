"""Social-force crossing traffic: worked examples of the people and the forklift."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import DataError
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.social_force import Agent, SocialForceAgents, crossing_traffic, social_crossings


def _person(route, speed=1.0, dwell=None, start=None, **kw):
    route = np.asarray(route, float)
    dwell = np.zeros(len(route)) if dwell is None else np.asarray(dwell, float)
    return Agent("person", kw.pop("radius_m", 0.25), route, np.full(len(route) - 1, speed), dwell,
                 route[0] if start is None else np.asarray(start, float), **kw)


def _corridor(half_width_m: float) -> OccupancyGrid:
    """Walls at |y| >= half_width_m, x in [-1, 11], 5 cm cells."""
    res = 0.05
    ny = int(round(2 * (half_width_m + 0.5) / res))
    ys = (np.arange(ny) + 0.5) * res - (half_width_m + 0.5)
    occ = np.zeros((ny, 240), dtype=bool)
    occ[np.abs(ys) >= half_width_m, :] = True
    return OccupancyGrid(occ, res, np.array([-1.0, -(half_width_m + 0.5)]))


def test_lone_agent_reaches_its_goal_at_its_desired_speed():
    """From rest at (0, 0) towards (10, 0) at 1 m/s, tau 0.5 s, Euler steps of 0.05 s: v after
    n steps = 1 - (1 - 0.05 / 0.5)^n -- 0.878 m/s at 1 s, 0.988 at 2 s (the continuous
    1 - exp(-t / tau): 0.865, 0.982) -- cruising at 1 m/s mid-way, and it reaches (10, 0)
    (braking into its turning point) before it walks back."""
    sim = SocialForceAgents([_person([[0, 0], [10, 0]])])
    assert sim.velocity_at(1.0)[0, 0] == pytest.approx(1 - 0.9**20, abs=1e-9)
    assert sim.velocity_at(2.0)[0, 0] == pytest.approx(1 - 0.9**40, abs=1e-9)
    assert np.linalg.norm(sim.velocity_at(5.0)[0]) == pytest.approx(1.0, abs=1e-3)
    xs = np.array([sim.position_at(t)[0] for t in np.arange(0.0, 14.0, 0.05)])
    assert xs[:, 0].max() == pytest.approx(10.0 - 0.25, abs=0.1)  # within arrive_m of the goal
    assert np.abs(xs[:, 1]).max() < 1e-9
    assert sim.velocity_at(13.0)[0, 0] < -0.5  # and it walks back


def test_two_agents_head_on_pass_without_overlap():
    """Head on along y = 0 (5 cm apart sideways), 1 m/s each: they swerve and pass, never
    closer than the sum of their radii (0.5 m), and both get past each other."""
    a = _person([[0, 0], [10, 0]])
    b = _person([[10, 0.05], [0, 0.05]])
    sim = SocialForceAgents([a, b])
    gaps = [np.linalg.norm(np.diff(sim.position_at(t), axis=0)) for t in np.arange(0.0, 9.0, 0.05)]
    assert min(gaps) > 0.5
    end = sim.position_at(9.0)
    assert end[0, 0] > 8.0 and end[1, 0] < 2.0


def test_agent_next_to_a_wall_keeps_clearance():
    """Walking along a corridor wall (wall face at y = -1, route at y = -0.6, radius 0.25: the
    disc would clear the wall by 0.15 m): the wall's potential pushes it out, it never touches
    the wall and walks a little further from it than its route."""
    grid = _corridor(1.0)
    sim = SocialForceAgents([_person([[0, -0.6], [9, -0.6]])], grid)
    ys = np.array([sim.position_at(t)[0, 1] for t in np.arange(0.0, 9.0, 0.1)])
    assert (ys - 0.25 > -1.0 + 0.1).all()  # at least 10 cm between the disc and the wall face
    assert ys[30:].mean() > -0.6  # pushed off its route, away from the wall


def test_forklift_drives_then_reverses():
    """A forklift from (0, 0) to (5, 0) at 0.5 m/s, 1 s at each end: it drives forwards (heading
    0, velocity +x), then reverses back (velocity -x) with its heading still 0 -- it does not
    turn round."""
    f = Agent("forklift", 0.4, np.array([[0.0, 0.0], [5.0, 0.0]]), np.array([0.5]), np.array([1.0, 1.0]),
              np.array([0.0, 0.0]))
    sim = SocialForceAgents([f])
    assert sim.velocity_at(5.0)[0, 0] == pytest.approx(0.5, abs=1e-6)
    back = [t for t in np.arange(5.0, 20.0, 0.1) if sim.velocity_at(t)[0, 0] < -0.4]
    assert back, "it never reversed"
    t = back[0] + 1.0
    assert sim.velocity_at(t)[0, 0] == pytest.approx(-0.5, abs=0.01)
    assert abs(sim.headings_at(t)[0]) < 1e-6
    assert sim.position_at(t)[0, 0] < 4.8


def test_people_partially_avoid_the_robot():
    """A person walking at a robot standing on its route (0.5 regard) swerves and passes it
    without contact; with no regard it walks into it (the body force stops the overlap only at
    contact)."""
    def closest(regard: float) -> float:
        sim = SocialForceAgents([_person([[0, 0], [8, 0.02]], regard_robot=regard)])
        gaps = []
        for t in np.arange(0.0, 8.0, 0.1):
            sim.observe_robot(t, np.array([4.0, 0.0]), 0.2)
            gaps.append(np.linalg.norm(sim.position_at(t)[0] - [4.0, 0.0]) - 0.45)
        return min(gaps)

    assert closest(0.5) > 0.05
    assert closest(0.0) < closest(0.5)


def test_same_seed_same_traffic_and_episodes_are_independent():
    path = np.array([[0.0, 0.0], [12.0, 0.0]])
    grid = _corridor(4.0)
    one = social_crossings(path, 3, np.random.default_rng(5), grid=grid)
    two = social_crossings(path, 3, np.random.default_rng(5), grid=grid)
    ts = np.arange(0.0, 30.0, 0.5)
    np.testing.assert_array_equal(np.array([one.position_at(t) for t in ts]),
                                  np.array([two.position_at(t) for t in ts]))
    # a fresh episode does not see the robot another one saw
    ep = one.episode()
    ep.observe_robot(0.0, one.position_at(10.0)[0] + [0.5, 0.0], 0.2)
    np.testing.assert_array_equal(one.episode().position_at(12.0), one.position_at(12.0))
    assert crossing_traffic("constant_velocity", path, 2, np.random.default_rng(5)).episode().position_at(1.0).shape \
        == (2, 2)


def test_bad_agents_are_data_errors():
    with pytest.raises(DataError):
        Agent("bicycle", 0.3, np.zeros((2, 2)), np.ones(1), np.zeros(2), np.zeros(2))
    with pytest.raises(DataError):
        _person([[0, 0], [1, 0]], speed=0.0)
    with pytest.raises(DataError):
        crossing_traffic("teleport", np.array([[0.0, 0.0], [5.0, 0.0]]), 1, np.random.default_rng(0))
    with pytest.raises(DataError):
        SocialForceAgents([_person([[0, 0], [1, 0]])]).position_at(-1.0)
