"""Moving circular obstacles for closed-loop local-planning experiments.

Each obstacle shuttles back and forth along a straight segment A -> B -> A at constant speed
(a triangle wave in the segment parameter), so it keeps crossing the same place and never leaves
the area it was generated in. ``position_at(t)`` and ``velocity_at(t)`` are closed-form and
vectorised over obstacles.

:func:`crossing_obstacles` places segments across a global path (perpendicular to it) and times
them so that each obstacle is on the path roughly when a robot moving at a nominal speed gets
there -- the interaction a local planner must resolve -- with seeded jitter in place, speed,
size and timing. Segments are shortened until they lie in free space of the static map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import DataError
from slamkit.maps.distance_field import distance_at, distance_field_m
from slamkit.maps.occupancy_grid import OccupancyGrid


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class MovingObstacles:
    """K circles; obstacle i moves between ``a_xy_m[i]`` and ``b_xy_m[i]`` at ``speed_mps[i]``;
    ``phase[i]`` in [0, 2) is its segment parameter at t = 0 (0 at A, 1 at B, back to A at 2)."""

    a_xy_m: np.ndarray
    b_xy_m: np.ndarray
    speed_mps: np.ndarray
    radius_m: np.ndarray
    phase: np.ndarray

    def __post_init__(self) -> None:
        a = np.asarray(self.a_xy_m, float).reshape(-1, 2)
        b = np.asarray(self.b_xy_m, float).reshape(-1, 2)
        k = len(a)
        fields = {"speed_mps": self.speed_mps, "radius_m": self.radius_m, "phase": self.phase}
        arrays = {n: np.asarray(v, float).reshape(-1) for n, v in fields.items()}
        if len(b) != k or any(len(v) != k for v in arrays.values()):
            raise DataError(f"MovingObstacles: inconsistent lengths a={k}, b={len(b)}, "
                            + ", ".join(f"{n}={len(v)}" for n, v in arrays.items()))
        if np.any(arrays["radius_m"] < 0) or np.any(arrays["speed_mps"] < 0):
            raise DataError("MovingObstacles: radius_m and speed_mps must be >= 0")
        object.__setattr__(self, "a_xy_m", _ro(a))
        object.__setattr__(self, "b_xy_m", _ro(b))
        for n, v in arrays.items():
            object.__setattr__(self, n, _ro(v))

    @staticmethod
    def empty() -> "MovingObstacles":
        z = np.zeros(0)
        return MovingObstacles(np.zeros((0, 2)), np.zeros((0, 2)), z, z, z)

    def __len__(self) -> int:
        return len(self.radius_m)

    # the moving-disc interface the plant uses, shared with slamkit.sim.social_force (whose
    # people react to the robot, so each episode runs its own copy): shuttles need neither
    def episode(self) -> "MovingObstacles":
        """The obstacles of one episode: these (closed-form, they do not react to the robot)."""
        return self

    def observe_robot(self, t_s: float, xy_m: np.ndarray, radius_m: float) -> None:
        """Shuttles ignore the robot."""

    def routes_xy_m(self) -> list[np.ndarray]:
        """Each obstacle's route (A, B), for plots."""
        return [np.array([a, b]) for a, b in zip(self.a_xy_m, self.b_xy_m)]

    @property
    def length_m(self) -> np.ndarray:
        return np.linalg.norm(self.b_xy_m - self.a_xy_m, axis=1)

    def _param(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        # s in [0, 2): 0..1 from A to B, 1..2 back; triangle wave tri(s) and its direction
        rate = np.where(self.length_m > 0, self.speed_mps / np.maximum(self.length_m, 1e-12), 0.0)
        s = np.mod(self.phase + rate * t_s, 2.0)
        tri = np.where(s <= 1.0, s, 2.0 - s)
        direction = np.where(s <= 1.0, 1.0, -1.0)
        return tri, direction * rate

    def position_at(self, t_s: float) -> np.ndarray:
        """(K, 2) centres at time ``t_s``."""
        tri, _ = self._param(t_s)
        return self.a_xy_m + tri[:, None] * (self.b_xy_m - self.a_xy_m)

    def velocity_at(self, t_s: float) -> np.ndarray:
        """(K, 2) velocities at time ``t_s`` (what a tracker would report)."""
        _, dtri = self._param(t_s)
        return dtri[:, None] * (self.b_xy_m - self.a_xy_m)


def crossing_obstacles(path_xy_m: np.ndarray, n: int, rng: np.random.Generator,
                       grid: OccupancyGrid | None = None, nominal_speed_mps: float = 0.5,
                       speed_mps: tuple[float, float] = (0.3, 0.7),
                       radius_m: tuple[float, float] = (0.2, 0.4),
                       half_length_m: tuple[float, float] = (1.5, 3.0),
                       along_path: tuple[float, float] = (0.2, 0.8),
                       timing_jitter_s: float = 1.0, min_separation_m: float = 1.5,
                       min_side_m: float = 0.5) -> MovingObstacles:
    """``n`` obstacles shuttling across ``path_xy_m`` (M, 2), seeded by ``rng``.

    Crossing points are drawn at arc-length fractions ``along_path`` of the path, at least
    ``min_separation_m`` apart along it; each segment is perpendicular to the local path direction,
    centred on it, with a random half length, and shortened until a disc of the obstacle's radius
    stays in free space of ``grid`` along it (points where either side of the crossing would be
    shorter than ``min_side_m`` -- doorways, narrow gaps, where no robot could get out of the way
    -- are skipped, so fewer than ``n`` obstacles may come back in cluttered maps). The phase puts the
    obstacle on the path when a robot moving at ``nominal_speed_mps`` arrives, +- jitter."""
    path = np.asarray(path_xy_m, dtype=float).reshape(-1, 2)
    if len(path) < 2:
        raise DataError("crossing_obstacles needs a path with at least 2 points")
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    s_cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = s_cum[-1]
    field = None if grid is None else distance_field_m(grid)
    A, B, V, R, P = [], [], [], [], []
    chosen: list[float] = []
    for _attempt in range(20 * max(n, 1)):
        if len(A) == n:
            break
        s = rng.uniform(*along_path) * total
        if any(abs(s - c) < min_separation_m for c in chosen):
            continue
        i = int(np.clip(np.searchsorted(s_cum, s) - 1, 0, len(seg) - 1))
        centre = path[i] + (s - s_cum[i]) / max(seg[i], 1e-12) * (path[i + 1] - path[i])
        tangent = (path[i + 1] - path[i]) / max(seg[i], 1e-12)
        normal = np.array([-tangent[1], tangent[0]])
        r = rng.uniform(*radius_m)
        half = rng.uniform(*half_length_m)
        speed = rng.uniform(*speed_mps)
        if field is not None:
            # shorten each side separately until the swept disc stays free
            sides = []
            for sign in (1.0, -1.0):
                offsets = np.linspace(0.0, half, 25)
                pts = centre + sign * offsets[:, None] * normal
                ok = distance_at(grid, field, pts) > r + grid.resolution_m
                free_len = offsets[np.argmin(ok)] if not ok.all() else half
                if not ok[0]:
                    free_len = 0.0
                sides.append(max(free_len - 0.05, 0.0))
            if min(sides) < min_side_m:
                continue
            a, b = centre - sides[1] * normal, centre + sides[0] * normal
        else:
            a, b = centre - half * normal, centre + half * normal
        if rng.random() < 0.5:
            a, b = b, a
        length = float(np.linalg.norm(b - a))
        frac_to_path = float(np.linalg.norm(centre - a)) / max(length, 1e-12)
        t_arrive = s / nominal_speed_mps + rng.uniform(-timing_jitter_s, timing_jitter_s)
        phase = np.mod(frac_to_path - speed / max(length, 1e-12) * t_arrive, 2.0)
        A.append(a); B.append(b); V.append(speed); R.append(r); P.append(phase)  # noqa: E702
        chosen.append(s)
    if not A:
        return MovingObstacles.empty()
    return MovingObstacles(np.array(A), np.array(B), np.array(V), np.array(R), np.array(P))
