"""Speed planning along a fixed path against moving obstacles: the velocity half of the
path-velocity decomposition (Kant & Zucker, "Toward efficient trajectory planning: the
path-velocity decomposition", IJRR 5(3), 1986), searched forward in time over (arc length,
speed) with bounded acceleration (:func:`plan_speed_along_path`).

The obstacles enter as a blocked (time, arc length) table -- where the path is covered by a
predicted obstacle, grown by the caller's margins -- and the places where the robot may stand
still; the planner neither predicts nor knows what the obstacles are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slamkit.errors import DataError


@dataclass(frozen=True)
class SpeedPlan:
    """What :func:`plan_speed_along_path` found. ``feasible``: some plan keeps clear of every
    blocked cell over the horizon and ends it where the robot may be (past ``goal_m``, or able to
    stop inside a rest stretch). ``arrival_s``: the earliest time past ``goal_m`` (inf: not
    within the horizon). ``speed_mps`` / ``arc_m``: the chosen plan at t = 0, dt, ... (its first
    step after t = 0 is the command; empty when infeasible). ``unhindered``: every step of it is the
    fastest allowed (the most acceleration, or top speed kept) -- the plan of a free path."""

    feasible: bool
    arrival_s: float
    speed_mps: np.ndarray
    arc_m: np.ndarray
    unhindered: bool = False

    @property
    def next_speed_mps(self) -> float:
        """The plan's speed one step ahead (nan when infeasible)."""
        return float(self.speed_mps[1]) if len(self.speed_mps) > 1 else math.nan


def plan_speed_along_path(blocked: np.ndarray, rest: np.ndarray, spacing_m: float, dt_s: float,
                          speed0_mps: float, speed_max_mps: float, accel_mps2: float, goal_m: float,
                          bucket_m: float = 0.025) -> SpeedPlan:
    """The earliest way along a path past ``goal_m`` that keeps off blocked cells.

    ``blocked`` (K + 1, S): cell i (the path point at arc length i ``spacing_m`` from the robot)
    is covered at time k ``dt_s`` (an arc past the last point counts as the last point). ``rest``
    (S,): the robot may stand still at point i. The robot starts at arc 0 at ``speed0_mps``
    (clipped to [0, ``speed_max_mps``], on the nearest level); each step of ``dt_s`` its speed
    changes by at most ``accel_mps2 dt_s`` (speed levels ``speed_max_mps`` / n, n the fewest with
    a level step <= that), within [0, ``speed_max_mps``], never backing up; it moves the step's
    mean speed times ``dt_s``. A state (arc, speed) at step k is allowed when its point is not
    blocked at k and -- at speed 0 -- it may rest there. It ends the horizon past ``goal_m``, or
    where it can still stop (at ``accel_mps2``) before the next point it may not rest on.

    The search keeps one state per (``bucket_m`` of arc, speed level) each step -- the one whose
    first step is fastest -- so it is exact up to that bucket. Of the plans that get past
    ``goal_m`` it returns the earliest; of the rest the one that ends furthest along; ties go to
    the faster first step (a robot that dawdles now has no slack later), then the faster last."""
    blocked = np.asarray(blocked, bool)
    rest = np.asarray(rest, bool)
    if blocked.ndim != 2 or rest.shape != blocked.shape[1:] or blocked.shape[0] < 2 or not len(rest):
        raise DataError(f"plan_speed_along_path: blocked (K + 1 >= 2, S) and rest (S,), got {blocked.shape}, "
                        f"{rest.shape}")
    for name, value in (("spacing_m", spacing_m), ("dt_s", dt_s), ("speed_max_mps", speed_max_mps),
                        ("accel_mps2", accel_mps2), ("bucket_m", bucket_m)):
        if not 0 < value < math.inf:
            raise DataError(f"plan_speed_along_path: {name} must be finite and > 0, got {value}")
    if not (math.isfinite(speed0_mps) and math.isfinite(goal_m)):
        raise DataError(f"plan_speed_along_path: speed0_mps and goal_m must be finite, got {speed0_mps}, {goal_m}")
    n_levels = int(math.ceil(speed_max_mps / (accel_mps2 * dt_s) - 1e-9))
    levels = np.linspace(0.0, speed_max_mps, n_levels + 1)
    n_cells = len(rest)
    # how far the robot can still go from point i before a point it may not rest on
    room = np.zeros(n_cells)
    run = 0.0
    for i in range(n_cells - 1, -1, -1):
        run = run + spacing_m if rest[i] else 0.0
        room[i] = max(run - spacing_m, 0.0) if rest[i] else -1.0

    def cell(arc: np.ndarray) -> np.ndarray:
        return np.minimum(np.round(arc / spacing_m).astype(int), n_cells - 1)

    def allowed(arc: np.ndarray, level: np.ndarray, k: int) -> np.ndarray:
        i = cell(arc)
        return ~blocked[k, i] & ((level > 0) | rest[i])

    j0 = int(np.argmin(np.abs(levels - min(max(speed0_mps, 0.0), speed_max_mps))))
    arc = np.zeros(1)
    level = np.array([j0])
    first = np.array([j0])  # the level after the first step, per state
    # the states of every step, to read the chosen plan back: arc, level, parent index
    history: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = [(arc, level, np.array([-1]))]
    if not allowed(arc, level, 0)[0]:
        return SpeedPlan(False, math.inf, np.zeros(0), np.zeros(0))
    for k in range(1, blocked.shape[0]):
        parent = np.repeat(np.arange(len(arc)), 3)
        new_level = np.clip(np.repeat(level, 3) + np.tile([-1, 0, 1], len(arc)), 0, n_levels)
        new_arc = arc[parent] + 0.5 * (levels[level[parent]] + levels[new_level]) * dt_s
        new_first = new_level if k == 1 else first[parent]
        ok = allowed(new_arc, new_level, k)
        parent, new_level, new_arc, new_first = parent[ok], new_level[ok], new_arc[ok], new_first[ok]
        if not len(parent):
            return SpeedPlan(False, math.inf, np.zeros(0), np.zeros(0))
        past = new_arc >= goal_m
        if past.any():  # the earliest arrival: of its plans the fastest first step
            history.append((new_arc, new_level, parent))
            ties = np.flatnonzero(past)
            best = int(ties[np.lexsort((-new_arc[ties], -new_level[ties], -new_first[ties]))[0]])
            return _plan(history, best, levels, k * dt_s)
        # one state per (bucket, level): the fastest first step (then the furthest arc)
        key = np.floor(new_arc / bucket_m).astype(int) * (n_levels + 1) + new_level
        order = np.lexsort((-new_arc, -new_first, key))
        keep = order[np.concatenate([[True], key[order][1:] != key[order][:-1]])]
        arc, level, first = new_arc[keep], new_level[keep], new_first[keep]
        history.append((arc, level, parent[keep]))
    stop_m = levels[level] ** 2 / (2.0 * accel_mps2)
    can_stop = stop_m <= room[cell(arc)] + 1e-9
    if not can_stop.any():
        return SpeedPlan(False, math.inf, np.zeros(0), np.zeros(0))
    candidates = np.flatnonzero(can_stop)
    best = candidates[np.lexsort((-first[candidates], -np.round(arc[candidates] / bucket_m)))[0]]
    return _plan(history, int(best), levels, math.inf)


def _plan(history: list[tuple[np.ndarray, np.ndarray, np.ndarray]], index: int, levels: np.ndarray,
          arrival_s: float) -> SpeedPlan:
    arcs, level_path = [], []
    for arc, level, parent in reversed(history):
        arcs.append(arc[index])
        level_path.append(int(level[index]))
        index = int(parent[index])
    level_path = level_path[::-1]
    unhindered = all(b == min(a + 1, len(levels) - 1) for a, b in zip(level_path, level_path[1:]))
    return SpeedPlan(True, arrival_s, levels[level_path], np.asarray(arcs[::-1]), unhindered)
