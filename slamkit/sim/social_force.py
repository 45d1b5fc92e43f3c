"""Crossing traffic that behaves like people and vehicles: the social-force model.

People follow Helbing & Molnar (1995, Phys. Rev. E 51, 4282): each one relaxes its velocity
towards the desired one (towards its next waypoint at its desired speed) with relaxation time
``tau_s``, and is pushed by repulsive potentials -- from the other people (the elliptical
potential V0 exp(-b / sigma), whose semi-minor axis b allows for the other's step, weighted by a
field of view), from the walls (U0 exp(-d / R) on the static map's distance field) and, more
weakly, from the robot (each person regards it by a seeded factor: they partially avoid it). A
body force keeps discs from overlapping (Helbing, Farkas & Vicsek 2000). On top of the force
model: a route of waypoints walked out and back (a turn at each), a desired speed per leg, a
dwell (a stop) at chosen waypoints approached by braking, and groups whose members walk side by
side and keep together (a member ahead of its group slows, one behind hurries).

A forklift is a non-holonomic vehicle (a unicycle steered onto its route) that drives its route
forwards, waits at the end (loading) and reverses back along it; it avoids nobody.

:class:`SocialForceAgents` has the interface the plant, the lidar and the scoring use for
:class:`slamkit.sim.moving_obstacles.MovingObstacles` (``position_at(t)``, ``velocity_at(t)``,
``radius_m``, ``len``), integrated lazily at ``dt_s`` as time is asked for (deterministic: the
same spec and robot motion give the same traffic). Because the people react to the robot, the
traffic of one episode depends on that episode: :meth:`SocialForceAgents.episode` gives a fresh
copy (the plant takes one per episode), and :meth:`observe_robot` tells it where the robot is.

:func:`social_crossings` turns the shuttles of :func:`slamkit.sim.moving_obstacles.crossing_obstacles`
(same seeded places, sizes, speeds and timing across the path) into such agents: a disc of a
forklift's size becomes a forklift, the others people, some of them a pair walking together.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from slamkit.errors import DataError
from slamkit.maps.distance_field import bilinear, surface_distance_field_m
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.moving_obstacles import crossing_obstacles

KINDS = ("person", "forklift")


@dataclass(frozen=True)
class SocialForceConfig:
    """The model's constants (SI units, per unit mass). Helbing & Molnar 1995: tau 0.5 s,
    V0 2.1 m^2/s^2, sigma 0.3 m, U0 10 m^2/s^2, R 0.2 m, step time 2 s, field of view 200 deg
    with weight 0.5 outside it."""

    dt_s: float = 0.05
    tau_s: float = 0.5
    agent_v0_m2ps2: float = 2.1
    agent_sigma_m: float = 0.3
    step_time_s: float = 2.0
    wall_u0_m2ps2: float = 10.0
    wall_r_m: float = 0.2
    fov_half_rad: float = math.radians(100.0)
    behind_weight: float = 0.5
    #: body force per metre of overlap (HFV 2000's k = 1.2e5 kg/s^2 over 80 kg)
    contact_k_ps2: float = 1500.0
    #: people never exceed this multiple of their desired speed (HM 1995's v_max = 1.3 v0)
    max_speed_factor: float = 1.3
    #: a waypoint counts as reached within this distance
    arrive_m: float = 0.25
    #: braking into a dwell, and a forklift's acceleration
    decel_mps2: float = 0.6
    #: group cohesion: a member farther than this ahead / behind its group's centre along its
    #: walking direction slows to / hurries at these factors of its desired speed
    group_slack_m: float = 0.3
    group_slow: float = 0.7
    group_hurry: float = 1.2
    forklift_omega_max_radps: float = 0.8
    #: a person slower than ``stall_speed_mps`` for ``stall_s`` while it wants to walk gives up
    #: on its waypoint and heads for the next
    stall_speed_mps: float = 0.05
    stall_s: float = 2.0


@dataclass(frozen=True)
class Agent:
    """One agent. ``route_xy_m`` (W >= 2, 2) is walked 0 -> W-1 and back, again and again,
    from ``start_xy_m`` towards waypoint ``start_target`` going ``start_direction`` (+1 up the
    route, -1 down); ``speed_mps`` (W-1,) the desired speed per leg; ``dwell_s`` (W,) how long
    it stands at each waypoint on reaching it; ``regard_robot`` in [0, 1] how strongly it
    avoids the robot (a fraction of the agent potential; forklifts ignore it); ``group`` >= 0
    ties people walking together (-1: alone)."""

    kind: str
    radius_m: float
    route_xy_m: np.ndarray
    speed_mps: np.ndarray
    dwell_s: np.ndarray
    start_xy_m: np.ndarray
    start_target: int = 1
    start_direction: int = 1
    regard_robot: float = 0.5
    group: int = -1

    def __post_init__(self) -> None:
        route = np.asarray(self.route_xy_m, float).reshape(-1, 2)
        speed = np.asarray(self.speed_mps, float).reshape(-1)
        dwell = np.asarray(self.dwell_s, float).reshape(-1)
        where = f"Agent({self.kind})"
        if self.kind not in KINDS:
            raise DataError(f"{where}: kind must be one of {KINDS}")
        if len(route) < 2 or len(speed) != len(route) - 1 or len(dwell) != len(route):
            raise DataError(f"{where}: a route of W >= 2 waypoints needs W-1 speeds and W dwells, got "
                            f"{len(route)}, {len(speed)}, {len(dwell)}")
        if not (np.isfinite(route).all() and np.all(speed > 0) and np.all(dwell >= 0) and self.radius_m > 0):
            raise DataError(f"{where}: waypoints finite, speeds and radius > 0, dwells >= 0")
        if not (0 <= self.start_target < len(route) and self.start_direction in (1, -1)):
            raise DataError(f"{where}: start_target in [0, {len(route)}), start_direction +-1")
        if not 0.0 <= self.regard_robot <= 1.0:
            raise DataError(f"{where}: regard_robot must be in [0, 1], got {self.regard_robot}")
        for name, v in (("route_xy_m", route), ("speed_mps", speed), ("dwell_s", dwell),
                        ("start_xy_m", np.asarray(self.start_xy_m, float).reshape(2))):
            v = v.copy()
            v.setflags(write=False)
            object.__setattr__(self, name, v)


def _ellipse_force(r: np.ndarray, v_other: np.ndarray, v0: float, sigma: float, step_s: float) -> np.ndarray:
    """-grad V(b(r)) of HM 1995's elliptical potential V0 exp(-b / sigma) for the offset ``r``
    (from the other to this agent, surface to surface) and the other's velocity: 2b =
    sqrt((|r| + |r - y|)^2 - |y|^2), y = v_other * step_s."""
    y = v_other * step_s
    n1 = max(float(np.linalg.norm(r)), 1e-6)
    ry = r - y
    n2 = max(float(np.linalg.norm(ry)), 1e-6)
    b = 0.5 * math.sqrt(max((n1 + n2) ** 2 - float(y @ y), 1e-12))
    db_dr = (n1 + n2) / (4.0 * max(b, 1e-6)) * (r / n1 + ry / n2)
    return v0 / sigma * math.exp(-b / sigma) * db_dr


class SocialForceAgents:
    """Agents in a static map (see the module docstring). ``grid`` gives the walls; None: none."""

    def __init__(self, agents: tuple[Agent, ...] | list[Agent], grid: OccupancyGrid | None = None,
                 config: SocialForceConfig = SocialForceConfig()):
        self.agents = tuple(agents)
        self.grid = grid
        self.config = config
        self._field = None if grid is None else surface_distance_field_m(grid)
        r = np.array([a.radius_m for a in self.agents], float)
        r.setflags(write=False)
        self.radius_m = r
        self._restart()

    # ------------------------------------------------------------------ the MovingObstacles interface
    def __len__(self) -> int:
        return len(self.agents)

    def episode(self) -> "SocialForceAgents":
        """A fresh copy (no history, no robot seen) for one episode."""
        return SocialForceAgents(self.agents, self.grid, self.config)

    def observe_robot(self, t_s: float, xy_m: np.ndarray, radius_m: float) -> None:
        """The robot is at ``xy_m`` at ``t_s`` (its velocity: from the previous observation)."""
        xy = np.asarray(xy_m, float).reshape(2)
        if self._robot is not None and t_s > self._robot[0]:
            self._robot_v = (xy - self._robot[1]) / (t_s - self._robot[0])
        self._robot = (float(t_s), xy.copy(), float(radius_m))

    def position_at(self, t_s: float) -> np.ndarray:
        """(K, 2) centres at ``t_s`` >= 0 (linear between integration steps)."""
        return self._at(t_s, self._xy)

    def velocity_at(self, t_s: float) -> np.ndarray:
        """(K, 2) velocities at ``t_s``."""
        return self._at(t_s, self._v)

    def routes_xy_m(self) -> list[np.ndarray]:
        """Each agent's route (for plots)."""
        return [a.route_xy_m for a in self.agents]

    def headings_at(self, t_s: float) -> np.ndarray:
        """(K,) body headings (a forklift's, which reverses without turning round; a person's
        walking direction)."""
        k = min(int(round(max(t_s, 0.0) / self.config.dt_s)), self._integrate_to(t_s))
        return self._heading[k].copy()

    # ------------------------------------------------------------------ integration
    def _restart(self) -> None:
        k = len(self.agents)
        self._robot: tuple[float, np.ndarray, float] | None = None
        self._robot_v = np.zeros(2)
        x = np.array([a.start_xy_m for a in self.agents], float).reshape(k, 2)
        self._target = np.array([a.start_target for a in self.agents], int)
        self._dir = np.array([a.start_direction for a in self.agents], int)
        self._dwell_until = np.full(k, -math.inf)
        self._slow_since = np.full(k, math.inf)
        heading = np.zeros(k)
        for i, a in enumerate(self.agents):
            d = a.route_xy_m[self._target[i]] - x[i]
            if a.kind == "forklift":
                # it drives forwards up its route, so its nose points up the route's first leg
                d = a.route_xy_m[1] - a.route_xy_m[0]
            heading[i] = math.atan2(d[1], d[0])
        self._xy, self._v, self._heading = [x], [np.zeros((k, 2))], [heading]

    def _integrate_to(self, t_s: float) -> int:
        if not (math.isfinite(t_s) and t_s >= 0.0):
            raise DataError(f"SocialForceAgents: time must be finite and >= 0, got {t_s!r}")
        need = int(math.ceil(t_s / self.config.dt_s - 1e-9))
        while len(self._xy) <= need:
            self._step()
        return need

    def _at(self, t_s: float, series: list[np.ndarray]) -> np.ndarray:
        k1 = self._integrate_to(t_s)
        u = t_s / self.config.dt_s
        k0 = min(int(math.floor(u)), k1)
        f = u - k0
        return ((1.0 - f) * series[k0] + f * series[k1]) if k1 > k0 else series[k1].copy()

    def _desired(self, i: int, x: np.ndarray, t_s: float) -> tuple[np.ndarray, float]:
        """Unit direction to agent i's target and its desired speed now (0 while dwelling;
        braking into a waypoint it will dwell at); advances the target on arrival."""
        a, c = self.agents[i], self.config
        if t_s < self._dwell_until[i]:
            return np.zeros(2), 0.0
        w = a.route_xy_m
        d = w[self._target[i]] - x
        dist = float(np.linalg.norm(d))
        # held off its waypoint (a wall's or someone's repulsion balancing its drive) it gives
        # up on it after ``stall_s`` at a standstill, as a person would
        stalled = t_s - self._slow_since[i] >= c.stall_s
        if dist <= c.arrive_m or stalled:
            self._slow_since[i] = math.inf
            j = self._target[i]
            if a.dwell_s[j] > 0 and self._dwell_until[i] < t_s - a.dwell_s[j]:
                self._dwell_until[i] = t_s + a.dwell_s[j]
                self._advance(i)
                return np.zeros(2), 0.0
            self._advance(i)
            d = w[self._target[i]] - x
            dist = float(np.linalg.norm(d))
        j, prev = self._target[i], self._target[i] - self._dir[i]
        leg = min(j, prev)
        speed = float(a.speed_mps[leg])
        if a.dwell_s[j] > 0 or j in (0, len(w) - 1):  # it stops (or turns round) there: brakes into it
            speed = min(speed, math.sqrt(2.0 * c.decel_mps2 * max(dist - c.arrive_m, 0.0)) + 0.05)
        return d / max(dist, 1e-9), speed

    def _advance(self, i: int) -> None:
        n = len(self.agents[i].route_xy_m)
        j = self._target[i] + self._dir[i]
        if not 0 <= j < n:
            self._dir[i] = -self._dir[i]
            j = self._target[i] + self._dir[i]
        self._target[i] = j

    def _step(self) -> None:
        c = self.config
        dt = c.dt_s
        t = (len(self._xy) - 1) * dt
        x, v, heading = self._xy[-1], self._v[-1], self._heading[-1]
        new_x, new_v, new_h = x.copy(), v.copy(), heading.copy()
        k = len(self.agents)
        groups = np.array([a.group for a in self.agents])
        for i, a in enumerate(self.agents):
            e, speed = self._desired(i, x[i], t)
            if a.kind == "forklift":
                new_x[i], new_v[i], new_h[i] = self._forklift_step(i, x[i], v[i], heading[i], e, speed)
                continue
            if a.group >= 0 and speed > 0:
                mates = np.flatnonzero(groups == a.group)
                ahead = float((x[i] - x[mates].mean(axis=0)) @ e)
                speed *= c.group_slow if ahead > c.group_slack_m else c.group_hurry if ahead < -c.group_slack_m else 1.0
            f = (speed * e - v[i]) / c.tau_s
            for j in range(k):
                if j == i:
                    continue
                f += self._repulsion(x[i], v[i], a.radius_m, x[j], v[j], self.agents[j].radius_m,
                                     0.3 if a.group >= 0 and a.group == self.agents[j].group else 1.0)
            if self._robot is not None and a.regard_robot > 0:
                _, rxy, rr = self._robot
                f += self._repulsion(x[i], v[i], a.radius_m, rxy, self._robot_v, rr, a.regard_robot)
            if self._field is not None:
                g = self.grid
                d, grad = bilinear(self._field, g.resolution_m, g.origin_xy_m, x[i][None])
                gap = float(d[0]) - a.radius_m
                f += c.wall_u0_m2ps2 / c.wall_r_m * math.exp(-max(gap, 0.0) / c.wall_r_m) * grad[0]
                if gap < 0:
                    f += c.contact_k_ps2 * (-gap) * grad[0]
            vi = v[i] + f * dt
            cap = c.max_speed_factor * max(float(a.speed_mps.max()), 0.1)
            s = float(np.linalg.norm(vi))
            if s > cap:
                vi *= cap / s
            new_v[i] = vi
            new_x[i] = x[i] + vi * dt
            if speed > 0 and float(np.linalg.norm(vi)) < c.stall_speed_mps:
                self._slow_since[i] = min(self._slow_since[i], t)
            else:
                self._slow_since[i] = math.inf
            if s > 0.05:
                new_h[i] = math.atan2(vi[1], vi[0])
        self._xy.append(new_x)
        self._v.append(new_v)
        self._heading.append(new_h)

    def _repulsion(self, xi, vi, ri, xj, vj, rj, weight: float) -> np.ndarray:
        """The force on a person at ``xi`` from a disc at ``xj``: the elliptical potential on
        the surface-to-surface offset, times the field-of-view weight, plus the body force."""
        c = self.config
        r = xi - xj
        dist = float(np.linalg.norm(r))
        n = r / max(dist, 1e-9)
        gap = dist - ri - rj
        f = weight * _ellipse_force(n * max(gap, 0.01), vj, c.agent_v0_m2ps2, c.agent_sigma_m, c.step_time_s)
        sv = float(np.linalg.norm(vi))
        if sv > 1e-6 and float(vi @ -f) < float(np.linalg.norm(f)) * sv * math.cos(c.fov_half_rad):
            f = c.behind_weight * f  # behind it: it reacts less
        if gap < 0:
            f = f + c.contact_k_ps2 * (-gap) * n
        return f

    def _forklift_step(self, i, x, v, heading, e, speed):
        """A unicycle steered onto its route: forwards up the route, in reverse down it (its
        motion direction is its heading, or the heading turned by pi); its signed speed along
        the heading follows the desired one at ``decel_mps2`` (so it stops before it reverses).
        It avoids nobody."""
        c = self.config
        sign = 1.0 if self._dir[i] > 0 else -1.0
        along = heading + (0.0 if sign > 0 else math.pi)
        u_now = float(v @ np.array([math.cos(heading), math.sin(heading)]))
        omega, target = 0.0, 0.0
        if speed > 0:
            bearing = math.atan2(e[1], e[0]) - along
            err = math.atan2(math.sin(bearing), math.cos(bearing))
            target = sign * speed * max(math.cos(err), 0.0)
            if u_now * sign > 0.0:  # steering only works while moving its way
                omega = float(np.clip(2.0 * err, -c.forklift_omega_max_radps, c.forklift_omega_max_radps))
        u_new = float(np.clip(target, u_now - c.decel_mps2 * c.dt_s, u_now + c.decel_mps2 * c.dt_s))
        h_new = heading + omega * c.dt_s
        v_new = u_new * np.array([math.cos(h_new), math.sin(h_new)])
        return x + v_new * c.dt_s, v_new, h_new


@dataclass(frozen=True)
class CrowdOptions:
    """How :func:`social_crossings` turns shuttles into agents (probabilities and ranges drawn
    per agent from the seeded generator)."""

    #: a crossing disc this large is a forklift; people are at most ``person_radius_m``
    forklift_radius_m: float = 0.36
    person_radius_m: float = 0.3
    turn_probability: float = 0.5
    turn_offset_m: tuple[float, float] = (0.4, 1.0)
    stop_probability: float = 0.3
    stop_s: tuple[float, float] = (1.0, 3.0)
    end_dwell_s: tuple[float, float] = (0.0, 3.0)
    forklift_end_dwell_s: tuple[float, float] = (1.0, 3.0)
    leg_speed_factor: tuple[float, float] = (0.7, 1.2)
    group_probability: float = 0.3
    group_spacing_m: float = 0.7
    regard_robot: tuple[float, float] = (0.2, 0.7)
    config: SocialForceConfig = field(default_factory=SocialForceConfig)


def social_crossings(path_xy_m: np.ndarray, n: int, rng: np.random.Generator, grid: OccupancyGrid | None = None,
                     options: CrowdOptions = CrowdOptions(), **crossing_kwargs) -> SocialForceAgents:
    """``n`` crossings of ``path_xy_m`` as :func:`crossing_obstacles` draws them (same arguments
    in ``crossing_kwargs``, same ``rng``), each turned into agents: a forklift (radius >=
    ``forklift_radius_m``: drives across, waits, reverses back) or a person, who may turn (a
    waypoint beside the crossing point, along the path), stop on the way and walk with a
    companion (a second person beside, the same route shifted along the path). Waypoints whose
    disc would not be free in ``grid`` are dropped (a companion that would not fit stays home)."""
    shuttles = crossing_obstacles(path_xy_m, n, rng, grid=grid, **crossing_kwargs)
    field_m = None if grid is None else surface_distance_field_m(grid)

    def free(p: np.ndarray, r: float) -> bool:
        if field_m is None:
            return True
        return bool(bilinear(field_m, grid.resolution_m, grid.origin_xy_m, np.asarray(p, float)[None])[0][0] > r + 0.05)

    o = options
    agents: list[Agent] = []
    for i in range(len(shuttles)):
        a, b = shuttles.a_xy_m[i], shuttles.b_xy_m[i]
        r, v = float(shuttles.radius_m[i]), float(shuttles.speed_mps[i])
        x0, v_dir = shuttles.position_at(0.0)[i], shuttles.velocity_at(0.0)[i]
        going_up = float(v_dir @ (b - a)) >= 0.0
        span = b - a
        normal = np.array([-span[1], span[0]]) / max(float(np.linalg.norm(span)), 1e-9)  # along the path
        if r >= o.forklift_radius_m:
            dwell = rng.uniform(*o.forklift_end_dwell_s, 2)
            agents.append(Agent("forklift", r, np.array([a, b]), np.array([v]), dwell, x0,
                                1 if going_up else 0, 1 if going_up else -1, 0.0))
            continue
        r = min(r, o.person_radius_m)
        route = [a, b]
        dwell = [rng.uniform(*o.end_dwell_s), rng.uniform(*o.end_dwell_s)]
        if rng.random() < o.turn_probability:
            mid = 0.5 * (a + b) + rng.choice([-1.0, 1.0]) * rng.uniform(*o.turn_offset_m) * normal
            stop = rng.uniform(*o.stop_s) if rng.random() < o.stop_probability else 0.0
            if free(mid, r):
                route, dwell = [a, mid, b], [dwell[0], stop, dwell[1]]
        route_a = np.array(route)
        speeds = v * rng.uniform(*o.leg_speed_factor, len(route) - 1)
        # the start: the shuttle's place at t = 0, heading for the next waypoint its way
        if going_up:
            target = next((j for j in range(1, len(route)) if float((route_a[j] - x0) @ (b - a)) > 0), len(route) - 1)
        else:
            target = next((j for j in range(len(route) - 2, -1, -1) if float((route_a[j] - x0) @ (b - a)) < 0), 0)
        regard = float(rng.uniform(*o.regard_robot))
        group = -1
        companion = rng.random() < o.group_probability
        shift = rng.choice([-1.0, 1.0]) * o.group_spacing_m * normal
        if companion and all(free(p, r) for p in np.vstack([route_a + shift, (x0 + shift)[None]])):
            group = i
            agents.append(Agent("person", r, route_a + shift, speeds, np.array(dwell), x0 + shift,
                                target, 1 if going_up else -1, regard, group))
        agents.append(Agent("person", r, route_a, speeds, np.array(dwell), x0, target,
                            1 if going_up else -1, regard, group))
    return SocialForceAgents(agents, grid, o.config)


#: the crossing-traffic models a navigation scenario can draw (``scenarios: {agents: ...}``)
AGENT_MODELS = ("constant_velocity", "social_force")


def crossing_traffic(model: str, path_xy_m: np.ndarray, n: int, rng: np.random.Generator,
                     grid: OccupancyGrid | None = None, **crossing_kwargs):
    """The crossing traffic of a scenario: ``constant_velocity`` shuttles
    (:func:`crossing_obstacles`) or ``social_force`` people and forklifts
    (:func:`social_crossings`, drawn from the same shuttles)."""
    if model == "constant_velocity":
        return crossing_obstacles(path_xy_m, n, rng, grid=grid, **crossing_kwargs)
    if model == "social_force":
        return social_crossings(path_xy_m, n, rng, grid=grid, **crossing_kwargs)
    raise DataError(f"crossing traffic model {model!r}: choose from {AGENT_MODELS}")


__all__ = ["AGENT_MODELS", "Agent", "CrowdOptions", "SocialForceAgents", "SocialForceConfig", "crossing_traffic",
           "social_crossings"]
