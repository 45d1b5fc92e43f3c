"""Tiny landmark-world sequences built in the tests themselves (no dependency on slamkit.sim), so
the filters are checked against data whose generation the test controls exactly: noise levels,
kidnapping, known or unknown correspondences."""

from __future__ import annotations

import numpy as np

from slamkit.data.estimate import Prior
from slamkit.data.sequence import Odometry, RangeBearing, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.estimation._common import NoiseParams
from slamkit.geometry.angles import wrap_angle
from slamkit.models import diff_drive, range_bearing

NOISE = NoiseParams(sigma_v_mps=0.1, sigma_omega_radps=0.05, sigma_range_m=0.1, sigma_bearing_rad=0.02)


def ring_world(rng: np.random.Generator, n_landmarks: int = 16, radius_m: float = 6.0,
               jitter_m: float = 3.0) -> dict[int, np.ndarray]:
    """Landmarks scattered around a ring the robot circles (well spread, no symmetry)."""
    ang = np.linspace(0, 2 * np.pi, n_landmarks, endpoint=False) + rng.uniform(-0.2, 0.2, n_landmarks)
    r = radius_m + rng.uniform(-jitter_m, jitter_m, n_landmarks)
    pts = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
    return {int(i + 10): pts[i] for i in range(n_landmarks)}


def simulate(rng: np.random.Generator, landmarks: dict[int, np.ndarray], n_steps: int = 200,
             dt_s: float = 0.1, v_mps: float = 1.0, omega_radps: float = 0.2,
             noise: NoiseParams = NOISE, max_range_m: float = 8.0, obs_every: int = 1,
             known_ids: bool = True, kidnap_at: int | None = None,
             kidnap_pose: np.ndarray | None = None, start: np.ndarray | None = None) -> Sequence:
    """Robot follows constant (v, omega) from ``start`` (default (0, -5, 0): a circle of radius
    5 m round the origin at the default controls). Odometry reports the commanded controls plus
    Gaussian noise of ``noise``; observations see every landmark within ``max_range_m``."""
    ids = np.array(sorted(landmarks))
    lm = np.array([landmarks[i] for i in ids])
    x = np.array([0.0, -5.0, 0.0]) if start is None else np.asarray(start, float)
    u_true = np.array([v_mps, omega_radps])
    stamps, poses, events = [0.0], [x.copy()], []
    for k in range(1, n_steps + 1):
        t = k * dt_s
        x = np.asarray(diff_drive.motion(x, u_true, dt_s), dtype=float)
        if kidnap_at is not None and k == kidnap_at:
            x = np.asarray(kidnap_pose, dtype=float).copy()
        u_odo = u_true + rng.standard_normal(2) * [noise.sigma_v_mps, noise.sigma_omega_radps]
        events.append(Odometry(t, dt_s, float(u_odo[0]), float(u_odo[1])))
        if k % obs_every == 0:
            z = np.asarray(range_bearing.observe(np.broadcast_to(x, (len(lm), 3)), lm), dtype=float)
            vis = z[:, 0] < max_range_m
            zn = z[vis] + rng.standard_normal((int(vis.sum()), 2)) * [noise.sigma_range_m,
                                                                      noise.sigma_bearing_rad]
            zn[:, 1] = wrap_angle(zn[:, 1])
            lid = ids[vis] if known_ids else np.full(int(vis.sum()), -1)
            events.append(RangeBearing(t, lid, zn[:, 0], zn[:, 1]))
        stamps.append(t)
        poses.append(x.copy())
    gt = Trajectory.from_se2(np.array(stamps), np.array(poses))
    meta = {"odometry_sigma": (noise.sigma_v_mps, noise.sigma_omega_radps),
            "range_bearing_sigma": (noise.sigma_range_m, noise.sigma_bearing_rad)}
    return Sequence.from_events("test_ring", events, ground_truth=gt, world_p_landmarks=landmarks,
                                initial_world_xytheta_body=np.array(poses[0]), metadata=meta)


def exact_prior(seq: Sequence, sigma_xy_m: float = 0.05, sigma_theta_rad: float = 0.02) -> Prior:
    return Prior(np.asarray(seq.initial_world_xytheta_body, float),
                 np.diag([sigma_xy_m**2, sigma_xy_m**2, sigma_theta_rad**2]))


def run(estimator, seq: Sequence, prior: Prior | None = None):
    estimator.reset(prior if prior is not None else exact_prior(seq))
    for e in seq:
        estimator.step(e)
    return estimator.estimate()


def position_errors(estimate, seq: Sequence) -> np.ndarray:
    """Per-stamp position error (m) of the estimate against ground truth, matched by stamp."""
    gt = seq.ground_truth
    index = {round(float(t), 9): i for i, t in enumerate(gt.stamps_s)}
    rows = np.array([index[round(float(t), 9)] for t in estimate.trajectory.stamps_s])
    return np.linalg.norm(estimate.trajectory.world_t_body[:, :2] - gt.world_t_body[rows, :2], axis=1)


def pose_errors(estimate, seq: Sequence) -> np.ndarray:
    """(N, 3) estimate - truth with the heading wrapped, matched by stamp."""
    gt = seq.ground_truth
    index = {round(float(t), 9): i for i, t in enumerate(gt.stamps_s)}
    rows = np.array([index[round(float(t), 9)] for t in estimate.trajectory.stamps_s])
    e = estimate.trajectory.xytheta() - gt.xytheta()[rows]
    e[:, 2] = wrap_angle(e[:, 2])
    return e


def ate_rmse_m(estimate, seq: Sequence) -> float:
    """Position RMSE without alignment (the filters here share the ground-truth frame)."""
    return float(np.sqrt(np.mean(position_errors(estimate, seq) ** 2)))
