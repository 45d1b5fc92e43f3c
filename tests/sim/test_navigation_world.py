"""The navigation world's draws and the kidnapped robot (issue 30, item 4: simulation in
slamkit.sim; the route between a start and a goal is the caller's planner)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from slamkit.maps.distance_field import distance_field_m
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.moving_obstacles import MovingObstacles
from slamkit.sim.navigation_world import NavigationPlant, NavigationScenario, passage_draws, start_goal_draws


def _room(size_m: float = 10.0, resolution_m: float = 0.05) -> OccupancyGrid:
    n = int(round(size_m / resolution_m))
    occ = np.zeros((n, n), bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True   # walls 0.1 m thick
    return OccupancyGrid(occ, resolution_m, np.zeros(2), name="room")


def _plant(grid: OccupancyGrid, start) -> NavigationPlant:
    sc = NavigationScenario("room", 0, grid, np.asarray(start, float), np.array([5.0, 5.0, 0.0]),
                            np.zeros((0, 2)), MovingObstacles.empty())
    return NavigationPlant(sc, np.random.default_rng(0))


def test_kidnap_shifts_in_the_body_frame_or_the_other_way_out_of_a_wall():
    grid = _room()
    field_m = distance_field_m(grid)
    plant = _plant(grid, [5.0, 5.0, np.pi / 2])
    assert plant.kidnap(np.array([0.3, 0.0]), 0.0, 0.2, field_m)
    np.testing.assert_allclose(plant.world_xytheta_body, [5.0, 5.3, np.pi / 2], atol=1e-12)
    # facing the wall 0.45 m away: 0.3 m forward leaves 0.05 m to the wall's face, minus the
    # radius -- in the wall -- so the robot is moved 0.3 m back instead
    plant = _plant(grid, [0.55, 5.0, np.pi])
    assert plant.kidnap(np.array([0.3, 0.0]), 0.0, 0.2, field_m)
    np.testing.assert_allclose(plant.world_xytheta_body, [0.85, 5.0, np.pi], atol=1e-12)
    # across a corridor 1.2 m wide (walls 0.1 m thick) a 0.5 m shift lands in a wall either way:
    # nothing moves
    occ = np.zeros((200, 24), bool)
    occ[:, :2] = occ[:, -2:] = True
    corridor = OccupancyGrid(occ, 0.05, np.zeros(2), name="corridor")
    plant = _plant(corridor, [0.6, 5.0, 0.0])
    assert not plant.kidnap(np.array([0.5, 0.0]), 0.0, 0.2, distance_field_m(corridor))
    np.testing.assert_array_equal(plant.world_xytheta_body, [0.6, 5.0, 0.0])


def test_start_goal_draws_keep_the_distance_band_and_ask_the_route():
    grid = _room()
    asked = []

    def route(a, b):
        asked.append((a.copy(), b.copy()))
        d = float(np.linalg.norm(a - b))
        return SimpleNamespace(solved=True, length_m=1.5 * d, path=np.vstack([a, b]))

    draws = list(start_goal_draws(grid, np.random.default_rng(3), route, 0.2, (3.0, 6.0), 50))
    assert draws and len(asked) == len(draws)        # a route 1.5x the distance is always short enough
    for poses, res in draws:
        d = np.linalg.norm(poses[0, :2] - poses[1, :2])
        assert 3.0 <= d <= 6.0 and res.solved
        assert np.all((poses[:, :2] > 0.8) & (poses[:, :2] < 9.2))   # 0.5 m beyond the radius from the walls
    # a route longer than twice the longest distance is refused; an unsolved one too
    assert not list(start_goal_draws(grid, np.random.default_rng(3), lambda a, b: SimpleNamespace(
        solved=True, length_m=12.5, path=None), 0.2, (3.0, 6.0), 50))
    assert not list(passage_draws(grid, np.random.default_rng(3), lambda a, b: SimpleNamespace(
        solved=False, length_m=np.inf, path=None), 20))


def test_passage_draws_put_start_and_goal_at_either_end():
    grid = _room(12.0)
    route = lambda a, b: SimpleNamespace(solved=True, length_m=float(np.linalg.norm(a - b)), path=None)  # noqa: E731
    for poses, _ in list(passage_draws(grid, np.random.default_rng(0), route, 10)):
        assert 1.0 <= poses[0, 0] <= 2.5 and 9.5 <= poses[1, 0] <= 11.0
        assert 1.2 <= poses[0, 1] <= 10.8 and poses[0, 2] == 0.0


@pytest.mark.parametrize("seed", [0, 1])
def test_draws_are_seeded(seed):
    grid = _room()
    route = lambda a, b: SimpleNamespace(solved=True, length_m=1.0, path=None)  # noqa: E731
    a = [p for p, _ in start_goal_draws(grid, np.random.default_rng(seed), route, 0.2, (2.0, 8.0), 20)]
    b = [p for p, _ in start_goal_draws(grid, np.random.default_rng(seed), route, 0.2, (2.0, 8.0), 20)]
    assert len(a) == len(b) > 0 and all(np.array_equal(x, y) for x, y in zip(a, b))


def test_discs_seen_counts_the_beams_that_end_on_each_disc_and_not_the_hidden_ones():
    """The last scan's noise-free beams (1 deg apart, one at 0 deg) per disc, robot at (5, 5)
    facing +x: a disc of 0.3 m 2 m ahead spans +-asin(0.3 / 2) = +-8.6 deg (17 beams); one of 0.2 m
    2 m behind spans +-5.7 deg (11 beams); one of 0.3 m 4 m ahead hides behind the first, and one
    3 m to the left behind a wall 1.5 m away -- 0 beams each."""
    occ = _room().occupied.copy()
    occ[int(6.4 / 0.05):int(6.5 / 0.05), int(4.0 / 0.05):int(6.0 / 0.05)] = True  # the wall
    grid = OccupancyGrid(occ, 0.05, np.zeros(2), name="room")
    centres = np.array([[7.0, 5.0], [3.0, 5.0], [9.0, 5.0], [5.0, 8.0]])
    discs = MovingObstacles(centres, centres, np.zeros(4), np.array([0.3, 0.2, 0.3, 0.3]), np.zeros(4))
    sc = NavigationScenario("room", 0, grid, np.array([5.0, 5.0, 0.0]), np.array([5.0, 5.0, 0.0]),
                            np.zeros((0, 2)), discs)
    plant = NavigationPlant(sc, np.random.default_rng(0))
    t_s, beams = plant.discs_seen()
    assert np.isnan(t_s) and beams.tolist() == [0, 0, 0, 0]  # no scan yet
    plant.scan(1.5)
    t_s, beams = plant.discs_seen()
    assert t_s == 1.5 and beams.tolist() == [17, 11, 0, 0]
    plant.blind_boxes_m = np.array([[4.0, 4.0, 6.0, 6.0]])  # a blind scan sees nothing
    plant.scan(1.6)
    assert plant.discs_seen()[1].tolist() == [0, 0, 0, 0]
