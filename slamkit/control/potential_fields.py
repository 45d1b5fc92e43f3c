"""Artificial potential fields (Khatib 1986, "Real-time obstacle avoidance for manipulators and
mobile robots", IJRR 5(1); forms as in Choset et al., "Principles of Robot Motion", 2005, ch. 4.1).

Attractive potential towards the goal q_g, with gain k_att:

* quadratic  U = 1/2 k_att |q - q_g|^2                 F = -k_att (q - q_g)
* conic      U = k_att |q - q_g|                       F = -k_att (q - q_g) / |q - q_g|
* combined   quadratic within ``d_star_m`` of the goal and conic beyond (continuous force), so a
  far goal does not produce an unbounded pull (Choset eq. 4.2).

Repulsive potential of an obstacle at distance rho(q) with influence distance D0 (Khatib eq. 18):

    U = 1/2 k_rep (1/rho - 1/D0)^2   if rho <= D0, else 0
    F = k_rep (1/rho - 1/D0) (1/rho^2) grad rho

summed over circular obstacles (rho = |q - c| - r, grad rho = (q - c)/|q - c|) and, for the static
map, taken from the nearest obstacle through a distance field (grad rho = gradient of the field).

The force is turned into a unicycle command by steering towards its direction. Gradient descent
on U stalls in local minima (the forces cancel); they are detected when the resultant force or the
progress over a time window falls below a threshold, and escaped either by a seeded random walk
(Barraquand & Latombe 1991) or by handing over to the global planner (status LOCAL_MINIMUM).
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from slamkit.control.path_following import lookahead_point
from slamkit.control.protocols import (non_finite_brake, ControlOutput, ControlStatus, DistanceGrid, LocalWorld,
                                       Reference, RobotState)
from slamkit.errors import ControlError
from slamkit.geometry.angles import wrap_angle

ATTRACTIVE_KINDS = ("quadratic", "conic", "combined")


def attractive_force(xy_m: np.ndarray, goal_xy_m: np.ndarray, k_att: float = 1.0,
                     kind: str = "quadratic", d_star_m: float = 1.0) -> np.ndarray:
    """(..., 2) points -> (..., 2) attractive force (negative gradient of the potential)."""
    if kind not in ATTRACTIVE_KINDS:
        raise ControlError(f"attractive kind must be one of {ATTRACTIVE_KINDS}, got {kind!r}")
    diff = np.asarray(xy_m, dtype=float) - np.asarray(goal_xy_m, dtype=float)
    dist = np.linalg.norm(diff, axis=-1, keepdims=True)
    unit = diff / np.maximum(dist, 1e-12)
    if kind == "quadratic":
        return -k_att * diff
    if kind == "conic":
        return -k_att * unit
    # combined: quadratic near, conic (scaled by d*) far -- continuous at |q - q_g| = d*
    return np.where(dist <= d_star_m, -k_att * diff, -k_att * d_star_m * unit)


def _khatib_magnitude(rho_m: np.ndarray, k_rep: float, influence_m: float) -> np.ndarray:
    rho = np.maximum(rho_m, 1e-6)  # inside an obstacle: push as hard as at 1 um
    mag = k_rep * (1.0 / rho - 1.0 / influence_m) / rho**2
    return np.where(rho_m <= influence_m, mag, 0.0)


def repulsive_force_circles(xy_m: np.ndarray, centers_xy_m: np.ndarray, radii_m: np.ndarray,
                            k_rep: float = 2.0, influence_m: float = 2.0,
                            robot_radius_m: float = 0.0) -> np.ndarray:
    """(..., 2) points -> (..., 2) summed Khatib repulsion of circles (K, 2), (K,)."""
    xy = np.asarray(xy_m, dtype=float)
    c = np.asarray(centers_xy_m, dtype=float).reshape(-1, 2)
    r = np.asarray(radii_m, dtype=float).reshape(-1)
    if len(c) == 0:
        return np.zeros_like(xy)
    diff = xy[..., None, :] - c  # (..., K, 2)
    dist = np.linalg.norm(diff, axis=-1)
    rho = dist - r - robot_radius_m
    unit = diff / np.maximum(dist, 1e-12)[..., None]
    return (_khatib_magnitude(rho, k_rep, influence_m)[..., None] * unit).sum(axis=-2)


def repulsive_force_field(xy_m: np.ndarray, distance: DistanceGrid, k_rep: float = 2.0,
                          influence_m: float = 2.0, robot_radius_m: float = 0.0) -> np.ndarray:
    """(..., 2) points -> (..., 2) Khatib repulsion of the nearest static obstacle."""
    rho, grad = distance.query(xy_m)
    norm = np.linalg.norm(grad, axis=-1, keepdims=True)
    unit = grad / np.maximum(norm, 1e-12)
    return _khatib_magnitude(rho - robot_radius_m, k_rep, influence_m)[..., None] * unit


@dataclass(frozen=True)
class PotentialFieldConfig:
    k_att: float = 1.0
    attractive: str = "combined"
    d_star_m: float = 1.0
    # chosen on 12 seeded office/warehouse episodes: 1 m / 0.5 stalled in doorways (1 m wide)
    k_rep: float = 0.2
    influence_m: float = 0.6
    robot_radius_m: float = 0.2
    #: the attractive goal is this far along the global path (the path's end when closer)
    lookahead_m: float = 1.0
    dt_s: float = 0.1
    v_max_mps: float = 0.8
    omega_max_radps: float = 1.5
    accel_max_mps2: float = 1.0
    alpha_max_radps2: float = 3.0
    #: v = k_v |F| cos(heading error), omega = k_omega * heading error
    k_v: float = 1.0
    k_omega: float = 2.0
    goal_tolerance_m: float = 0.2
    #: local minimum: |F| below this, or less than ``stall_distance_m`` travelled in ``stall_window_s``
    min_force: float = 0.05
    stall_window_s: float = 3.0
    stall_distance_m: float = 0.15
    #: "random_walk" or "handover"
    escape: str = "random_walk"
    escape_duration_s: float = 1.5
    escape_speed_mps: float = 0.3

    def __post_init__(self) -> None:
        if self.attractive not in ATTRACTIVE_KINDS:
            raise ControlError(f"PotentialFieldConfig.attractive must be one of {ATTRACTIVE_KINDS}")
        if self.escape not in ("random_walk", "handover"):
            raise ControlError("PotentialFieldConfig.escape must be 'random_walk' or 'handover'")
        if self.influence_m <= 0 or self.dt_s <= 0:
            raise ControlError("PotentialFieldConfig.influence_m and dt_s must be positive")


class PotentialFieldController:
    """Gradient descent on attractive + repulsive potentials, with local-minimum escape."""

    name = "potential_fields"

    def __init__(self, config: PotentialFieldConfig = PotentialFieldConfig(),
                 rng: np.random.Generator | None = None):
        self.config = config
        self._rng = rng if rng is not None else np.random.default_rng(0)
        self.reset()

    def reset(self) -> None:
        n = max(1, int(round(self.config.stall_window_s / self.config.dt_s)))
        self._history: deque[np.ndarray] = deque(maxlen=n)
        self._escape_left = 0
        self._escape_heading = 0.0

    def forces(self, xy_m: np.ndarray, goal_xy_m: np.ndarray, world: LocalWorld) -> dict[str, np.ndarray]:
        c = self.config
        att = attractive_force(xy_m, goal_xy_m, c.k_att, c.attractive, c.d_star_m)
        rep = repulsive_force_circles(xy_m, world.circle_xy_m, world.circle_radius_m, c.k_rep,
                                      c.influence_m, c.robot_radius_m)
        if world.distance is not None:
            rep = rep + repulsive_force_field(xy_m, world.distance, c.k_rep, c.influence_m,
                                              c.robot_radius_m)
        return {"attractive": att, "repulsive": rep, "total": att + rep}

    def _limit(self, state: RobotState, v: float, w: float) -> np.ndarray:
        c = self.config
        v0, w0 = state.command
        v = float(np.clip(v, max(0.0, v0 - c.accel_max_mps2 * c.dt_s), v0 + c.accel_max_mps2 * c.dt_s))
        w = float(np.clip(w, w0 - c.alpha_max_radps2 * c.dt_s, w0 + c.alpha_max_radps2 * c.dt_s))
        return np.array([min(v, c.v_max_mps), float(np.clip(w, -c.omega_max_radps, c.omega_max_radps))])

    def compute(self, state: RobotState, reference: Reference, world: LocalWorld) -> ControlOutput:
        if not state.finite:
            return non_finite_brake()
        t0 = time.perf_counter()
        c = self.config
        xy = state.world_xytheta_body[:2]
        theta = state.world_xytheta_body[2]
        goal = reference.goal_xy_m
        if np.linalg.norm(goal - xy) <= c.goal_tolerance_m:
            return ControlOutput(self._limit(state, 0.0, 0.0), ControlStatus.GOAL_REACHED,
                                 solve_time_s=time.perf_counter() - t0)
        carrot = lookahead_point(reference.path_xy_m, xy, c.lookahead_m)
        f = self.forces(xy, carrot, world)
        self._history.append(xy.copy())
        status = ControlStatus.OK

        if self._escape_left > 0:
            self._escape_left -= 1
            heading, speed, status = self._escape_heading, c.escape_speed_mps, ControlStatus.ESCAPING
        else:
            stalled = (len(self._history) == self._history.maxlen
                       and np.linalg.norm(self._history[-1] - self._history[0]) < c.stall_distance_m)
            if np.linalg.norm(f["total"]) < c.min_force or stalled:
                self._history.clear()
                if c.escape == "handover":
                    cmd = self._limit(state, 0.0, 0.0)
                    return ControlOutput(cmd, ControlStatus.LOCAL_MINIMUM, force_xy=f,
                                         solve_time_s=time.perf_counter() - t0)
                # random walk: a random heading in the half plane that does not face the repulsion
                rep_dir = np.arctan2(f["repulsive"][1], f["repulsive"][0])
                self._escape_heading = float(rep_dir + self._rng.uniform(-np.pi / 2, np.pi / 2))
                self._escape_left = max(1, int(round(c.escape_duration_s / c.dt_s))) - 1
                heading, speed, status = self._escape_heading, c.escape_speed_mps, ControlStatus.ESCAPING
            else:
                heading = float(np.arctan2(f["total"][1], f["total"][0]))
                speed = c.k_v * float(np.linalg.norm(f["total"]))
        err = float(wrap_angle(heading - theta))
        v = speed * max(np.cos(err), 0.0)
        w = c.k_omega * err
        cmd = self._limit(state, v, w)
        return ControlOutput(cmd, status, force_xy=f, solve_time_s=time.perf_counter() - t0,
                             info={"carrot_xy_m": carrot})
