"""What a navigation benchmark reports per episode and over a set of episodes (issue 33).

Per episode (pure functions of arrays; the experiment supplies the series and the optimal path):

* the outcome, one of :data:`OUTCOMES`: ``success``, ``collision_static``, ``collision_moving``,
  ``timeout`` (ran out of time, no collision, never believed it arrived) or ``off_goal`` (the
  stack stopped believing it arrived, outside the tolerance by the truth);
* the 5th-percentile clearance over the run (:func:`clearance_percentile_m`): the minimum is one
  sample, the 5th percentile says how much of the run was spent close (Nav2's and the
  social-navigation benchmarks' "time near obstacles" in one number);
* time to goal over the optimal time, optimal path length / maximum speed, and path length over
  the optimal path (:func:`ratio_to_optimal`); both >= 1 for a robot that cannot beat the bound;
* difficulty: the narrowest free width along a path (:func:`narrowest_passage_m`), and how long
  the traffic holds up a robot that knows its future (:func:`path_velocity_arrival_s`).

Over episodes: rates with binomial intervals (:func:`slamkit.metrics.stats.rate_of`) and
difficulty bins (:func:`bin_label`).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from slamkit.errors import DataError

#: an episode ends in exactly one of these
OUTCOMES = ("success", "collision_static", "collision_moving", "timeout", "off_goal")


def outcome(success: bool, collision_static: bool, collision_moving: bool, reached_by_belief: bool) -> str:
    """The episode's outcome (:data:`OUTCOMES`); a collision outranks everything (an episode ends
    at its first contact, and one with both a wall and a disc is counted as static: the wall was
    always there to be avoided)."""
    if collision_static:
        return "collision_static"
    if collision_moving:
        return "collision_moving"
    if success:
        return "success"
    return "off_goal" if reached_by_belief else "timeout"


def clearance_percentile_m(clearance_m, q: float = 5.0) -> float:
    """The ``q``-th percentile (numpy's linear interpolation) of a clearance series, over its
    finite samples (+inf: no moving obstacle exists); nan when none is finite."""
    c = np.asarray(clearance_m, dtype=float).reshape(-1)
    if not 0.0 <= q <= 100.0:
        raise DataError(f"percentile q must lie in [0, 100], got {q!r}")
    c = c[np.isfinite(c)]
    return float(np.percentile(c, q)) if c.size else float("nan")


def polyline_length_m(xy_m) -> float:
    """Length of an (N, 2) polyline (0 for fewer than two points)."""
    p = np.asarray(xy_m, dtype=float).reshape(-1, 2)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if len(p) > 1 else 0.0


def optimal_time_s(optimal_path_length_m: float, max_speed_mps: float) -> float:
    """The time to goal no robot capped at ``max_speed_mps`` can beat on the optimal path."""
    if not (math.isfinite(max_speed_mps) and max_speed_mps > 0):
        raise DataError(f"max_speed_mps must be finite and > 0, got {max_speed_mps!r}")
    return float(optimal_path_length_m) / float(max_speed_mps)


def ratio_to_optimal(value: float, optimal: float) -> float:
    """``value / optimal`` (time to goal over the optimal time, path over the optimal path); nan
    when either is not a positive finite number (an episode that did not arrive has no time)."""
    if not (math.isfinite(value) and math.isfinite(optimal) and optimal > 0 and value >= 0):
        return float("nan")
    return float(value) / float(optimal)


def narrowest_passage_m(path_xy_m, distance_field_m: np.ndarray, origin_xy_m, resolution_m: float,
                        skip_ends_m: float = 0.5) -> float:
    """The narrowest free width a path goes through: twice the smallest wall distance of the
    cells it crosses (``distance_field_m`` (H, W): each cell's distance to the nearest occupied
    cell), leaving out the first and last ``skip_ends_m`` of its length, where the start and goal
    may stand next to a wall without that being a passage. The path should keep to the middle of
    free space (a costmap A* path does; a shortest path grazes corners). nan for an empty path;
    +inf where nothing is in reach."""
    p = np.asarray(path_xy_m, dtype=float).reshape(-1, 2)
    if len(p) == 0:
        return float("nan")
    # resample at half a cell so no crossed cell is skipped
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    step = 0.5 * resolution_m
    along = np.arange(0.0, total + step, step) if total > 0 else np.zeros(1)
    along = np.clip(along, 0.0, total)
    keep = (along >= skip_ends_m) & (along <= total - skip_ends_m)
    if not keep.any():  # a path shorter than both ends: its middle point
        along = np.array([0.5 * total])
    else:
        along = along[keep]
    pts = np.column_stack([np.interp(along, s, p[:, 0]), np.interp(along, s, p[:, 1])])
    h, w = distance_field_m.shape
    ij = np.floor((pts - np.asarray(origin_xy_m, float)) / resolution_m).astype(int)
    inside = (ij[:, 0] >= 0) & (ij[:, 0] < w) & (ij[:, 1] >= 0) & (ij[:, 1] < h)
    if not inside.any():
        raise DataError("narrowest_passage_m: the path lies outside the distance field")
    d = distance_field_m[ij[inside, 1], ij[inside, 0]]
    return float(2.0 * d.min())


def path_velocity_arrival_s(path_xy_m, discs_at: Callable[[float], tuple[np.ndarray, np.ndarray]],
                            clearance_m: float, speed_mps: float, horizon_s: float, step_m: float = 0.05) -> float:
    """The earliest time a robot that knows the traffic's future reaches the end of a path: the
    path-velocity decomposition (Kant & Zucker, "Toward efficient trajectory planning: the
    path-velocity decomposition", IJRR 5(3), 1986) -- it keeps to the path, at any speed in
    [0, ``speed_mps``] along it, never backing up, accelerations unbounded (so, up to the lattice, no
    robot that keeps to the path and never backs up arrives earlier at that top speed; one it finds
    a way for can be done), and its centre stays more than ``clearance_m``
    (robot radius plus any margin) from the surface of every disc; ``discs_at(t)`` -> (centres
    (K, 2), radii (K,)) at time t. Exact on a lattice: ``step_m`` along the path, time steps of
    ``step_m / speed_mps``. +inf when it cannot arrive within ``horizon_s``."""
    p = np.asarray(path_xy_m, dtype=float).reshape(-1, 2)
    if (len(p) < 2 or not 0 < speed_mps < math.inf or not 0 < step_m < math.inf
            or not 0 <= clearance_m < math.inf or not 0 <= horizon_s < math.inf or not np.isfinite(p).all()):
        raise DataError("path_velocity_arrival_s: a finite path of >= 2 points, speed_mps and step_m finite and "
                        f"> 0, clearance_m and horizon_s finite and >= 0 (got speed {speed_mps}, step {step_m}, "
                        f"clearance {clearance_m}, horizon {horizon_s})")
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    if s[-1] <= 0.0:
        raise DataError("path_velocity_arrival_s: the path has no length")
    along = np.linspace(0.0, s[-1], int(math.ceil(s[-1] / step_m)) + 1)
    xy = np.column_stack([np.interp(along, s, p[:, 0]), np.interp(along, s, p[:, 1])])
    dt = (along[1] - along[0]) / speed_mps

    def free(t: float) -> np.ndarray:
        centres, radii = discs_at(t)
        centres = np.asarray(centres, float).reshape(-1, 2)
        if not len(centres):
            return np.ones(len(xy), bool)
        d = np.linalg.norm(xy[:, None, :] - centres[None], axis=-1) - np.asarray(radii, float)[None]
        return (d > clearance_m).all(axis=1)

    reach = np.zeros(len(xy), bool)  # where the robot can be at time i dt
    reach[0] = bool(free(0.0)[0])
    for i in range(1, int(math.floor(horizon_s / dt + 1e-9)) + 1):
        if not reach.any():
            break
        reach = (reach | np.concatenate([[False], reach[:-1]])) & free(i * dt)
        if reach[-1]:
            return i * dt
    return math.inf


def bin_label(value: float, edges: tuple[float, ...], unit: str = "") -> str:
    """The half-open bin ``[edges[i], edges[i+1])`` holding ``value``, with open ends (``< a``,
    ``>= b``): the label a by-difficulty table groups on; ``n/a`` for nan."""
    if not edges or any(b <= a for a, b in zip(edges, edges[1:])):
        raise DataError(f"bin edges must be increasing, got {edges!r}")
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    fmt = (lambda x: f"{x:g}{unit}")
    if value < edges[0]:
        return f"< {fmt(edges[0])}"
    for a, b in zip(edges, edges[1:]):
        if a <= value < b:
            return f"{a:g}-{fmt(b)}"
    return f">= {fmt(edges[-1])}"
