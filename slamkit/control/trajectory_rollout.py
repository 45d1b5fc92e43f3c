"""Trajectory rollout as a controller (Gerkey & Konolige 2008, "Planning and control in
unstructured terrain", the ``base_local_planner`` of ROS), beside the Dynamic Window Approach.

The two differ in what they sample and how they simulate it (the ROS documentation states it
the same way): DWA samples the velocities reachable within *one control period*,
v_c +- a dt, and holds each over the horizon; trajectory rollout samples the velocities
reachable over the *whole simulation horizon*, v_c +- a T, and simulates the robot accelerating
towards each at the acceleration limits (so the arcs are not circles: they start at the current
velocity). Everything else -- the admissibility test, the tiers, the scoring -- is DWA's
(:mod:`slamkit.control.dwa`), with the course's objective as the default weights:

    G(v, omega) = alpha heading + beta clearance + gamma velocity,  alpha = 0.8, beta = 0.2, gamma = 0.4

(the path-distance and progress terms of ROS are off by default, ``w_path = w_progress = 0``).
The rollout is one loop over the horizon's steps, vectorised over all candidates.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from slamkit.control.dwa import DWAConfig, DWAController
from slamkit.control.protocols import RobotState
from slamkit.control.rollout import rollout_profiles


@dataclass(frozen=True)
class RolloutConfig(DWAConfig):
    #: the course's objective: alpha heading + beta clearance + gamma velocity
    w_heading: float = 0.8
    w_clearance: float = 0.2
    w_velocity: float = 0.4
    w_path: float = 0.0
    w_progress: float = 0.0


def ramped_commands(command: np.ndarray, targets: np.ndarray, config: DWAConfig, steps: int) -> np.ndarray:
    """(2,) current (v, omega), (K, 2) targets -> (K, steps, 2): the command of each rollout step,
    moving from the current one towards the target by at most a dt and alpha dt per step."""
    k = np.arange(1, steps + 1)[None, :, None] * config.rollout_dt_s
    rate = np.array([config.accel_max_mps2, config.alpha_max_radps2])
    delta = np.asarray(targets, float)[:, None, :] - np.asarray(command, float)[None, None, :]
    return np.asarray(command, float) + np.clip(delta, -rate * k, rate * k)


class RolloutController(DWAController):
    name = "rollout"

    def __init__(self, config: RolloutConfig = RolloutConfig()):
        super().__init__(config)

    def candidates(self, state: RobotState) -> np.ndarray:
        """A grid over the velocities reachable within the horizon (not one period)."""
        c = self.config
        v_c, w_c = state.command
        v = np.linspace(max(c.v_min_mps, v_c - c.accel_max_mps2 * c.horizon_s),
                        min(c.v_max_mps, v_c + c.accel_max_mps2 * c.horizon_s), c.n_v)
        w = np.linspace(max(-c.omega_max_radps, w_c - c.alpha_max_radps2 * c.horizon_s),
                        min(c.omega_max_radps, w_c + c.alpha_max_radps2 * c.horizon_s), c.n_omega)
        vv, ww = np.meshgrid(v, w, indexing="ij")
        return np.column_stack([vv.ravel(), ww.ravel()])

    def rollouts(self, state: RobotState, cand: np.ndarray, steps: int) -> np.ndarray:
        return rollout_profiles(state.world_xytheta_body, ramped_commands(state.command, cand, self.config, steps),
                                self.config.rollout_dt_s)

    def compute(self, state, reference, world):
        out = super().compute(state, reference, world)
        if out.chosen < 0 or not np.isfinite(out.command).all():
            return out
        # the command sent now is the first step of the chosen ramp, not its target
        first = ramped_commands(state.command, out.command[None, :], self.config, 1)[0, 0]
        return replace(out, command=first, info={**out.info, "target_command": tuple(out.command.tolist())})
