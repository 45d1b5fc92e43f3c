"""Trajectory rollout (Gerkey & Konolige 2008, "Planning and control in unstructured terrain",
the ROS base_local_planner): simulate every candidate command held constant over a short horizon
and score the resulting arcs.

With (v, omega) held constant the unicycle drives an exact circular arc, so the pose after time t
is the velocity motion model applied once with dt = t (``slamkit.models.diff_drive.motion``).
All candidates and all horizon samples are therefore produced by one broadcast call, with no
Python loop over candidates or time steps.
"""

from __future__ import annotations

import numpy as np

from slamkit.control.protocols import LocalWorld
from slamkit.models.diff_drive import motion


def rollout_arcs(world_xytheta_body: np.ndarray, commands: np.ndarray, dt_s: float, steps: int) -> np.ndarray:
    """(3,) start pose, (K, 2) constant (v, omega) commands -> (K, steps + 1, 3) poses at
    t = 0, dt, ..., steps * dt (heading wrapped to [-pi, pi))."""
    u = np.asarray(commands, dtype=float).reshape(-1, 2)
    t = dt_s * np.arange(steps + 1)
    pose = np.asarray(world_xytheta_body, dtype=float).reshape(1, 1, 3)
    return motion(pose, u[:, None, :], t[None, :])


def rollout_profiles(world_xytheta_body: np.ndarray, commands: np.ndarray, dt_s: float) -> np.ndarray:
    """(3,) start pose, (K, T, 2) commands held for ``dt_s`` each (a speed profile: braking,
    reversing) -> (K, T + 1, 3) poses, each step an exact arc (one motion call per step, vectorised
    over the K profiles)."""
    u = np.asarray(commands, dtype=float)
    u = u.reshape((1,) * (3 - u.ndim) + u.shape)
    out = np.empty((u.shape[0], u.shape[1] + 1, 3))
    out[:, 0] = np.asarray(world_xytheta_body, dtype=float).reshape(3)
    for k in range(u.shape[1]):
        out[:, k + 1] = motion(out[:, k], u[:, k], dt_s)
    return out


def trajectory_clearance(traj_xytheta: np.ndarray, world: LocalWorld, dt_s: float,
                         robot_radius_m: float) -> np.ndarray:
    """(K, T+1, 3) rollouts -> (K, T+1) distance from the robot's disc to the nearest obstacle,
    moving circles predicted to the sample's time (negative = collision)."""
    t = dt_s * np.arange(traj_xytheta.shape[1])
    return world.clearance_m(traj_xytheta[..., :2], t) - robot_radius_m


def distance_to_collision(traj_xytheta: np.ndarray, clearance_m: np.ndarray, speeds_mps: np.ndarray,
                          dt_s: float) -> np.ndarray:
    """(K,) arc length travelled before the first sample whose clearance is <= 0 (inf when the
    rollout stays free), i.e. dist(v, omega) of Fox et al. 1997."""
    hit = clearance_m <= 0.0
    any_hit = hit.any(axis=1)
    first = np.argmax(hit, axis=1)  # index of the first colliding sample
    # the robot is safe at least until the sample before the hit
    dist = np.abs(np.asarray(speeds_mps, dtype=float)) * dt_s * np.maximum(first - 1, 0)
    return np.where(any_hit, dist, np.inf)
