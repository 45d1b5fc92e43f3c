"""The Dynamic Window Approach (Fox, Burgard & Thrun, "The dynamic window approach to collision
avoidance", IEEE Robotics & Automation Magazine 4(1), 1997).

Search space (section 4.1 of the paper), over velocities (v, omega):

* V_s  the velocity limits of the robot;
* V_d  the dynamic window reachable within one control period dt from the current (v_c, omega_c)
  under the acceleration limits:  [v_c - a dt, v_c + a dt] x [omega_c - alpha dt, omega_c + alpha dt];
* V_a  the admissible velocities, with which the robot can still stop before the nearest
  obstacle on its arc:  v <= sqrt(2 dist(v, omega) a_brake)  (eq. 9).

Objective (eq. 12): G = w_h heading + w_c clearance + w_v velocity, each term normalised to [0, 1]
with a fixed scale (not by the per-cycle sum of the paper, so that the weights mean the same in
every cycle): heading = 1 - |angle from the rollout's final heading to the target| / pi, where the
target is the point ``lookahead_m`` further along the global path than the projection of the
rollout's end (a fixed carrot ahead of the robot would be overshot by fast arcs, which then score
as "facing backwards": measured, that made the robot creep); velocity = v / v_max; clearance =
min(dist(v, omega), L) / L, the paper's distance to the first obstacle *on the arc*, with L the
longest arc of the horizon (1 for an arc that stays free). The paper's definition matters: a
"distance to the nearest obstacle anywhere" term penalises driving parallel to a wall, and
measured with it the robot stalled wherever a wall was within the cap.

Two terms from ROS base_local_planner keep the robot on the global path: path = 1 - min(distance
of the rollout's end from the path, ``path_cap_m``) / ``path_cap_m`` (``path_distance_bias``) and
progress = (arc length of the end's projection - that of the robot) / L (``goal_distance_bias``;
without it the path term rewards standing still on the path). Without the path term the carrot
pulls the robot across corners and, at doorways, into the door frame, where it deadlocks
(measured in the office scenarios).

Tiers (as ROS base_local_planner and PythonRobotics do in effect): when some admissible arc stays
free over the whole horizon only those compete, because the heading term measured at the end of a
long arc otherwise outweighs a collision two seconds away; admissible arcs that collide later
(the robot could still stop) are used only when no free one exists.

Candidates are a grid over the window, rolled out as exact arcs and scored all at once (numpy
broadcasting over candidates x horizon x obstacles). No admissible candidate -> brake.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from slamkit.geometry.angles import wrap_angle
from slamkit.control.path_following import crop, point_at, project_many, project_on_path
from slamkit.control.protocols import (non_finite_brake, ControlOutput, ControlStatus, DistanceGrid, LocalWorld,
                                       Reference, RobotState, brake_command)
from slamkit.control.rollout import distance_to_collision, rollout_arcs, trajectory_clearance
from slamkit.errors import ControlError


@dataclass(frozen=True)
class DWAConfig:
    dt_s: float = 0.1
    v_min_mps: float = 0.0
    v_max_mps: float = 0.8
    omega_max_radps: float = 1.5
    accel_max_mps2: float = 1.0
    alpha_max_radps2: float = 3.0
    #: deceleration used for the admissibility test (the robot's braking capability)
    brake_decel_mps2: float = 1.0
    n_v: int = 11
    n_omega: int = 21
    horizon_s: float = 2.0
    rollout_dt_s: float = 0.1
    robot_radius_m: float = 0.2
    safety_margin_m: float = 0.1
    # weights chosen on 12 seeded office/warehouse episodes (success 0.67 -> 0.75 vs 1/0.3/0.5)
    w_heading: float = 0.3
    w_clearance: float = 0.4
    w_velocity: float = 0.3
    w_path: float = 0.5
    w_progress: float = 1.0
    path_cap_m: float = 1.0
    lookahead_m: float = 1.0
    #: the heading term's target no further along the path than the robot sees it: the last path
    #: point before the first one its disc plus ``safety_margin_m`` cannot reach in a straight line
    #: through the static map (:meth:`DWAController.visible_s`). Where the path hooks round an
    #: obstacle the carrot ``lookahead_m`` ahead lies behind it, the heading term turns the robot to
    #: face it through the obstacle, and no admissible arc drives (issue 33: Willow development seed
    #: 3060 turned on the spot and recovered for 50 s beside a one-cell obstacle the path hooked
    #: round, and reached the goal in 27 s with it). Measured in the navigation stack (the course's
    #: weights) on development seeds 3000-3089 x 3 worlds, paired with the defaults' 259 / 5 / 0 / 6
    #: (successes / moving / static / timeouts, 2026-12-08): 260 / 6 / 0 / 4 -- 6 better (office
    #: 3052, Willow 3044 / 3054 / 3060 / 3066 / 3080), 5 worse (moving hits office 3012, warehouse
    #: 3000, Willow 3020; timeouts Willow 3040 / 3079). False (the plain carrot): no evidence that
    #: it helps the stack as a whole
    line_of_sight_target: bool = False
    goal_tolerance_m: float = 0.2

    def __post_init__(self) -> None:
        if self.n_v < 1 or self.n_omega < 1:
            raise ControlError("DWAConfig.n_v and n_omega must be >= 1")
        if min(self.dt_s, self.horizon_s, self.rollout_dt_s, self.accel_max_mps2,
               self.alpha_max_radps2, self.brake_decel_mps2) <= 0:
            raise ControlError("DWAConfig times and accelerations must be positive")
        if self.v_max_mps < self.v_min_mps:
            raise ControlError("DWAConfig.v_max_mps < v_min_mps")


def dynamic_window(v_c: float, omega_c: float, config: DWAConfig) -> tuple[tuple[float, float], tuple[float, float]]:
    """V_s intersected with V_d: ((v_lo, v_hi), (omega_lo, omega_hi))."""
    c = config
    v_lo = max(c.v_min_mps, v_c - c.accel_max_mps2 * c.dt_s)
    v_hi = min(c.v_max_mps, v_c + c.accel_max_mps2 * c.dt_s)
    w_lo = max(-c.omega_max_radps, omega_c - c.alpha_max_radps2 * c.dt_s)
    w_hi = min(c.omega_max_radps, omega_c + c.alpha_max_radps2 * c.dt_s)
    if v_lo > v_hi:  # current speed outside V_s (e.g. after a config change): nearest reachable
        v_lo = v_hi = float(np.clip(v_c, c.v_min_mps, c.v_max_mps))
    if w_lo > w_hi:
        w_lo = w_hi = float(np.clip(omega_c, -c.omega_max_radps, c.omega_max_radps))
    return (v_lo, v_hi), (w_lo, w_hi)



class DWAController:
    name = "dwa"

    def __init__(self, config: DWAConfig = DWAConfig()):
        self.config = config

    def reset(self) -> None:
        pass

    def candidates(self, state: RobotState) -> np.ndarray:
        (v_lo, v_hi), (w_lo, w_hi) = dynamic_window(*state.command, self.config)
        v = np.linspace(v_lo, v_hi, self.config.n_v)
        w = np.linspace(w_lo, w_hi, self.config.n_omega)
        vv, ww = np.meshgrid(v, w, indexing="ij")
        return np.column_stack([vv.ravel(), ww.ravel()])

    def visible_s(self, path_xy_m: np.ndarray, xy_m: np.ndarray, distance: DistanceGrid, step_m: float = 0.05) -> float:
        """How far along ``path_xy_m`` the robot at ``xy_m`` sees it: the arc length of the last
        point (every ``step_m`` from the robot's projection, up to ``lookahead_m`` plus the
        horizon's reach) before the first one it cannot reach in a straight line with its disc
        plus ``safety_margin_m`` clear of ``distance`` all the way (40 points on each line, <= 7
        cm apart: a miss of 3.5 cm adds < 3 mm to a 0.25 m clearance; a robot already closer to a
        wall than that needs only its present clearance); inf (no limit) when the first is not."""
        c = self.config
        s0 = project_on_path(path_xy_m, xy_m)
        s = s0 + np.arange(step_m, c.lookahead_m + c.v_max_mps * c.horizon_s + 1e-9, step_m)
        ahead = point_at(path_xy_m, s)
        frac = np.linspace(0.0, 1.0, 41)[1:, None, None]
        lines = xy_m[None, None, :] + frac * (ahead[None] - xy_m[None, None, :])
        need_m = min(c.robot_radius_m + c.safety_margin_m, float(distance.query(xy_m)[0]) - 1e-3)
        seen = np.logical_and.accumulate((distance.query(lines)[0] > need_m).all(axis=0))
        return float(s[np.flatnonzero(seen)[-1]]) if seen[0] else np.inf

    def rollouts(self, state: RobotState, cand: np.ndarray, steps: int) -> np.ndarray:
        """(K, 2) candidates -> (K, steps + 1, 3) poses: each command held over the horizon."""
        return rollout_arcs(state.world_xytheta_body, cand, self.config.rollout_dt_s, steps)

    def compute(self, state: RobotState, reference: Reference, world: LocalWorld) -> ControlOutput:
        if not state.finite:
            return non_finite_brake()
        t0 = time.perf_counter()
        c = self.config
        xy = state.world_xytheta_body[:2]
        goal = reference.goal_xy_m
        dist_goal = float(np.linalg.norm(goal - xy))
        if dist_goal <= c.goal_tolerance_m:
            cmd = brake_command(state.command, c.accel_max_mps2, c.alpha_max_radps2, c.dt_s)
            return ControlOutput(cmd, ControlStatus.GOAL_REACHED, solve_time_s=time.perf_counter() - t0)

        cand = self.candidates(state)
        steps = max(1, int(round(c.horizon_s / c.rollout_dt_s)))
        traj = self.rollouts(state, cand, steps)
        clear = trajectory_clearance(traj, world, c.rollout_dt_s, c.robot_radius_m + c.safety_margin_m)
        dist = distance_to_collision(traj, clear, cand[:, 0], c.rollout_dt_s)
        # |v|: a reversing arc must be able to stop before what is behind the robot too
        admissible = np.abs(cand[:, 0]) <= np.sqrt(2.0 * dist * c.brake_decel_mps2)
        # slow enough to stop at the goal (else the robot circles it)
        admissible &= cand[:, 0] <= max(np.sqrt(2.0 * dist_goal * c.brake_decel_mps2), c.v_min_mps)

        # only the part of the path the rollouts can reach matters (keeps the projection cheap)
        horizon_len = max(c.v_max_mps * c.horizon_s, 1e-9)
        s_robot = project_on_path(reference.path_xy_m, xy)
        local = crop(reference.path_xy_m, s_robot - 0.5, s_robot + horizon_len + c.path_cap_m + 0.5)
        s_end = project_many(local, traj[:, -1, :2])
        s_target = s_end + c.lookahead_m
        if c.line_of_sight_target and world.distance is not None:
            s_target = np.maximum(np.minimum(s_target, self.visible_s(local, xy, world.distance)), s_end)
        target = point_at(local, s_target)
        to_target = target - traj[:, -1, :2]
        bearing = np.arctan2(to_target[:, 1], to_target[:, 0])
        heading = 1.0 - np.abs(wrap_angle(bearing - traj[:, -1, 2])) / np.pi
        free = np.isinf(dist)
        clearance = np.minimum(dist, horizon_len) / horizon_len
        if np.any(admissible & free):
            admissible &= free
        velocity = cand[:, 0] / max(c.v_max_mps, 1e-9)
        off_path = np.linalg.norm(point_at(local, s_end) - traj[:, -1, :2], axis=1)
        path = 1.0 - np.minimum(off_path, c.path_cap_m) / c.path_cap_m
        s_now = project_many(local, xy[None, :])[0]
        progress = (s_end - s_now) / horizon_len
        score = (c.w_heading * heading + c.w_clearance * clearance + c.w_velocity * velocity
                 + c.w_path * path + c.w_progress * progress)
        score = np.where(admissible, score, -np.inf)
        info = {"window_v_mps": (float(cand[:, 0].min()), float(cand[:, 0].max())),
                "window_omega_radps": (float(cand[:, 1].min()), float(cand[:, 1].max())),
                "n_admissible": int(admissible.sum())}
        if not admissible.any():
            cmd = brake_command(state.command, c.accel_max_mps2, c.alpha_max_radps2, c.dt_s)
            return ControlOutput(cmd, ControlStatus.FALLBACK_BRAKE, candidates_xytheta=traj,
                                 scores=score, chosen=-1, solve_time_s=time.perf_counter() - t0,
                                 info=info)
        best = int(np.argmax(score))
        return ControlOutput(cand[best], ControlStatus.OK, candidates_xytheta=traj, scores=score,
                             chosen=best, solve_time_s=time.perf_counter() - t0, info=info)
