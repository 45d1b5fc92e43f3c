"""Planning under localisation uncertainty (issue 14, the course's section 11.4): the passage
hall, the lidar's blind boxes, and the covariance-aware stack's fallback to the largest chance
margin that still leaves a path, as worked examples."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from slamkit.errors import ConfigError, DataError
from slamkit.estimation.obstacle_tracker import Tracks
from slamkit.experiments.navigation import EpisodeConfig, make_navigation_scenario
from slamkit.maps.generators import PassageHallConfig, passage_hall
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.navigation_world import NavigationPlant
from slamkit.systems.navigation import GlobalPlanningConfig, NavigationConfig, NavigationStack


def _wall_with_gap() -> OccupancyGrid:
    """6 m x 4 m at 5 cm; a wall across at x = 3 m (3 cells) with an 11-cell (0.55 m) gap in
    rows 35..45, so the gap's middle row is 6 cells = 0.30 m from the wall cells' centres."""
    occ = np.zeros((80, 120), bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    occ[:, 60:63] = True
    occ[35:46, 60:63] = False
    return OccupancyGrid(occ, 0.05)


def test_passage_hall_has_an_exact_narrow_gap_and_the_wide_door_at_the_far_end():
    for seed in range(4):
        g = passage_hall(np.random.default_rng(seed))
        assert (g.width, g.height) == (240, 120)
        col = g.occupied[:, g.width // 2]
        free = np.flatnonzero(~col)
        runs = np.split(free, np.flatnonzero(np.diff(free) > 1) + 1)
        widths = sorted(len(r) for r in runs)
        assert widths == [11, 24]  # 0.55 m and 1.2 m
        gap = next(r for r in runs if len(r) == 11)
        door = next(r for r in runs if len(r) == 24)
        assert 2.2 - 0.05 <= 0.05 * gap.mean() <= 3.8 + 0.05
        # the door sits at the end farther from the gap
        assert abs(door.mean() - gap.mean()) > 1.5
    with pytest.raises(DataError):
        passage_hall(np.random.default_rng(0), PassageHallConfig(narrow_width_m=0.57))


def test_the_lidar_returns_nothing_inside_a_blind_box():
    sc = make_navigation_scenario(0, "passage", n_obstacles=0)
    blind = NavigationPlant(sc, np.random.default_rng(0), lidar_blind_boxes_m=[[0.0, 0.0, 3.0, 6.0]])
    seeing = NavigationPlant(sc, np.random.default_rng(0), lidar_blind_boxes_m=[[8.0, 0.0, 12.0, 6.0]])
    assert sc.start_xytheta[0] < 3.0 and blind.lidar_blind() and not seeing.lidar_blind()
    assert np.isnan(blind.scan(0.0).ranges_m).all()
    assert np.isfinite(seeing.scan(0.0).ranges_m).mean() > 0.9
    with pytest.raises(ConfigError, match="lidar_blind_boxes_m"):
        EpisodeConfig(lidar_blind_boxes_m=((1.0, 0.0, 0.5, 2.0),))


def test_an_infeasible_chance_margin_falls_back_to_the_largest_feasible_one():
    cfg = NavigationConfig(uncertainty="covariance", collision_probability=0.05, planning=GlobalPlanningConfig(path_margin_m=0.05))
    stack = NavigationStack(_wall_with_gap(), cfg)
    stack.reset([1.0, 2.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    stack.set_goal([5.0, 2.0, 0.0])
    none = Tracks(np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros((0, 4, 4)))
    # sigma 1 cm: k sigma = 1.645 cm -> 2 cm; inscribed 0.27 < 0.30 m: the gap is open, k as asked
    assert stack.planning.plan(np.array([1.0, 2.0, 0.0]), np.diag([1e-4, 1e-4, 0.0]), none, np.zeros(0, int))
    assert stack.chance_k == pytest.approx(1.644854, abs=1e-6) and stack.chance_fallbacks == 0
    assert np.abs(stack.path[:, 1] - 2.0).max() < 0.1  # straight through the gap
    # sigma 10 cm: k sigma = 16.45 -> 17 cm closes the gap (0.25 + 0.17 > 0.30); the largest
    # margin that leaves it open is 4 cm (inscribed 0.29 < 0.30; 5 cm reaches the wall cells'
    # 0.30), i.e. k = 1.645 * 4 / 17 = 0.387, a planned collision probability of 0.349
    assert stack.planning.plan(np.array([1.0, 2.0, 0.0]), np.diag([0.01, 0.01, 0.0]), none, np.zeros(0, int))
    assert stack.chance_k == pytest.approx(1.644854 * 4 / 17, abs=1e-6) and stack.chance_fallbacks == 1
    assert stack.planned_collision_probability_max == pytest.approx(norm.sf(1.644854 * 4 / 17), abs=1e-6)
    assert stack.planned_collision_probability_max == pytest.approx(0.3494, abs=1e-3)
    assert np.isnan(NavigationStack(_wall_with_gap()).planned_collision_probability_max)  # fixed inflation


def test_narrow_passages_plans_a_passage_narrower_than_the_path_margin_with_the_widest_margin_that_fits():
    # the gap's middle row is 0.30 m from the wall cells' centres: the costmap's inscribed radius
    # 0.2 + 0.15 closes it and no other way exists. The local planner needs 0.2 + its 0.05 m from
    # the walls' surface, half a cell (2.5 cm) nearer than their cells' centres, so the path margin
    # may be lowered to 0.08 m (whole centimetres, not under 0.075); it is lowered to the widest that leaves the
    # gap open, 0.09 m (inscribed 0.29; 0.30 reaches the wall cells) -- not the bare map, whose
    # path grazes the wall cells
    none = Tracks(np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros((0, 4, 4)))
    narrowing = NavigationConfig(planning=GlobalPlanningConfig(narrow_passages=True))
    stack = NavigationStack(_wall_with_gap(), narrowing)
    stack.reset([1.0, 1.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    stack.set_goal([5.0, 3.0, 0.0])
    assert stack.planning.plan(np.array([1.0, 1.0, 0.0]), np.diag([1e-4, 1e-4, 0.0]), none, np.zeros(0, int))
    assert (stack.narrowed_plans, stack.bare_map_plans) == (1, 0)
    assert stack.planning.path_margin_m == pytest.approx(0.09, abs=1e-9)
    in_gap = stack.path[np.abs(stack.path[:, 0] - 3.075) <= 0.1]
    assert len(in_gap) and np.allclose(in_gap[:, 1], 2.025)  # the gap's middle row, 0.30 m from both sides
    # a gap of 0.45 m (middle 0.25 m from the wall cells, under 0.28) the local planner cannot pass: the bare map
    occ = _wall_with_gap().occupied.copy()
    occ[35, 60:63] = occ[45, 60:63] = True
    narrow = NavigationStack(OccupancyGrid(occ, 0.05), narrowing)
    narrow.reset([1.0, 1.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    narrow.set_goal([5.0, 3.0, 0.0])
    assert narrow.planning.plan(np.array([1.0, 1.0, 0.0]), np.diag([1e-4, 1e-4, 0.0]), none, np.zeros(0, int))
    assert (narrow.narrowed_plans, narrow.bare_map_plans) == (0, 1) and np.isnan(narrow.planning.path_margin_m)
    # a robot standing 0.3 m from a wall (inside the 0.35 m inscribed radius) in open space plans
    # its way out with the configured margin beyond its neighbourhood: no bare map
    open_ = NavigationStack(_wall_with_gap(), narrowing)
    open_.reset([1.0, 0.4, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    open_.set_goal([1.5, 3.0, 0.0])
    assert open_.planning.plan(np.array([1.0, 0.4, 0.0]), np.diag([1e-4, 1e-4, 0.0]), none, np.zeros(0, int))
    assert (open_.narrowed_plans, open_.bare_map_plans) == (1, 0) and open_.planning.path_margin_m == 0.15
    clearance = open_.distance.query(open_.path)[0]
    assert clearance[5:].min() > 0.35  # off the wall within its first few cells
    # off (the default): the bare map for the gap, its path grazing the wall cells
    bare = NavigationStack(_wall_with_gap(), NavigationConfig())
    bare.reset([1.0, 1.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
    bare.set_goal([5.0, 3.0, 0.0])
    assert bare.planning.plan(np.array([1.0, 1.0, 0.0]), np.diag([1e-4, 1e-4, 0.0]), none, np.zeros(0, int))
    assert (bare.narrowed_plans, bare.bare_map_plans) == (0, 1)
    assert bare.distance.query(bare.path)[0].min() < 0.1


def test_paired_variants_table_differences_by_seed():
    from slamkit.experiments.navigation import Episode, _variants, paired_variants_markdown

    config = {"variants": [{"name": "fixed"}, {"name": "covariance", "paired_with": "fixed"}]}
    assert [n for n, _, _ in _variants(config)] == ["fixed", "covariance"]
    with pytest.raises(ConfigError, match="paired_with"):
        _variants({"variants": [{"name": "a", "paired_with": "b"}]})
    base = {m: 0.0 for m in ("success", "collision_static", "collision_moving", "min_clearance_static_m",
                             "time_s", "path_length_m", "localisation_error_max_m")}
    eps = [Episode(f"passage_{s}", "passage", s, v, np.zeros(1), np.zeros((1, 3)), np.zeros((1, 3)),
                   {**base, "path_length_m": length})
           for s, v, length in ((0, "fixed", 8.0), (0, "covariance", 10.0), (1, "fixed", 8.5),
                                (1, "covariance", 11.5), (2, "fixed", 9.0))]
    text = paired_variants_markdown(config["variants"], eps)
    # seeds 0 and 1 are paired (seed 2 has no covariance run): +2.0 and +3.0 m -> mean 2.5
    row = next(line for line in text.splitlines() if "path_length_m" in line)
    assert "covariance - fixed" in row and "| 2 |" in row and "2.5" in row


def test_local_tightening_never_puts_the_estimate_inside_an_obstacle():
    from slamkit.control.chance_constraints import worst_sigma_m

    occ = np.zeros((80, 120), bool)  # 6 m x 4 m, walls 2 cells thick: surfaces at x = 0.1 m ...
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    stack = NavigationStack(OccupancyGrid(occ, 0.05), NavigationConfig(uncertainty="covariance"))
    # ... so an estimate at x = 0.45 m has 0.35 m to the wall: beyond the 0.2 m disc and DWA's
    # 0.05 m margin, 0.10 m of room. sigma ~ 10 cm wants k sigma = 16 cm: k drops to 0.10 / sigma
    stack.reset([0.45, 2.0, 0.0], np.diag([0.01, 0.01, 1e-4]))
    stack.set_goal([5.0, 2.0, 0.0])
    sigma = worst_sigma_m(stack.current_pose()[1])
    assert 0.08 < sigma < 0.12
    stack.command(0.0)
    # (the particle mean is within a few millimetres of x = 0.45 m)
    assert stack.chance_k_min == pytest.approx(0.10 / sigma, rel=5e-3)
    assert stack.planned_collision_probability_max == pytest.approx(norm.sf(stack.chance_k_min), rel=1e-9)
