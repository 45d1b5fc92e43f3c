"""The local-planning contract: what every controller takes and what it returns.

``Controller.compute(state, reference, world) -> ControlOutput``. The output carries the command
*and what explains it* (the rollouts and their scores for DWA, the force vectors for potential
fields, the predicted horizon for MPC) so a viewer can show why the robot did what it did,
without the controller importing a viewer (ARCHITECTURE.md section 5, "algorithms expose hooks").

Frames and units: every pose is ``world_T_body`` as (x, y, theta) in metres and radians; the
command of a unicycle / differential drive is (v [m/s], omega [rad/s]); the command of a
kinematic bicycle is (v [m/s], steering [rad]). Obstacles the controller knows about are given
in a :class:`LocalWorld`: moving circles (with a constant-velocity prediction) and a static
distance field. Control sits below ``slamkit.sim`` in the layer table, so the simulator's
moving-obstacle objects are flattened into plain arrays here by the caller.
"""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass, field
from typing import Any, Mapping, Protocol, runtime_checkable

import numpy as np

from slamkit.errors import ControlError
from slamkit.maps.distance_field import bilinear


class ControlStatus(enum.Enum):
    OK = "ok"
    #: the goal tolerance is met; the command is zero
    GOAL_REACHED = "goal_reached"
    #: potential fields: the robot sits in a local minimum and asks the global planner for help
    LOCAL_MINIMUM = "local_minimum"
    #: potential fields: random-walk escape from a local minimum in progress
    ESCAPING = "escaping"
    #: no admissible candidate (DWA) or the solver failed (MPC): the command is a safe brake
    FALLBACK_BRAKE = "fallback_brake"


def _ro(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class RobotState:
    """``world_xytheta_body`` (3,) of world_T_body; ``command`` (2,) the command applied during the last
    cycle (v, omega) or (v, steering) -- DWA builds its window and MPC its rate limits from it."""

    world_xytheta_body: np.ndarray
    command: np.ndarray = field(default_factory=lambda: np.zeros(2))
    t_s: float = 0.0

    def __post_init__(self) -> None:
        pose = np.asarray(self.world_xytheta_body, dtype=float).reshape(-1)
        cmd = np.asarray(self.command, dtype=float).reshape(-1)
        if pose.shape != (3,) or cmd.shape != (2,):
            raise ControlError(f"RobotState needs world_xytheta_body (3,) and command (2,), got "
                               f"{pose.shape} and {cmd.shape}")
        # a non-finite pose (a diverged estimator) is not refused here: every controller answers
        # it with a zero command (see ``non_finite_brake``), which is what a robot must do
        object.__setattr__(self, "world_xytheta_body", _ro(pose.copy()))
        object.__setattr__(self, "command", _ro(cmd.copy()))

    @property
    def finite(self) -> bool:
        return bool(np.all(np.isfinite(self.world_xytheta_body)) and np.all(np.isfinite(self.command)))


@dataclass(frozen=True)
class Reference:
    """What to track: ``path_xy_m`` (M, 2) from the global planner (the goal is its last point)
    and an optional ``goal_theta_rad``; ``speed_mps`` is the desired cruise speed."""

    path_xy_m: np.ndarray
    speed_mps: float = 0.5
    goal_theta_rad: float | None = None

    def __post_init__(self) -> None:
        path = np.asarray(self.path_xy_m, dtype=float)
        if path.ndim == 1 and path.size == 2:
            path = path.reshape(1, 2)
        if path.ndim != 2 or path.shape[1] != 2 or len(path) == 0:
            raise ControlError(f"Reference.path_xy_m must be (M, 2) with M >= 1, got {path.shape}")
        if not np.all(np.isfinite(path)):
            raise ControlError("Reference.path_xy_m contains non-finite values")
        object.__setattr__(self, "path_xy_m", _ro(path.copy()))

    @property
    def goal_xy_m(self) -> np.ndarray:
        return self.path_xy_m[-1]


@dataclass(frozen=True)
class DistanceGrid:
    """A static Euclidean distance field sampled on the cells of an occupancy grid:
    ``distance_m[iy, ix]`` is the distance from the centre of cell (iy, ix) to the nearest occupied
    cell (0 inside obstacles). Outside the grid the distance is 0 (unknown counts as occupied).

    Bilinear interpolation between cell centres keeps the gradient defined everywhere but on cell
    borders, which the MPC linearisation and the potential-field repulsion both need."""

    distance_m: np.ndarray
    resolution_m: float
    origin_xy_m: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def __post_init__(self) -> None:
        d = np.asarray(self.distance_m, dtype=float)
        if d.ndim != 2 or d.size == 0:
            raise ControlError(f"DistanceGrid.distance_m must be a non-empty 2D array, got {d.shape}")
        if not self.resolution_m > 0:
            raise ControlError(f"DistanceGrid.resolution_m must be positive, got {self.resolution_m}")
        object.__setattr__(self, "distance_m", _ro(d.copy()))
        object.__setattr__(self, "origin_xy_m", _ro(np.asarray(self.origin_xy_m, float).reshape(2).copy()))
        object.__setattr__(self, "resolution_m", float(self.resolution_m))

    def query(self, xy_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(..., 2) points -> (distance (...), gradient (..., 2)), bilinear, vectorised
        (:func:`slamkit.maps.distance_field.bilinear`; 0 outside the grid)."""
        return bilinear(self.distance_m, self.resolution_m, self.origin_xy_m, xy_m, outside=0.0)


@dataclass(frozen=True)
class LocalWorld:
    """What a controller knows about its surroundings at time ``t_s``.

    ``circle_xy_m`` (K, 2) centres, ``circle_radius_m`` (K,), ``circle_velocity_mps`` (K, 2): moving
    (or static, velocity 0) circular obstacles, predicted with constant velocity;
    ``distance`` the static map as a :class:`DistanceGrid` (or None for open space);
    ``circle_growth_mps`` (K,) how fast each predicted disc's radius grows with the look-ahead
    time (None: 0, the plain constant-velocity prediction). A tracked obstacle may stop, turn or
    reverse: with centre x + (1 - lam) v t and radius r + lam |v| t the disc holds every place
    it can reach at speed |v| when lam = 1 (the reachable set), the constant-velocity guess
    when lam = 0. ``circle_growth_max_m`` (K,) where each disc's growth stops (None: never; a
    standing person who may set off is a hazard within a step or two, not anywhere it could
    walk to within the horizon)."""

    circle_xy_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    circle_radius_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    circle_velocity_mps: np.ndarray | None = None
    distance: DistanceGrid | None = None
    t_s: float = 0.0
    circle_growth_mps: np.ndarray | None = None
    circle_growth_max_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        c = np.asarray(self.circle_xy_m, dtype=float).reshape(-1, 2)
        r = np.asarray(self.circle_radius_m, dtype=float).reshape(-1)
        v = (np.zeros_like(c) if self.circle_velocity_mps is None
             else np.asarray(self.circle_velocity_mps, dtype=float).reshape(-1, 2))
        g = (np.zeros_like(r) if self.circle_growth_mps is None
             else np.asarray(self.circle_growth_mps, dtype=float).reshape(-1))
        g_max = (np.full_like(r, np.inf) if self.circle_growth_max_m is None
                 else np.asarray(self.circle_growth_max_m, dtype=float).reshape(-1))
        if not (len(c) == len(r) == len(v) == len(g) == len(g_max)):
            raise ControlError(f"LocalWorld: {len(c)} circle centres, {len(r)} radii, {len(v)} velocities, "
                               f"{len(g)} growth rates, {len(g_max)} growth limits")
        if np.isnan(g_max).any() or np.any(g_max < 0):
            raise ControlError("LocalWorld.circle_growth_max_m must be >= 0 (inf: no limit)")
        bad = ~(np.isfinite(c).all(axis=1) & np.isfinite(r) & np.isfinite(v).all(axis=1) & np.isfinite(g))
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise ControlError(f"LocalWorld: obstacle {k} has a non-finite centre, radius or velocity "
                               f"({c[k].tolist()}, {float(r[k])}, {v[k].tolist()}) or growth rate ({float(g[k])})")
        if np.any(r < 0) or np.any(g < 0):
            raise ControlError("LocalWorld.circle_radius_m and circle_growth_mps must be >= 0")
        object.__setattr__(self, "circle_xy_m", _ro(c.copy()))
        object.__setattr__(self, "circle_radius_m", _ro(r.copy()))
        object.__setattr__(self, "circle_velocity_mps", _ro(v.copy()))
        object.__setattr__(self, "circle_growth_mps", _ro(g.copy()))
        object.__setattr__(self, "circle_growth_max_m", _ro(g_max.copy()))

    @property
    def num_circles(self) -> int:
        return len(self.circle_radius_m)

    def with_copies(self, k: np.ndarray, xy_m: np.ndarray, velocity_mps: np.ndarray) -> LocalWorld:
        """This world with a copy of each disc ``k`` (J,) appended, at the centres ``xy_m`` (J, 2)
        moving at ``velocity_mps`` (J, 2): its radius, growth and growth limit kept (a second
        guess of where the same obstacle goes)."""
        k = np.asarray(k, dtype=int).reshape(-1)
        return dataclasses.replace(
            self, circle_xy_m=np.vstack([self.circle_xy_m, np.asarray(xy_m, float).reshape(-1, 2)]),
            circle_radius_m=np.concatenate([self.circle_radius_m, self.circle_radius_m[k]]),
            circle_velocity_mps=np.vstack([self.circle_velocity_mps, np.asarray(velocity_mps, float).reshape(-1, 2)]),
            circle_growth_mps=np.concatenate([self.circle_growth_mps, self.circle_growth_mps[k]]),
            circle_growth_max_m=np.concatenate([self.circle_growth_max_m, self.circle_growth_max_m[k]]))

    def circles_at(self, dt_s: np.ndarray) -> np.ndarray:
        """Constant-velocity prediction: (T,) time offsets -> (T, K, 2) centres."""
        dt = np.asarray(dt_s, dtype=float).reshape(-1)
        return self.circle_xy_m[None, :, :] + dt[:, None, None] * self.circle_velocity_mps[None, :, :]

    def radii_at(self, dt_s: np.ndarray) -> np.ndarray:
        """The predicted discs' radii: (T,) time offsets -> (T, K), r + min(growth * dt, growth max)."""
        dt = np.asarray(dt_s, dtype=float).reshape(-1)
        grown = np.maximum(dt, 0.0)[:, None] * self.circle_growth_mps[None, :]
        return self.circle_radius_m[None, :] + np.minimum(grown, self.circle_growth_max_m[None, :])

    def clearance_m(self, xy_m: np.ndarray, dt_s: np.ndarray | float = 0.0) -> np.ndarray:
        """Distance from points (..., T, 2) to the nearest obstacle surface, the circles predicted
        ``dt_s`` (T,) ahead (broadcast over the leading axes). +inf with no obstacles."""
        xy = np.asarray(xy_m, dtype=float)
        if xy.ndim == 1:
            xy = xy[None, :]
        dt = np.broadcast_to(np.asarray(dt_s, dtype=float), xy.shape[-2:-1])
        out = np.full(xy.shape[:-1], np.inf)
        if self.num_circles:
            centres = self.circles_at(dt)  # (T, K, 2)
            dist = np.linalg.norm(xy[..., :, None, :] - centres, axis=-1) - self.radii_at(dt)
            out = np.minimum(out, dist.min(axis=-1))
        if self.distance is not None:
            out = np.minimum(out, self.distance.query(xy)[0])
        return out


@dataclass(frozen=True)
class ControlOutput:
    """A controller's answer for one cycle.

    ``command`` (2,); ``status``; ``candidates_xytheta`` (K, T+1, 3) rollouts with ``scores`` (K,)
    and ``chosen`` (index, -1 if none) for sampling controllers; ``predicted_xytheta`` (N+1, 3) and
    ``predicted_commands`` (N, 2) for MPC; ``force_xy`` for potential fields;
    ``solve_time_s`` the wall time of the decision; ``info`` solver details (iterations,
    solver status string, cost terms)."""

    command: np.ndarray
    status: ControlStatus = ControlStatus.OK
    candidates_xytheta: np.ndarray | None = None
    scores: np.ndarray | None = None
    chosen: int = -1
    predicted_xytheta: np.ndarray | None = None
    predicted_commands: np.ndarray | None = None
    force_xy: Mapping[str, np.ndarray] = field(default_factory=dict)
    solve_time_s: float = 0.0
    info: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        cmd = np.asarray(self.command, dtype=float).reshape(-1)
        if cmd.shape != (2,):
            raise ControlError(f"ControlOutput.command must have 2 entries, got {cmd.shape}")
        object.__setattr__(self, "command", _ro(cmd.copy()))


@runtime_checkable
class Controller(Protocol):
    """Local planners and trackers. Engines keep private state (the warm start of MPC, the escape
    state of potential fields); ``reset`` clears it between episodes."""

    name: str

    def reset(self) -> None: ...

    def compute(self, state: RobotState, reference: Reference, world: LocalWorld) -> ControlOutput: ...


def non_finite_brake() -> ControlOutput:
    """The answer to a state with NaN or inf in it: stop (zero command), and say why."""
    return ControlOutput(np.zeros(2), ControlStatus.FALLBACK_BRAKE, info={"reason": "non-finite robot state"})


def brake_command(command: np.ndarray, decel_mps2: float, omega_decel_radps2: float,
                  dt_s: float) -> np.ndarray:
    """The safe fallback: decelerate (v, omega) towards zero within the acceleration limits."""
    v, w = np.asarray(command, dtype=float).reshape(2)
    dv = decel_mps2 * dt_s
    dw = omega_decel_radps2 * dt_s
    v_new = np.sign(v) * max(abs(v) - dv, 0.0)
    w_new = np.sign(w) * max(abs(w) - dw, 0.0)
    return np.array([v_new, w_new])
