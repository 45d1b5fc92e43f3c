"""Reference paths and how the simulated robot drives them.

The simulated robot is a differential drive whose velocity command (v, omega) is held constant
over each control period ``dt_s``; the true motion over a period is the exact arc of
:func:`slamkit.models.diff_drive.motion`. Estimators that use the same model with the
odometry reading therefore see only the injected noise, not a discretisation mismatch.

Commands come from a pure-pursuit tracker (Coulter, "Implementation of the Pure Pursuit Path
Tracking Algorithm", CMU-RI-TR-92-01, 1992): steer towards the path point one lookahead
distance ahead, curvature kappa = 2 sin(alpha) / L_d, omega = v kappa; or from a velocity
profile given as (duration, v, omega) segments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.models import diff_drive


@dataclass(frozen=True)
class Drive:
    """True poses at every control stamp and the commands held between them.

    ``stamps_s`` (T+1,), ``world_xytheta_body`` (T+1, 3), ``controls`` (T, 2) = (v, omega)
    held over [stamps_s[k], stamps_s[k+1])."""

    stamps_s: np.ndarray
    world_xytheta_body: np.ndarray
    controls: np.ndarray
    dt_s: float

    def pose_at(self, stamps_s: np.ndarray) -> np.ndarray:
        """(N, 3) true poses at arbitrary stamps inside the run, exact on the arcs."""
        t = np.asarray(stamps_s, dtype=float).reshape(-1)
        k = np.clip(np.floor((t - self.stamps_s[0]) / self.dt_s + 1e-9).astype(np.int64), 0,
                    len(self.controls) - 1 if len(self.controls) else 0)
        if len(self.controls) == 0:
            return np.repeat(self.world_xytheta_body[:1], len(t), axis=0)
        tau = t - self.stamps_s[k]
        return diff_drive.motion(self.world_xytheta_body[k], self.controls[k], tau)

    def body_velocity_at(self, stamps_s: np.ndarray) -> np.ndarray:
        """(N, 2) commanded (v, omega) in force at the given stamps."""
        t = np.asarray(stamps_s, dtype=float).reshape(-1)
        k = np.clip(np.floor((t - self.stamps_s[0]) / self.dt_s + 1e-9).astype(np.int64), 0,
                    len(self.controls) - 1)
        return self.controls[k]


def control_stamps(n: int, dt_s: float) -> np.ndarray:
    """(n,) stamps k * dt_s, computed as k / rate when the rate 1 / dt_s is a whole number, so
    they equal the stamps of sensors at divisor rates bit for bit (k / 20 == (k / 2) / 10 in
    floating point, whereas 3 * 0.05 != 0.15)."""
    rate = 1.0 / dt_s
    if abs(rate - round(rate)) < 1e-9 * rate:
        return np.arange(n) / round(rate)
    return np.arange(n) * dt_s


# ---------------------------------------------------------------------------------------------
# Reference paths (waypoint polylines)


def circle(radius_m: float, center_xy_m=(0.0, 0.0), num: int = 72) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, num, endpoint=False)
    return np.asarray(center_xy_m) + radius_m * np.column_stack([np.cos(a), np.sin(a)])


def rounded_rectangle(length_m: float, width_m: float, corner_radius_m: float,
                      center_xy_m=(0.0, 0.0), spacing_m: float = 0.25) -> np.ndarray:
    """A stadium-like loop, counter-clockwise, starting in the middle of the bottom side."""
    r = min(corner_radius_m, 0.5 * width_m, 0.5 * length_m)
    hx, hy = 0.5 * length_m - r, 0.5 * width_m - r
    pts = []
    corners = [(hx, -hy, -np.pi / 2), (hx, hy, 0.0), (-hx, hy, np.pi / 2), (-hx, -hy, np.pi)]
    for (cx, cy, a0) in corners:
        arc = np.linspace(a0, a0 + np.pi / 2, max(2, int(np.ceil(r * np.pi / 2 / spacing_m))))
        pts.append(np.column_stack([cx + r * np.cos(arc), cy + r * np.sin(arc)]))
    return resample_polyline(np.asarray(center_xy_m) + np.vstack(pts), spacing_m, closed=True)


def figure_eight(size_m: float, center_xy_m=(0.0, 0.0), num: int = 160) -> np.ndarray:
    """Lemniscate of Gerono x = a sin(2s)/2... scaled so the eight spans ``size_m`` in x."""
    s = np.linspace(0, 2 * np.pi, num, endpoint=False)
    a = 0.5 * size_m
    return np.asarray(center_xy_m) + np.column_stack([a * np.sin(s), 0.5 * a * np.sin(2 * s)])


def random_waypoints(rng: np.random.Generator, num: int, extent_m: tuple[float, float, float, float],
                     min_separation_m: float = 3.0) -> np.ndarray:
    """``num`` waypoints uniform in (xmin, xmax, ymin, ymax), consecutive ones at least
    ``min_separation_m`` apart (redrawn otherwise, a bounded number of times)."""
    xmin, xmax, ymin, ymax = extent_m
    pts = [rng.uniform([xmin, ymin], [xmax, ymax])]
    while len(pts) < num:
        for _ in range(100):
            p = rng.uniform([xmin, ymin], [xmax, ymax])
            if np.linalg.norm(p - pts[-1]) >= min_separation_m:
                break
        pts.append(p)
    return np.asarray(pts)


def resample_polyline(points_xy: np.ndarray, spacing_m: float, closed: bool) -> np.ndarray:
    """Points every ``spacing_m`` along the polyline (closing it when ``closed``)."""
    p = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    if closed:
        p = np.vstack([p, p[:1]])
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return p[:1]
    n = max(2, int(np.floor(s[-1] / spacing_m)) + (0 if closed else 1))
    q = np.linspace(0, s[-1], n, endpoint=not closed)
    return np.column_stack([np.interp(q, s, p[:, 0]), np.interp(q, s, p[:, 1])])


# ---------------------------------------------------------------------------------------------
# Driving


@dataclass(frozen=True)
class PurePursuit:
    speed_mps: float = 1.0
    lookahead_m: float = 1.0
    max_omega_radps: float = 1.5
    #: below this speed fraction the robot turns nearly in place at sharp corners
    min_speed_fraction: float = 0.2


def pure_pursuit(path_xy: np.ndarray, closed: bool, duration_s: float, dt_s: float,
                 config: PurePursuit = PurePursuit(), start_xytheta: np.ndarray | None = None,
                 goal_tolerance_m: float = 0.3) -> Drive:
    """Drive along ``path_xy`` for ``duration_s`` (closed paths repeat) or until the end of an
    open path. Starts on the first point heading along the path unless ``start_xytheta``."""
    if dt_s <= 0 or duration_s < 0:
        raise ConfigError(f"pure_pursuit needs dt_s > 0 and duration_s >= 0, got {dt_s}, {duration_s}")
    c = config
    path = resample_polyline(path_xy, min(0.1, c.lookahead_m / 4), closed)
    n = len(path)
    if start_xytheta is None:
        d = path[1] - path[0]
        start_xytheta = np.array([path[0, 0], path[0, 1], np.arctan2(d[1], d[0])])
    pose = np.asarray(start_xytheta, dtype=float).reshape(3)
    steps = int(round(duration_s / dt_s))
    poses = [pose]
    controls = []
    progress = 0  # index of the closest path point, only moves forward (unwrapped for loops)
    window = max(10, int(4 * c.lookahead_m / 0.1))
    for _ in range(steps):
        ahead = progress + np.arange(window)
        idx = ahead % n if closed else np.minimum(ahead, n - 1)
        d = np.linalg.norm(path[idx] - pose[:2], axis=1)
        progress = int(ahead[np.argmin(d)])
        far = np.nonzero(d[np.argmin(d):] >= c.lookahead_m)[0]
        target_i = ahead[np.argmin(d) + far[0]] if len(far) else ahead[-1]
        target = path[target_i % n if closed else min(target_i, n - 1)]
        if not closed and progress >= n - 1 and np.linalg.norm(path[-1] - pose[:2]) < goal_tolerance_m:
            break
        dx, dy = target - pose[:2]
        c_, s_ = np.cos(pose[2]), np.sin(pose[2])
        alpha = np.arctan2(-s_ * dx + c_ * dy, c_ * dx + s_ * dy)
        if abs(alpha) > 0.5 * np.pi:
            # target behind the robot (a route reversing at a goal): pure pursuit's sin(alpha)
            # vanishes near +-pi and the robot would drive straight on, so turn in place
            v = 0.0
            omega = c.max_omega_radps if alpha >= 0 else -c.max_omega_radps
        else:
            v = c.speed_mps * np.clip(np.cos(alpha), c.min_speed_fraction, 1.0)
            ld = max(np.hypot(dx, dy), 1e-6)
            omega = np.clip(2.0 * v * np.sin(alpha) / ld, -c.max_omega_radps, c.max_omega_radps)
        u = np.array([v, omega])
        pose = diff_drive.motion(pose, u, dt_s)
        poses.append(pose)
        controls.append(u)
    poses_a = np.asarray(poses)
    return Drive(control_stamps(len(poses_a), dt_s), poses_a, np.asarray(controls).reshape(-1, 2), dt_s)


def velocity_profile(segments: list[tuple[float, float, float]], dt_s: float,
                     start_xytheta=(0.0, 0.0, 0.0)) -> Drive:
    """Drive ``segments`` of (duration_s, v_mps, omega_radps), each rounded to whole periods."""
    controls = []
    for duration, v, omega in segments:
        controls += [(v, omega)] * int(round(duration / dt_s))
    u = np.asarray(controls, dtype=float).reshape(-1, 2)
    return integrate_controls(np.asarray(start_xytheta, float), u, dt_s)


def integrate_controls(start_xytheta: np.ndarray, controls: np.ndarray, dt_s: float) -> Drive:
    poses = [np.asarray(start_xytheta, float).reshape(3)]
    for u in np.asarray(controls, float).reshape(-1, 2):
        poses.append(diff_drive.motion(poses[-1], u, dt_s))
    p = np.asarray(poses)
    return Drive(control_stamps(len(p), dt_s), p, np.asarray(controls, float).reshape(-1, 2), dt_s)
