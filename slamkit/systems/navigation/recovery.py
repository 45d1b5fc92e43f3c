"""Recovery of the navigation stack after being stuck (:class:`Recovery`, configured by
:class:`RecoveryConfig`, the ``recovery`` section of
:class:`~slamkit.systems.navigation.NavigationConfig`), as nav2's: no progress (braking, a local
minimum, or a standstill the local planner's objective prefers) for ``stuck_s`` -- waiting for
crossing traffic is not being stuck (:meth:`Recovery.watch`) -- makes the stack replan and
recover for ``duration_s``: back off from the walls, return towards the path's centre line,
replan (:meth:`Recovery.recover`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from slamkit.control.path_following import point_at, project_on_path
from slamkit.control.protocols import ControlOutput, ControlStatus, LocalWorld
from slamkit.estimation.obstacle_tracker import Tracks
from slamkit.geometry.angles import wrap_angle
from slamkit.systems.navigation.command import CommandStatus, NavigationCommand

if TYPE_CHECKING:
    from slamkit.systems.navigation.stack import NavigationStack


@dataclass(frozen=True)
class RecoveryConfig:
    #: no progress for this long starts a recovery
    stuck_s: float = 3.0
    #: how long a recovery lasts
    duration_s: float = 2.0
    #: the recovery creeps on only while the disc plus this stays clear 0.3 m ahead
    margin_m: float = 0.05


class Recovery:
    """When the robot is stuck and what it does then; counts ``recoveries``."""

    def __init__(self, stack: NavigationStack):
        self.stack = stack

    @property
    def config(self) -> RecoveryConfig:
        return self.stack.config.recovery

    def reset(self) -> None:
        self.brake_since: float | None = None
        self.recover_until = -math.inf
        self.recoveries = 0

    def stuck(self, t_s: float) -> bool:
        """No progress for ``stuck_s`` (see :meth:`watch`)."""
        return self.brake_since is not None and t_s - self.brake_since >= self.config.stuck_s

    def start(self, t_s: float) -> None:
        """A recovery from now on (the stack has just replanned)."""
        self.brake_since = None
        self.recover_until = t_s + self.config.duration_s
        self.recoveries += 1

    def active(self, t_s: float) -> bool:
        return t_s < self.recover_until

    def watch(self, t_s: float, v_yield_mps: float, out: ControlOutput | None, cmd: np.ndarray) -> None:
        """After a cycle of the local planner: no progress (braking, a local minimum, or a
        standstill the objective prefers) starts the stuck clock; waiting for crossing traffic
        (``v_yield_mps`` under cruise speed) is not being stuck."""
        if v_yield_mps < self.stack.config.cruise_speed_mps:
            self.brake_since = None
        elif out.status in (ControlStatus.FALLBACK_BRAKE, ControlStatus.LOCAL_MINIMUM) or abs(cmd[0]) < 0.02:
            self.brake_since = t_s if self.brake_since is None else self.brake_since
        else:
            self.brake_since = None

    def recover(self, pose: np.ndarray, tracks: Tracks) -> NavigationCommand:
        """Recovery after being stuck (nav2's back-up, then back to the plan): first back off
        from the walls -- straight forwards or backwards, whichever side the distance field
        says is freer, turning in place first when both are worse -- until the disc is
        ``path_margin_m`` clear (the margin the global path keeps); then turn towards the path
        (:meth:`recovery_target`) and creep along it while the robot's own disc stays clear of
        the map and the tracks. The stack replans when the recovery ends."""
        t0 = time.perf_counter()
        c, stack = self.config, self.stack
        world = LocalWorld(tracks.xy_m, tracks.radius_m, tracks.velocity_mps, stack.distance)
        cmd = self.back_off(pose, world)
        if cmd is None:
            target = self.recovery_target(pose, world)
            bearing = float(wrap_angle(math.atan2(target[1] - pose[1], target[0] - pose[0]) - pose[2]))
            cmd = np.array([0.0, float(np.clip(1.5 * bearing, -0.8, 0.8))])
            if abs(bearing) < 0.25:
                ahead = pose[:2] + np.outer(np.linspace(0.0, 0.3, 4), [math.cos(pose[2]), math.sin(pose[2])])
                if np.all(world.clearance_m(ahead) > stack.config.robot_radius_m + c.margin_m):
                    cmd = np.array([0.1, float(np.clip(1.5 * bearing, -0.8, 0.8))])
        if stack.now_s + 0.1 >= self.recover_until:
            stack.planning.last_plan_s = -math.inf  # replan from where the recovery left the robot
        stack.timings_s["local_planner"].append(time.perf_counter() - t0)
        return stack._send(cmd, CommandStatus.RECOVERY)

    def recovery_target(self, pose: np.ndarray, world: LocalWorld, lookahead_m: float = 1.0,
                        step_m: float = 0.05) -> np.ndarray:
        """Where the recovery heads: the farthest path point up to ``lookahead_m`` beyond the
        nearest one that the robot can drive to in a straight line (its disc plus
        ``margin_m`` clear of the map and the tracks all the way), else the nearest
        path point ahead. The plain point ``lookahead_m`` ahead cuts the corners of the path:
        where the path bends around a wall corner it lies straight ahead through the wall's
        margin, the creep is never clear and the recovery turns towards it for ever (measured:
        Willow 13, 13 recoveries in a row before the 0.7 m passage under a block, 90 s limit)."""
        path = self.stack.path
        s0 = project_on_path(path, pose[:2])
        ahead = point_at(path, s0 + np.arange(step_m, lookahead_m + 1e-9, step_m))  # (K, 2)
        frac = np.linspace(0.0, 1.0, 41)[:, None, None]  # points along each straight line (<= 3 cm apart)
        lines = pose[None, None, :2] + frac * (ahead[None] - pose[None, None, :2])  # (41, K, 2)
        clear = (world.clearance_m(lines.reshape(-1, 2)).reshape(lines.shape[:2])
                 > self.stack.config.robot_radius_m + self.config.margin_m).all(axis=0)
        return ahead[int(np.flatnonzero(clear)[-1])] if clear.any() else ahead[0]

    def back_off(self, pose: np.ndarray, world: LocalWorld, step_m: float = 0.1) -> np.ndarray | None:
        """The back-off command of :meth:`recover` (None once the disc is the global path's
        ``path_margin_m`` clear of the walls): 0.1 m/s along +-heading towards the freer side;
        when neither side gains clearance, turn in place towards the wall distance field's
        gradient (or away from it, whichever is the smaller turn), then drive along it."""
        stack = self.stack
        here = float(world.clearance_m(pose[:2])[0])
        if here >= stack.config.robot_radius_m + stack.config.planning.path_margin_m:
            return None
        u = np.array([math.cos(pose[2]), math.sin(pose[2])])
        probes = pose[:2] + np.outer([step_m, -step_m], u)
        gain = world.clearance_m(probes) - here
        k = int(np.argmax(gain))
        if gain[k] > 0.25 * step_m:
            return np.array([(0.1, -0.1)[k], 0.0])
        grad = stack.distance.query(pose[:2])[1]
        if not np.linalg.norm(grad) > 0:
            return None
        e = float(wrap_angle(math.atan2(grad[1], grad[0]) - pose[2]))
        e = float(wrap_angle(e - math.pi)) if abs(e) > 0.5 * math.pi else e  # face it or back along it
        return np.array([0.0, float(np.clip(1.5 * e, -0.8, 0.8))])
