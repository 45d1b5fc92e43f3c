"""Moving obstacles from the lidar scan itself: points the static map does not explain, clustered
and tracked with a constant-velocity Kalman filter (no oracle obstacle list).

* Detection: each beam's end point is put in the world with the *estimated* pose; an end point
  farther than ``unexplained_m`` from every occupied cell of the map (the map's distance field)
  is unexplained. Unexplained points are split into clusters in scan order wherever two
  neighbours are more than ``cluster_gap_m`` apart (the classic range-image segmentation,
  e.g. Premebida & Nunes 2005), and clusters of fewer than ``min_points`` are dropped (noise).
  A cluster is reported as a disc: a lidar sees only the near side of a round obstacle, so the
  radius R is half the cluster's extent (the visible chord; at least ``min_radius_m``) and the
  centre lies R behind the nearest point, on the line of sight through the points' mean.
* Tracking: one Kalman filter per track on (x, y, vx, vy) with the constant-velocity model and
  white-acceleration process noise (Bar-Shalom, Li & Kirubarajan, *Estimation with Applications
  to Tracking and Navigation*, sec. 6.3.2: Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]] per axis);
  detections are assigned greedily by increasing distance inside a ``gate_m`` gate (global
  nearest neighbour), unassigned detections start tentative tracks, a track is confirmed after
  ``confirm_hits`` hits and deleted after ``max_misses`` scans without one.
* Motion history, for a prediction that does not trust the constant-velocity model blindly
  (people and forklifts stop, turn and shuttle back): each track keeps the span of positions it
  has been estimated at (the two farthest apart, extended greedily: ``span_xy_m``), a typical
  speed (an exponential average of its speed, ``speed_typical_mps``: it stays up while the
  obstacle slows down to turn) and how often it has reversed along that span
  (``reversals``: the velocity's component along the span changed sign, each side faster than
  ``reverse_speed_mps``, once the span is ``reverse_span_m`` long). A track estimated more than
  ``span_restart_m`` across its span's line has left that line (it turned, or took over another
  obstacle's detections): its span starts again from there; its reversals and typical speed stay.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError


@dataclass(frozen=True)
class DetectorConfig:
    #: an end point farther than this from the map's occupied cells is unexplained
    unexplained_m: float = 0.25
    cluster_gap_m: float = 0.3
    min_points: int = 3
    min_radius_m: float = 0.1
    max_radius_m: float = 1.0

    def __post_init__(self) -> None:
        if min(self.unexplained_m, self.cluster_gap_m, self.min_radius_m) <= 0 or self.min_points < 1:
            raise ConfigError("DetectorConfig: distances must be > 0 and min_points >= 1")


@dataclass(frozen=True)
class Detection:
    """Discs found in one scan: ``xy_m`` (K, 2) centres, ``radius_m`` (K,), ``n_points`` (K,)."""

    xy_m: np.ndarray
    radius_m: np.ndarray
    n_points: np.ndarray


def unexplained_points(world_xytheta_body: np.ndarray, angles_rad: np.ndarray, ranges_m: np.ndarray,
                       max_range_m: float, map_distance_m, threshold_m: float) -> np.ndarray:
    """(M, 2) world end points of the valid beams (in scan order) whose distance to the map,
    ``map_distance_m(points) -> (M,)``, exceeds ``threshold_m``."""
    x, y, th = np.asarray(world_xytheta_body, float).reshape(3)
    r = np.asarray(ranges_m, float)
    a = np.asarray(angles_rad, float)
    ok = np.isfinite(r) & (r < max_range_m)
    pts = np.column_stack([x + r[ok] * np.cos(th + a[ok]), y + r[ok] * np.sin(th + a[ok])])
    if len(pts) == 0:
        return pts
    return pts[np.asarray(map_distance_m(pts)) > threshold_m]


def cluster_points(points_xy_m: np.ndarray, sensor_xy_m: np.ndarray, config: DetectorConfig) -> Detection:
    """Scan-ordered points (M, 2) -> discs (see the module docstring)."""
    pts = np.asarray(points_xy_m, float).reshape(-1, 2)
    if len(pts) == 0:
        return Detection(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=int))
    gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1) > config.cluster_gap_m
    labels = np.concatenate([[0], np.cumsum(gaps)])
    # a full 360-degree scan wraps: the last cluster may continue the first
    if labels[-1] > 0 and np.linalg.norm(pts[-1] - pts[0]) <= config.cluster_gap_m:
        labels[labels == labels[-1]] = 0
    centres, radii, counts = [], [], []
    for k in np.unique(labels):
        c = pts[labels == k]
        if len(c) < config.min_points:
            continue
        extent = float(np.linalg.norm(c.max(axis=0) - c.min(axis=0)))
        radius = float(np.clip(0.5 * extent, config.min_radius_m, config.max_radius_m))
        rel = c - np.asarray(sensor_xy_m, float)
        away = rel.mean(axis=0)
        away /= max(float(np.linalg.norm(away)), 1e-9)
        nearest = float(np.linalg.norm(rel, axis=1).min())
        centres.append(np.asarray(sensor_xy_m, float) + (nearest + radius) * away)
        radii.append(radius)
        counts.append(len(c))
    if not centres:
        return Detection(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=int))
    return merge_overlapping(np.array(centres), np.array(radii), np.array(counts), config.max_radius_m)


def merge_overlapping(xy_m: np.ndarray, radius_m: np.ndarray, n_points: np.ndarray,
                      max_radius_m: float) -> Detection:
    """Discs that overlap are one obstacle seen in pieces (a wall or another obstacle hid part
    of it): merged into the smallest disc around both (capped at ``max_radius_m``), repeatedly."""
    xy, r, n = [p for p in xy_m], list(radius_m), list(n_points)
    merged = True
    while merged and len(xy) > 1:
        merged = False
        for i in range(len(xy)):
            for j in range(i + 1, len(xy)):
                d = float(np.linalg.norm(xy[i] - xy[j]))
                if d < r[i] + r[j]:
                    if d + r[j] <= r[i] or d + r[i] <= r[j]:  # one inside the other
                        c, rad = (xy[i], r[i]) if r[i] >= r[j] else (xy[j], r[j])
                    else:
                        rad = 0.5 * (d + r[i] + r[j])
                        c = xy[i] + (rad - r[i]) * (xy[j] - xy[i]) / max(d, 1e-12)
                    xy[i], r[i], n[i] = c, min(rad, max_radius_m), n[i] + n[j]
                    del xy[j], r[j], n[j]
                    merged = True
                    break
            if merged:
                break
    return Detection(np.array(xy).reshape(-1, 2), np.array(r, float), np.array(n, dtype=int))


@dataclass(frozen=True)
class TrackerConfig:
    gate_m: float = 0.8
    #: white-acceleration spectral density q (m^2/s^3) of the constant-velocity model
    accel_psd: float = 0.5
    #: detection noise (standard deviation of a centre, m)
    sigma_detection_m: float = 0.08
    initial_speed_sigma_mps: float = 1.0
    confirm_hits: int = 2
    max_misses: int = 5
    #: a reversal counts when the velocity along the seen span flips between +- this speed ...
    reverse_speed_mps: float = 0.15
    #: ... and the span is at least this long (a standing track's jitter is no reversal)
    reverse_span_m: float = 0.3
    #: weight of the newest speed in the typical speed's exponential average (per scan)
    speed_smoothing: float = 0.1
    #: a deleted track hands its motion history to a younger one nearby (``_hand_over``: a
    #: shuttler's cluster splits at its turn near a wall, Willow seed 10). Measured and off: on
    #: pipelines/navigation.yaml's hard seeds the navigation stack, hedging more tracks as
    #: shuttlers, was hit at warehouse 5 and 29 (off: 5 reached, 29 no hit); with its
    #: span-shuttle prediction on as well, office 4/13/27 waited to the 90 s limit, 19/24 were hit
    hand_over: bool = False
    #: a track estimated farther than this from its span's line (across it) has left the line it
    #: was moving along -- its detections now come from another obstacle (two tracks swapped where
    #: two shuttlers met) or it turned: its span starts again from there (None: never). Warehouse
    #: seed 24: a track swapped from a shuttler along a wall to one crossing it diagonally kept
    #: the first one's span, and the robot waited inside the second one's lane
    span_restart_m: float | None = 0.3

    def __post_init__(self) -> None:
        if not 0 < self.speed_smoothing <= 1 or min(self.reverse_speed_mps, self.reverse_span_m) <= 0:
            raise ConfigError("TrackerConfig: speed_smoothing in (0, 1], reverse_speed_mps and reverse_span_m > 0")
        if min(self.gate_m, self.accel_psd, self.sigma_detection_m, self.initial_speed_sigma_mps) <= 0:
            raise ConfigError("TrackerConfig: gate, noise densities and sigmas must be > 0")
        if self.span_restart_m is not None and self.span_restart_m <= 0:
            raise ConfigError("TrackerConfig: span_restart_m > 0 or None")
        if self.confirm_hits < 1 or self.max_misses < 0:
            raise ConfigError("TrackerConfig: confirm_hits >= 1 and max_misses >= 0 needed")


@dataclass(frozen=True)
class Tracks:
    """Confirmed tracks: ``ids`` (K,), ``xy_m`` (K, 2), ``velocity_mps`` (K, 2), ``radius_m`` (K,),
    ``covariance`` (K, 4, 4) of (x, y, vx, vy); their motion history (module docstring):
    ``reversals`` (K,), ``speed_typical_mps`` (K,), ``span_xy_m`` (K, 2, 2) (None: none seen, the
    current speed and position)."""

    ids: np.ndarray
    xy_m: np.ndarray
    velocity_mps: np.ndarray
    radius_m: np.ndarray
    covariance: np.ndarray
    reversals: np.ndarray | None = None
    speed_typical_mps: np.ndarray | None = None
    span_xy_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        k = len(self.ids)
        if self.reversals is None:
            object.__setattr__(self, "reversals", np.zeros(k, dtype=int))
        if self.speed_typical_mps is None:
            object.__setattr__(self, "speed_typical_mps",
                               np.linalg.norm(np.asarray(self.velocity_mps, float).reshape(k, 2), axis=1))
        if self.span_xy_m is None:
            xy = np.asarray(self.xy_m, float).reshape(k, 2)
            object.__setattr__(self, "span_xy_m", np.stack([xy, xy], axis=1))


def cv_matrices(dt_s: float, accel_psd: float) -> tuple[np.ndarray, np.ndarray]:
    """F and Q of the constant-velocity model on (x, y, vx, vy) over ``dt_s``."""
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt_s
    q = accel_psd * np.array([[dt_s**3 / 3.0, dt_s**2 / 2.0], [dt_s**2 / 2.0, dt_s]])
    Q = np.zeros((4, 4))
    Q[np.ix_([0, 2], [0, 2])] = q
    Q[np.ix_([1, 3], [1, 3])] = q
    return F, Q


class ConstantVelocityTracker:
    """Tracks discs over scans; ``update(t_s, detection)`` then ``tracks()``."""

    def __init__(self, config: TrackerConfig = TrackerConfig()):
        self.config = config
        self.reset()

    def reset(self) -> None:
        self._x = np.zeros((0, 4))
        self._P = np.zeros((0, 4, 4))
        self._r = np.zeros(0)
        self._hits = np.zeros(0, dtype=int)
        self._misses = np.zeros(0, dtype=int)
        self._ids = np.zeros(0, dtype=int)
        self._span = np.zeros((0, 2, 2))
        self._speed = np.zeros(0)
        self._sign = np.zeros(0)
        self._reversals = np.zeros(0, dtype=int)
        self._next_id = 0
        self._t: float | None = None

    def predict_to(self, t_s: float) -> None:
        if self._t is not None and t_s > self._t and len(self._x):
            F, Q = cv_matrices(t_s - self._t, self.config.accel_psd)
            self._x = self._x @ F.T
            self._P = F @ self._P @ F.T + Q
        self._t = t_s if self._t is None else max(self._t, t_s)

    def update(self, t_s: float, detection: Detection) -> None:
        c = self.config
        self.predict_to(t_s)
        z, zr = detection.xy_m, detection.radius_m
        n_tr, n_det = len(self._x), len(z)
        assigned_tr = np.full(n_tr, -1)
        used = np.zeros(n_det, dtype=bool)
        if n_tr and n_det:
            d = np.linalg.norm(self._x[:, None, :2] - z[None, :, :], axis=2)
            for flat in np.argsort(d, axis=None):
                i, j = divmod(int(flat), n_det)
                if d[i, j] > c.gate_m:
                    break
                if assigned_tr[i] < 0 and not used[j]:
                    assigned_tr[i], used[j] = j, True
        R = np.eye(2) * c.sigma_detection_m**2
        H = np.zeros((2, 4))
        H[0, 0] = H[1, 1] = 1.0
        for i in np.flatnonzero(assigned_tr >= 0):
            j = assigned_tr[i]
            P = self._P[i]
            S = H @ P @ H.T + R
            K = P @ H.T @ np.linalg.inv(S)
            self._x[i] = self._x[i] + K @ (z[j] - self._x[i, :2])
            self._P[i] = (np.eye(4) - K @ H) @ P
            self._r[i] = 0.7 * self._r[i] + 0.3 * zr[j]
        self._hits[assigned_tr >= 0] += 1
        self._misses[assigned_tr >= 0] = 0
        self._misses[assigned_tr < 0] += 1
        self._remember_motion(assigned_tr >= 0)
        keep = self._misses <= c.max_misses
        if c.hand_over:
            self._hand_over(~keep)
        self._x, self._P, self._r = self._x[keep], self._P[keep], self._r[keep]
        self._hits, self._misses, self._ids = self._hits[keep], self._misses[keep], self._ids[keep]
        self._span, self._speed = self._span[keep], self._speed[keep]
        self._sign, self._reversals = self._sign[keep], self._reversals[keep]
        new = np.flatnonzero(~used)
        if len(new):
            x0 = np.column_stack([z[new], np.zeros((len(new), 2))])
            P0 = np.diag([c.sigma_detection_m**2] * 2 + [c.initial_speed_sigma_mps**2] * 2)
            self._x = np.vstack([self._x, x0])
            self._P = np.concatenate([self._P, np.repeat(P0[None], len(new), axis=0)])
            self._r = np.concatenate([self._r, zr[new]])
            self._hits = np.concatenate([self._hits, np.ones(len(new), dtype=int)])
            self._misses = np.concatenate([self._misses, np.zeros(len(new), dtype=int)])
            self._ids = np.concatenate([self._ids, self._next_id + np.arange(len(new))])
            self._span = np.concatenate([self._span, np.repeat(z[new][:, None, :], 2, axis=1)])
            self._speed = np.concatenate([self._speed, np.zeros(len(new))])
            self._sign = np.concatenate([self._sign, np.zeros(len(new))])
            self._reversals = np.concatenate([self._reversals, np.zeros(len(new), dtype=int)])
            self._next_id += len(new)

    def _remember_motion(self, updated: np.ndarray) -> None:
        """The motion history of the tracks just updated (see the module docstring)."""
        c = self.config
        for i in np.flatnonzero(updated):
            if self._off_span_line(i, self._x[i, :2]):
                self._span[i] = self._x[i, :2]
                self._sign[i] = 0.0
            self._extend_span(i, self._x[i, :2])
            v = self._x[i, 2:]
            self._speed[i] += c.speed_smoothing * (float(np.linalg.norm(v)) - self._speed[i])
            axis = self._span[i, 1] - self._span[i, 0]
            length = float(np.linalg.norm(axis))
            if length < c.reverse_span_m:
                continue
            along = float(v @ axis) / length
            if abs(along) > c.reverse_speed_mps:
                sign = float(np.sign(along))
                if self._sign[i] != 0 and sign != self._sign[i]:
                    self._reversals[i] += 1
                self._sign[i] = sign

    def _off_span_line(self, i: int, p: np.ndarray) -> bool:
        """Whether p lies more than ``span_restart_m`` across the line of track ``i``'s span (one
        at least ``reverse_span_m`` long)."""
        c = self.config
        a, b = self._span[i]
        length = float(np.linalg.norm(b - a))
        if c.span_restart_m is None or length < c.reverse_span_m:
            return False
        u = (b - a) / length
        return abs(float(u[0] * (p[1] - a[1]) - u[1] * (p[0] - a[0]))) > c.span_restart_m

    def _extend_span(self, i: int, p: np.ndarray) -> None:
        """Track ``i``'s span (a, b) takes in the point p: the longer of (a, p) and (p, b)
        replaces it when longer."""
        a, b = self._span[i]
        length, to_a, to_b = (float(np.linalg.norm(d)) for d in (b - a, p - a, p - b))
        if max(to_a, to_b) > length:
            self._span[i, 1 if to_a >= to_b else 0] = p

    def _hand_over(self, dying: np.ndarray) -> None:
        """A confirmed track about to be deleted hands its motion history to the nearest younger
        track within ``gate_m`` (its successor: a cluster that split -- near a wall part of the
        obstacle is explained by the map -- drew the detections away from it): the successor's
        span grows by the dying one's end points, it keeps the larger reversal count and the
        older typical speed (the successor's own is still rising from 0)."""
        c = self.config
        for i in np.flatnonzero(dying & (self._hits >= c.confirm_hits)):
            d = np.linalg.norm(self._x[:, :2] - self._x[i, :2], axis=1)
            heirs = np.flatnonzero(~dying & (self._ids > self._ids[i]) & (d <= c.gate_m))
            if not len(heirs):
                continue
            j = int(heirs[np.argmin(d[heirs])])
            for p in self._span[i]:
                self._extend_span(j, p)
            self._reversals[j] = max(self._reversals[j], self._reversals[i])
            self._speed[j] = max(self._speed[j], self._speed[i])

    def tracks(self) -> Tracks:
        ok = self._hits >= self.config.confirm_hits
        return Tracks(self._ids[ok].copy(), self._x[ok, :2].copy(), self._x[ok, 2:].copy(),
                      self._r[ok].copy(), self._P[ok].copy(), self._reversals[ok].copy(),
                      self._speed[ok].copy(), self._span[ok].copy())
