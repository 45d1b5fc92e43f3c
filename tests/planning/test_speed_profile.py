"""The speed plan along a path (slamkit.planning.speed_profile): a worked example on a free path,
a crossing it must pass behind, equality with an exhaustive search of every acceleration
sequence, the rest rule, and refused inputs."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from slamkit.errors import DataError
from slamkit.planning.speed_profile import plan_speed_along_path

SPACING_M, DT_S, V_MAX, ACCEL = 0.05, 0.2, 0.65, 0.5


def _free(n_steps: int = 30, n_cells: int = 121) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros((n_steps + 1, n_cells), bool), np.ones(n_cells, bool)


def test_free_path_worked_example():
    # speed levels 0.65 / 7 apart (the fewest with a step <= 0.5 m/s^2 * 0.2 s = 0.1 m/s); from
    # rest, one level a step: after 7 steps (1.4 s) 0.2 * (0.65 / 7) * 49 / 2 = 0.455 m at
    # 0.65 m/s, then 0.13 m a step: 3 m after 7 + ceil(2.545 / 0.13) = 27 steps = 5.4 s
    blocked, rest = _free()
    plan = plan_speed_along_path(blocked, rest, SPACING_M, DT_S, 0.0, V_MAX, ACCEL, 3.0)
    assert plan.feasible and plan.unhindered
    assert plan.arrival_s == pytest.approx(5.4)
    assert plan.speed_mps[:8] == pytest.approx(np.arange(8) * V_MAX / 7)
    assert plan.arc_m[7] == pytest.approx(0.2 * V_MAX / 7 * 49 / 2)
    assert plan.arc_m[-1] >= 3.0 > plan.arc_m[-2]


def test_a_crossing_is_passed_behind_at_the_earliest_time():
    # a lane at 1.5-2.3 m ahead is covered from 1 to 3 s; the robot at cruise speed would be in it
    # at 2.3 s. It cannot clear it before 1 s, so it must still be short of it at 3 s (its cells
    # are 5 cm: arc < 1.475 m) and then needs 1.5 m more at most 0.65 m/s: arrival >= 5.31 s; the
    # plan arrives at 5.4 s, the next step on the 0.2 s lattice
    blocked, _ = _free()
    arc = np.arange(blocked.shape[1]) * SPACING_M
    t = np.arange(blocked.shape[0]) * DT_S
    lane = (arc >= 1.5) & (arc <= 2.3)
    blocked[np.ix_((t >= 1.0 - 1e-9) & (t <= 3.0 + 1e-9), lane)] = True
    plan = plan_speed_along_path(blocked, ~lane, SPACING_M, DT_S, V_MAX, V_MAX, ACCEL, 3.0)
    assert plan.feasible and plan.arrival_s == pytest.approx(5.4) and not plan.unhindered
    cells = np.minimum(np.round(plan.arc_m / SPACING_M).astype(int), len(arc) - 1)
    assert not blocked[np.arange(len(cells)), cells].any()
    assert (np.abs(np.diff(plan.speed_mps)) <= V_MAX / 7 + 1e-9).all()
    assert (np.diff(plan.arc_m) >= 0).all()


def test_the_robot_stands_still_only_where_it_may_rest():
    # the lane is covered from 0 to 4 s and the robot may rest only in the first 0.5 m: it stops
    # there (not right at the lane's edge, 1.45 m) and waits; its plan ends the 6 s in reach of the
    # goal only after the lane clears
    blocked, _ = _free()
    arc = np.arange(blocked.shape[1]) * SPACING_M
    t = np.arange(blocked.shape[0]) * DT_S
    lane = (arc >= 1.5) & (arc <= 2.3)
    blocked[np.ix_(t <= 4.0 + 1e-9, lane)] = True
    rest = arc <= 0.5
    plan = plan_speed_along_path(blocked, rest, SPACING_M, DT_S, 0.0, V_MAX, ACCEL, 3.0)
    assert plan.feasible and math.isinf(plan.arrival_s)
    stopped = plan.speed_mps[1:] == 0.0
    assert stopped.any() and (plan.arc_m[1:][stopped] <= 0.5 + 0.5 * SPACING_M).all()
    # with rest everywhere it waits at the lane instead, and gets further by the horizon
    anywhere = plan_speed_along_path(blocked, np.ones_like(rest), SPACING_M, DT_S, 0.0, V_MAX, ACCEL, 3.0)
    assert anywhere.arc_m[-1] > plan.arc_m[-1]


def test_infeasible_when_the_robot_is_covered_or_cannot_stop_in_time():
    blocked, rest = _free()
    blocked[0, 0] = True  # covered where it stands
    assert not plan_speed_along_path(blocked, rest, SPACING_M, DT_S, 0.0, V_MAX, ACCEL, 3.0).feasible
    # at cruise speed, 0.1 m short of a wall of time (covered the whole horizon), may rest nowhere
    # beyond: it needs 0.42 m to stop
    blocked, rest = _free()
    blocked[:, 2:] = True
    plan = plan_speed_along_path(blocked, rest, SPACING_M, DT_S, V_MAX, V_MAX, ACCEL, 3.0)
    assert not plan.feasible and math.isnan(plan.next_speed_mps)


def _exhaustive_arrival(blocked, rest, v0_level, n_levels, goal_m):
    """Every sequence of level changes (-1, 0, +1): the earliest arrival, or whether some sequence
    survives the horizon able to stop (None: infeasible)."""
    levels = np.linspace(0.0, V_MAX, n_levels + 1)
    n_cells = len(rest)
    room = np.array([(np.argmin(rest[i:]) if not rest[i:].all() else n_cells - i) - 1 for i in range(n_cells)],
                    float) * SPACING_M
    best, survives = math.inf, False
    for seq in itertools.product((-1, 0, 1), repeat=blocked.shape[0] - 1):
        arc, lv = 0.0, v0_level
        for k, d in enumerate(seq, start=1):
            nl = min(max(lv + d, 0), n_levels)
            arc += 0.5 * (levels[lv] + levels[nl]) * DT_S
            lv = nl
            i = min(int(round(arc / SPACING_M)), n_cells - 1)
            if blocked[k, i] or (lv == 0 and not rest[i]):
                break
            if arc >= goal_m:
                best = min(best, k * DT_S)
                break
        else:
            i = min(int(round(arc / SPACING_M)), n_cells - 1)
            survives |= bool(rest[i]) and levels[lv] ** 2 / (2 * ACCEL) <= room[i] + 1e-9
    if math.isfinite(best):
        return best
    return math.inf if survives else None


@pytest.mark.parametrize("seed", range(12))
def test_equals_an_exhaustive_search_of_every_acceleration_sequence(seed):
    rng = np.random.default_rng(seed)
    n_steps, n_cells = 7, 16
    blocked = rng.random((n_steps + 1, n_cells)) < 0.1 + 0.03 * seed  # denser tables for later seeds
    blocked[0, 0] = False
    rest = rng.random(n_cells) < 0.7
    rest[0] = True
    v0 = float(rng.choice(np.linspace(0.0, V_MAX, 8)))
    goal = float(rng.uniform(0.2, 0.7))
    plan = plan_speed_along_path(blocked, rest, SPACING_M, DT_S, v0, V_MAX, ACCEL, goal, bucket_m=1e-9)
    expected = _exhaustive_arrival(blocked, rest, int(round(v0 / (V_MAX / 7))), 7, goal)
    if expected is None:
        assert not plan.feasible
    else:
        assert plan.feasible and plan.arrival_s == pytest.approx(expected)


@pytest.mark.parametrize("kwargs", [dict(spacing_m=0.0), dict(dt_s=math.nan), dict(speed_max_mps=-1.0),
                                    dict(accel_mps2=math.inf), dict(speed0_mps=math.nan), dict(goal_m=math.inf)])
def test_refuses_non_finite_or_non_positive_inputs(kwargs):
    blocked, rest = _free(5, 10)
    args = dict(spacing_m=SPACING_M, dt_s=DT_S, speed0_mps=0.0, speed_max_mps=V_MAX, accel_mps2=ACCEL, goal_m=1.0)
    with pytest.raises(DataError):
        plan_speed_along_path(blocked, rest, **{**args, **kwargs})
    with pytest.raises(DataError, match="blocked"):
        plan_speed_along_path(blocked, rest[:-1], **args)
