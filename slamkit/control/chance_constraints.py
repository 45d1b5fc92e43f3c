"""Chance constraints on obstacle clearance under a Gaussian pose error (constraint tightening).

A clearance constraint n^T (p - o) >= r on the robot position p (n the unit direction from the
obstacle o) holds with probability 1 - delta when p ~ N(p_hat, Sigma) if it holds for the mean
tightened by k sigma_n, sigma_n = sqrt(n^T Sigma n), k = Phi^-1(1 - delta) (Blackmore, Ono &
Williams, "Chance-constrained optimal path planning with obstacles", IEEE T-RO 27(6), 2011;
the same tightening as :func:`slamkit.maps.inflation.chance_inflation_m`). For a tracked
obstacle the error of its position estimate adds to the robot's (independent errors: the
covariances add).

:func:`tightened_world` applies it to what a local planner sees, so every controller (DWA,
rollout, the CasADi MPC, whose obstacle rows then are chance constraints) plans against the
tightened obstacles without knowing about covariances: each circle grows by k sigma_n along the
direction to the robot, and the static distance field shrinks by k sigma along the worst
direction (the largest eigenvalue: the field does not say which way the wall is).
"""

from __future__ import annotations

import numpy as np

from slamkit.control.protocols import DistanceGrid, LocalWorld
from slamkit.maps.inflation import chance_sigma_multiplier


def tightened_world(world: LocalWorld, robot_xy_m: np.ndarray, pose_cov_xy: np.ndarray,
                    collision_probability: float, circle_cov_xy: np.ndarray | None = None,
                    distance: DistanceGrid | None = None) -> LocalWorld:
    """``world`` with every obstacle grown by k sigma_n (see the module docstring).
    ``circle_cov_xy`` (K, 2, 2) the circles' position covariances (None: exact); ``distance``
    a static field already tightened (callers cache it per sigma; None: tightened here)."""
    k = chance_sigma_multiplier(collision_probability)
    cov = np.asarray(pose_cov_xy, float)[:2, :2]
    radii = world.circle_radius_m.copy()
    if world.num_circles:
        n = world.circle_xy_m - np.asarray(robot_xy_m, float).reshape(1, 2)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-9)
        total = cov[None] + (0.0 if circle_cov_xy is None else np.asarray(circle_cov_xy, float))
        var = np.einsum("ki,kij,kj->k", n, total, n)
        radii = radii + k * np.sqrt(np.maximum(var, 0.0))
    if distance is None and world.distance is not None:
        distance = tightened_distance(world.distance, cov, collision_probability)
    return LocalWorld(world.circle_xy_m, radii, world.circle_velocity_mps,
                      distance if distance is not None else world.distance, world.t_s)


def worst_sigma_m(pose_cov_xy: np.ndarray) -> float:
    """sqrt of the largest eigenvalue of the (2, 2) position covariance."""
    cov = np.asarray(pose_cov_xy, float)[:2, :2]
    return float(np.sqrt(max(float(np.linalg.eigvalsh(0.5 * (cov + cov.T))[-1]), 0.0)))


def tightened_distance(distance: DistanceGrid, pose_cov_xy: np.ndarray,
                       collision_probability: float) -> DistanceGrid:
    """The static field minus k sigma (worst direction), floored at 0."""
    margin = chance_sigma_multiplier(collision_probability) * worst_sigma_m(pose_cov_xy)
    return DistanceGrid(np.maximum(distance.distance_m - margin, 0.0), distance.resolution_m,
                        distance.origin_xy_m)
