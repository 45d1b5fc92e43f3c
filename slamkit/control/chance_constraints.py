"""Chance constraints on obstacle clearance under a Gaussian pose error (constraint tightening).

A clearance constraint n^T (p - o) >= r on the robot position p (n the unit direction from the
obstacle o) holds with probability 1 - delta when p ~ N(p_hat, Sigma) if it holds for the mean
tightened by k sigma_n, sigma_n = sqrt(n^T Sigma n), k = Phi^-1(1 - delta) (Blackmore, Ono &
Williams, "Chance-constrained optimal path planning with obstacles", IEEE T-RO 27(6), 2011;
the same tightening as :func:`slamkit.maps.inflation.chance_inflation_m`). For a tracked
obstacle the error of its position estimate adds to the robot's (independent errors: the
covariances add) -- unless the obstacle was measured relative to the robot (a lidar track): its
estimated position then carries the robot's pose error with it, the relative position the
collision depends on does not, and only the track's own covariance counts (``relative_circles``).

:func:`tightened_world` applies it to what a local planner sees, so every controller (DWA,
rollout, the CasADi MPC, whose obstacle rows then are chance constraints) plans against the
tightened obstacles without knowing about covariances: each circle grows by k sigma_n along the
direction to the robot, and the static distance field shrinks by k sigma along the worst
direction (the largest eigenvalue: the field does not say which way the wall is).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from slamkit.control.protocols import DistanceGrid, LocalWorld
from slamkit.errors import ConfigError
from slamkit.maps.inflation import chance_sigma_multiplier


def _multiplier(collision_probability: float | None, k_sigma: float | None) -> float:
    """k from delta, or ``k_sigma`` as given (a planner that could only afford a smaller k)."""
    if k_sigma is not None:
        if not (np.isfinite(k_sigma) and k_sigma >= 0):
            raise ConfigError(f"k_sigma must be finite and >= 0, got {k_sigma}")
        return float(k_sigma)
    if collision_probability is None:
        raise ConfigError("give collision_probability or k_sigma")
    return chance_sigma_multiplier(collision_probability)


def tightened_world(world: LocalWorld, robot_xy_m: np.ndarray, pose_cov_xy: np.ndarray,
                    collision_probability: float | None = None, circle_cov_xy: np.ndarray | None = None,
                    distance: DistanceGrid | None = None, *, k_sigma: float | None = None,
                    relative_circles: bool = False) -> LocalWorld:
    """``world`` with every obstacle grown by k sigma_n (see the module docstring), k from
    ``collision_probability`` or given as ``k_sigma``. ``circle_cov_xy`` (K, 2, 2) the circles'
    position covariances (None: exact); ``distance`` a static field already tightened (callers
    cache it per sigma; None: tightened here); ``relative_circles``: the circles were measured
    from the robot, so the pose covariance does not widen them (only ``circle_cov_xy``)."""
    k = _multiplier(collision_probability, k_sigma)
    cov = np.asarray(pose_cov_xy, float)[:2, :2]
    radii = world.circle_radius_m.copy()
    if world.num_circles:
        n = world.circle_xy_m - np.asarray(robot_xy_m, float).reshape(1, 2)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-9)
        total = (0.0 if relative_circles else cov[None]) + (0.0 if circle_cov_xy is None
                                                             else np.asarray(circle_cov_xy, float))
        var = np.einsum("ki,kij,kj->k", n, total, n)
        radii = radii + k * np.sqrt(np.maximum(var, 0.0))
    if distance is None and world.distance is not None:
        distance = tightened_distance(world.distance, cov, k_sigma=k)
    return dataclasses.replace(world, circle_radius_m=radii,
                               distance=distance if distance is not None else world.distance)


def worst_sigma_m(pose_cov_xy: np.ndarray) -> float:
    """sqrt of the largest eigenvalue of the (2, 2) position covariance."""
    cov = np.asarray(pose_cov_xy, float)[:2, :2]
    return float(np.sqrt(max(float(np.linalg.eigvalsh(0.5 * (cov + cov.T))[-1]), 0.0)))


def tightened_distance(distance: DistanceGrid, pose_cov_xy: np.ndarray,
                       collision_probability: float | None = None, *, k_sigma: float | None = None) -> DistanceGrid:
    """The static field minus k sigma (worst direction), floored at 0 (k as in
    :func:`tightened_world`)."""
    margin = _multiplier(collision_probability, k_sigma) * worst_sigma_m(pose_cov_xy)
    return DistanceGrid(np.maximum(distance.distance_m - margin, 0.0), distance.resolution_m,
                        distance.origin_xy_m)
