"""Bundle adjustment (GTSAM projection factors, Huber kernel) on a synthetic scene with a known
answer: perturbed poses and points are brought back, outlier observations are bounded by the
robust kernel, and two fixed poses fix the gauge (scale included)."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.backend.bundle_adjustment import BundleAdjustmentConfig, bundle_adjust
from slamkit.errors import ConfigError
from slamkit.geometry import se3, so3
from slamkit.models.camera import PinholeCamera

CAM = PinholeCamera(700.0, 700.0, 600.0, 180.0, width=1200, height=360)


def _scene(rng, n_frames=6, n_points=150):
    poses = np.stack([se3.from_rotation_translation(so3.exp(np.array([0.0, 0.02 * k, 0.0])), np.array([0.0, 0.0, 1.0 * k]))
                      for k in range(n_frames)])
    points = rng.uniform([-8, -3, 8], [8, 2, 40], (n_points, 3))
    f, p, uv = [], [], []
    for k, T in enumerate(poses):
        proj = CAM.project_world(T, points)
        ok = CAM.in_image(proj)
        f += [k] * int(ok.sum())
        p += np.flatnonzero(ok).tolist()
        uv.append(proj[ok])
    return poses, points, np.array(f), np.array(p), np.concatenate(uv)


def test_bundle_adjustment_recovers_perturbed_poses_and_points_despite_outliers():
    rng = np.random.default_rng(0)
    poses, points, f, p, uv = _scene(rng)
    uv = uv + rng.normal(0, 0.5, uv.shape)
    bad = rng.random(len(uv)) < 0.05
    uv[bad] += rng.uniform(-40, 40, (bad.sum(), 2))
    noisy_poses = poses.copy()
    for k in range(2, len(poses)):
        noisy_poses[k] = poses[k] @ se3.exp(rng.normal(0, [0.1, 0.1, 0.1, 0.01, 0.01, 0.01]))
    noisy_points = points + rng.normal(0, 0.5, points.shape)
    intrinsics = (CAM.fx, CAM.fy, CAM.cx, CAM.cy)
    errors = {}
    for kernel in ("none", "huber", "cauchy"):
        res = bundle_adjust(noisy_poses, noisy_points, f, p, uv, intrinsics, fixed=(0, 1),
                            config=BundleAdjustmentConfig(robust=kernel))
        np.testing.assert_allclose(res.world_T_camera[:2], poses[:2], atol=1e-6)  # held
        assert res.final_error < res.initial_error
        errors[kernel] = np.linalg.norm(res.world_T_camera[2:, :3, 3] - poses[2:, :3, 3], axis=1).max()
        if kernel == "cauchy":
            relative = np.linalg.norm(res.world_p - points, axis=1) / np.linalg.norm(points, axis=1)
            assert np.median(relative) < 0.02  # points 8-40 m away, 0.5 px noise
    before = np.linalg.norm(noisy_poses[2:, :3, 3] - poses[2:, :3, 3], axis=1).max()
    # measured: 0.19 m before; after: none 0.45 m (pulled by the 5 % gross outliers), Huber 0.044 m,
    # Cauchy 0.008 m
    assert before > 0.1
    assert errors["cauchy"] < 0.02 and errors["huber"] < 0.1 < errors["none"]


def test_points_seen_once_are_left_alone_and_bad_input_is_refused():
    rng = np.random.default_rng(1)
    poses, points, f, p, uv = _scene(rng, n_frames=3, n_points=20)
    only_first = f == 0
    res = bundle_adjust(poses, points, f[only_first], p[only_first], uv[only_first], (700, 700, 600, 180), fixed=(0,))
    assert not res.used_points.any() and np.array_equal(res.world_p, points)
    with pytest.raises(ConfigError):
        bundle_adjust(poses, points, f, p[:-1], uv, (700, 700, 600, 180))
    with pytest.raises(ConfigError):
        BundleAdjustmentConfig(robust="tukey")
