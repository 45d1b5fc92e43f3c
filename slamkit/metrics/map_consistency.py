"""Map consistency without ground truth: how far the scans of one visit lie from the walls that
the other visits put in the map.

A SLAM map is wrong where a place seen twice is drawn twice (doubled walls): the robot came back
with a pose error the loop closure did not remove, and its scans place the same wall elsewhere.
Where there are no reference relations (MIT CSAIL, the Freiburg hospital) this is what a user
looks for on the map, so it is what this figure measures.

Every keyframe scan's end points are placed at the estimated sensor poses. The trajectory is cut
into pieces of ``piece_path_m`` of travel; two pieces are *different visits* when more than
``exclude_path_m`` of travel lies between them. For every end point and every other visit that
saw the same place (it lies in the visit's field of view, not hidden behind a nearer wall of it)
from the same side (world beam directions within ``same_side_deg``), the distance (m) to that
visit's surface is taken: across the line through its nearest end point and that point's
neighbours in its scan (point-to-line, as ICP's; to the point where it has no neighbours), when
the nearest end point is at most ``max_distance_m`` away. Point-to-line, because along a wall
seen at a grazing angle the end points lie a metre apart and the nearest one says nothing of how
far the wall is.
Reported over those (end point, visit) pairs: the mean and the 95th percentile, and the fraction
of end points that had at least one such visit (``overlap``: the part of the map seen more than
once).

The same mean is also taken between the pieces of one pass (a piece and its neighbours within
``exclude_path_m`` of travel, ``same_pass_mean_m``): over so little travel no drift builds up, so
it is what the surfaces and the scan matcher give, the floor the figure over visits is read
against. Both grow where the surfaces scatter the end points (hedges, clutter, people, glass);
only the first grows where walls are doubled. Measured on the logs (odometry, whole logs, see
pipelines/lidar_slam_logs.yaml): Intel 0.064 m over visits against 0.037 m along a pass, the
Freiburg hospital 0.227 m against 0.089 m -- its own passes already disagree 2.4x more than
Intel's (visits 5-20 m of travel apart at ranges below 4 m: median 0.112 m against 0.017 m).

Why pairs of visits and not the distance to the final map's occupied cells, as simple as that
sounds: an end point marks its own cell occupied, so in a map built from the same scans it lies
on an occupied cell whether or not its wall is doubled (the free-space rays of a later visit clear
an earlier wall only when the later wall lies behind it). Leaving the point's own visit out is not
enough either: each copy of a doubled wall is also seen by other pieces of its own pass, and the
nearest of all other visits would find that copy. Scored visit by visit, a wall drawn twice counts
wherever a visit of one copy meets a visit of the other. Asking for the same side keeps the two
faces of a thin wall (a room seen once from inside, its corridor side on every pass) from counting
as a doubled wall; the distance cap keeps a place seen once from being scored against some other
surface far away (a doubling larger than the cap lowers ``overlap`` instead of raising the mean).

A consistent map scores the range noise, plus what walls are not: clutter seen from other
angles, people, corners (tests/metrics/test_map_consistency.py: a known scene scanned along a
known path twice with 1 cm range noise: 0.0125 m mean, 0.041 m 95th percentile; the second lap
moved by 0.2 m in x and y: 0.159 m and 0.210 m; the first 120 s of Intel, 0.016 m relation error,
0.089 m and 0.40 m: median 0.029 m, the tail at the chairs of the room and where a visit saw a
wall only sparsely).

This is the "map quality without ground truth" of the point-cloud literature (mean map entropy
and plane variance, Razlaw et al., "Evaluation of registration methods for sparse 3D laser scans",
ECMR 2015) reduced to what doubled walls do to a 2D map: a second copy at a distance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from slamkit.errors import DataError

@dataclass(frozen=True)
class MapConsistency:
    """``mean_m`` / ``p95_m``: distance (m) of an end point to another visit's nearest end point
    (same side, within the cap), over all (end point, visit) pairs; ``overlap``: fraction of the
    scored end points that had at least one such visit; ``pairs``: how many pairs;
    ``same_pass_mean_m``: the mean over the neighbouring pieces of one pass instead (the floor)."""

    mean_m: float
    p95_m: float
    overlap: float
    pairs: int
    same_pass_mean_m: float = float("nan")

    def as_metrics(self, prefix: str = "map_consistency_") -> dict[str, float]:
        return {f"{prefix}mean_m": self.mean_m, f"{prefix}p95_m": self.p95_m,
                f"{prefix}overlap": self.overlap, f"{prefix}same_pass_mean_m": self.same_pass_mean_m}


def world_end_points(world_xytheta_sensor: np.ndarray, angles_rad, ranges_m, max_range_m: float | None = None,
                     max_gap_m: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """End points (M, 2) of every keyframe's returns at its sensor pose, the keyframe of each (M,),
    each beam's world direction (M,) rad and the unit normal of the surface there (M, 2): across
    the line through the neighbouring returns of the same scan, NaN where a neighbour is missing or
    more than ``max_gap_m`` away. ``angles_rad[k]`` / ``ranges_m[k]``: keyframe k's beams (NaN
    range: no return; returns beyond ``max_range_m`` are dropped)."""
    poses = np.asarray(world_xytheta_sensor, dtype=float).reshape(-1, 3)
    if len(angles_rad) != len(poses) or len(ranges_m) != len(poses):
        raise DataError(f"{len(poses)} poses but {len(angles_rad)} angle and {len(ranges_m)} range arrays")
    pts, kf, direction, normal = [], [], [], []
    for k, (pose, a, r) in enumerate(zip(poses, angles_rad, ranges_m)):
        a, r = np.asarray(a, dtype=float), np.asarray(r, dtype=float)
        ok = np.isfinite(r) & (r > 0)
        if max_range_m is not None:
            ok &= r <= max_range_m
        world_a = pose[2] + a[ok]
        xy = pose[:2] + r[ok, None] * np.column_stack([np.cos(world_a), np.sin(world_a)])
        pts.append(xy)
        kf.append(np.full(len(xy), k))
        direction.append(world_a)
        normal.append(_normals(xy, max_gap_m))
    if not pts:
        return np.zeros((0, 2)), np.zeros(0, int), np.zeros(0), np.zeros((0, 2))
    return np.concatenate(pts), np.concatenate(kf), np.concatenate(direction), np.concatenate(normal)


def _normals(xy: np.ndarray, max_gap_m: float) -> np.ndarray:
    """Unit normals of a scan's end points (in beam order) from their two neighbours."""
    out = np.full(xy.shape, np.nan)
    if len(xy) < 3:
        return out
    gap = np.hypot(*np.diff(xy, axis=0).T)
    tangent = xy[2:] - xy[:-2]
    ok = (gap[:-1] <= max_gap_m) & (gap[1:] <= max_gap_m)
    length = np.hypot(tangent[:, 0], tangent[:, 1])
    ok &= length > 0
    out[1:-1][ok] = np.column_stack([-tangent[ok, 1], tangent[ok, 0]]) / length[ok, None]
    return out


def map_consistency(world_xytheta_sensor: np.ndarray, angles_rad, ranges_m, max_range_m: float | None = None,
                    piece_path_m: float = 2.5, exclude_path_m: float = 5.0, max_distance_m: float = 1.0,
                    same_side_deg: float = 60.0, query_every: int = 1) -> MapConsistency:
    """The map consistency figure of the keyframe scans at ``world_xytheta_sensor`` (K, 3) (see
    the module docstring). ``angles_rad`` / ``ranges_m``: K arrays of beam angles (sensor frame,
    increasing) and ranges (NaN: no return). ``query_every``: score every n-th end point only
    (all end points are the reference), a sample that keeps the figure (a mean) and divides the
    time."""
    if not (piece_path_m > 0 and exclude_path_m >= 0 and max_distance_m > 0 and query_every >= 1
            and 0 <= same_side_deg <= 180):
        raise DataError("map_consistency: piece_path_m and max_distance_m must be > 0, exclude_path_m >= 0, "
                        "query_every >= 1, same_side_deg in [0, 180]")
    poses = np.asarray(world_xytheta_sensor, dtype=float).reshape(-1, 3)
    if not np.isfinite(poses).all():
        raise DataError("map_consistency: the sensor poses must be finite")
    xy, kf, direction, normal = world_end_points(poses, angles_rad, ranges_m, max_range_m, max_distance_m)
    travel = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))])
    piece_of_kf = np.floor(travel / piece_path_m).astype(int)
    piece = piece_of_kf[kf]
    # pieces within exclude_path_m of travel of a piece belong to its visit
    reach = int(np.ceil(exclude_path_m / piece_path_m))
    cos_side = np.cos(np.deg2rad(same_side_deg))
    query = np.zeros(len(xy), dtype=bool)
    query[::query_every] = True

    # two sets of pairs: other visits (more than ``reach`` pieces apart), and the neighbouring
    # pieces of the same pass (1 to ``reach`` apart): no drift builds up over so little travel, so
    # the second is what the surfaces and the scan matcher give -- the floor the first is read against
    kinds = (lambda apart: apart > reach, lambda apart: (apart >= 1) & (apart <= reach))
    per_pair: tuple[list[np.ndarray], ...] = ([], [])
    matched = np.zeros(len(xy), dtype=bool)
    for q in np.unique(piece):
        ref = np.flatnonzero(piece == q)
        lo, hi = xy[ref].min(axis=0) - max_distance_m, xy[ref].max(axis=0) + max_distance_m
        inside = np.flatnonzero(query & np.all((xy >= lo) & (xy <= hi), axis=1))
        apart = np.abs(piece[inside] - q)
        tree = None
        for kind, pieces_apart in enumerate(kinds):
            cand = inside[pieces_apart(apart)]
            if len(cand) == 0:
                continue
            tree = cKDTree(xy[ref]) if tree is None else tree
            # the nearest end point of the visit first (cheap): only points near it can pair with it
            d, j = tree.query(xy[cand], distance_upper_bound=max_distance_m)
            near = np.isfinite(d)
            cand, d, j = cand[near], d[near], ref[j[near]]
            seen = np.zeros(len(cand), dtype=bool)
            for k in np.flatnonzero(piece_of_kf == q):
                if not seen.all():
                    todo = ~seen
                    seen[todo] = _seen_from(poses[k], np.asarray(angles_rad[k], float),
                                            np.asarray(ranges_m[k], float), xy[cand[todo]], direction[cand[todo]],
                                            max_distance_m, cos_side)
            asked, d, j = cand[seen], d[seen], j[seen]
            # to the other visit's surface: along the normal at its nearest end point where it has one
            across = np.abs(np.sum(normal[j] * (xy[asked] - xy[j]), axis=1))
            per_pair[kind].append(np.where(np.isfinite(across), across, d))
            if kind == 0:
                matched[asked] = True
    if not matched.any():
        return MapConsistency(float("nan"), float("nan"), 0.0, 0)
    d = np.concatenate(per_pair[0])
    same_pass = np.concatenate(per_pair[1]) if per_pair[1] else np.zeros(0)
    return MapConsistency(float(np.mean(d)), float(np.percentile(d, 95)),
                          float(matched.sum() / query.sum()), int(len(d)),
                          float(np.mean(same_pass)) if len(same_pass) else float("nan"))


def _seen_from(pose: np.ndarray, angles_rad: np.ndarray, ranges_m: np.ndarray, xy: np.ndarray,
               direction_rad: np.ndarray, behind_m: float, cos_side: float) -> np.ndarray:
    """Which of the points ``xy`` (seen along world beam directions ``direction_rad``) the scan
    at ``pose`` saw from the same side: inside its field of view, along a beam whose return lies
    no more than ``behind_m`` in front of the point (the point is not hidden behind a nearer
    wall; a doubled wall up to ``behind_m`` behind still counts), and looked at along a direction
    within ``arccos(cos_side)`` of the point's own beam."""
    rel = xy - pose[:2]
    rho = np.hypot(rel[:, 0], rel[:, 1])
    world_bearing = np.arctan2(rel[:, 1], rel[:, 0])
    bearing = np.mod(world_bearing - pose[2] + np.pi, 2 * np.pi) - np.pi
    step = np.median(np.diff(angles_rad)) if len(angles_rad) > 1 else np.pi
    i = np.clip(np.searchsorted(angles_rad, bearing), 1, max(len(angles_rad) - 1, 1))
    i = np.where(np.abs(angles_rad[i - 1] - bearing) < np.abs(angles_rad[i] - bearing), i - 1, i)
    r = ranges_m[i]
    with np.errstate(invalid="ignore"):
        return ((np.abs(angles_rad[i] - bearing) <= step) & np.isfinite(r) & (rho <= r + behind_m)
                & (np.cos(world_bearing - direction_rad) >= cos_side))
