"""slamkit.metrics agrees with evo (the reference implementation) to 1e-9 on random trajectory
pairs: association, ATE and RPE statistics for every alignment evo supports, RPE delta in frames
and metres, consecutive and all pairs."""

from __future__ import annotations

import copy

import numpy as np
import pytest

evo_metrics = pytest.importorskip("evo.core.metrics")
from evo.core import sync  # noqa: E402
from evo.core import trajectory as evo_traj  # noqa: E402

from slamkit.data.trajectory import Trajectory  # noqa: E402
from slamkit.geometry import se3, so3  # noqa: E402
from slamkit.metrics import associate, ate, rpe  # noqa: E402

STATS = ("rmse", "mean", "median", "std", "min", "max", "sse")
RELATIONS = {
    "translation_m": evo_metrics.PoseRelation.translation_part,
    "rotation_rad": evo_metrics.PoseRelation.rotation_angle_rad,
    "rotation_deg": evo_metrics.PoseRelation.rotation_angle_deg,
}


def random_pair(seed: int, n: int = 150):
    """A smooth 3D reference, and an estimate = similarity-transformed noisy copy whose stamps
    are jittered and partly missing (so association matters)."""
    rng = np.random.default_rng(seed)
    xi = np.column_stack([rng.normal(0.5, 0.2, n), rng.normal(0, 0.1, (n, 2)),
                          rng.normal(0, 0.05, (n, 3))])
    steps = se3.exp(xi)
    T = np.empty((n, 4, 4))
    T[0] = se3.exp(rng.normal(size=6))
    for k in range(1, n):
        T[k] = T[k - 1] @ steps[k]
    stamps = 100.0 + 0.1 * np.arange(n)
    ref = Trajectory.from_matrices(stamps, T)
    noise = se3.exp(np.column_stack([rng.normal(0, 0.05, (n, 3)), rng.normal(0, 0.02, (n, 3))]))
    S = se3.exp(rng.normal(size=6))
    scale = rng.uniform(0.5, 2.0)
    est_T = T @ noise
    est_T[:, :3, 3] *= scale
    est_T = S @ est_T
    keep = np.sort(rng.choice(n, size=int(0.9 * n), replace=False))
    est_stamps = stamps[keep] + rng.uniform(-0.004, 0.004, len(keep))
    est = Trajectory.from_matrices(est_stamps, est_T[keep])
    return ref, est


def to_evo(t: Trajectory) -> evo_traj.PoseTrajectory3D:
    return evo_traj.PoseTrajectory3D(positions_xyz=np.array(t.world_t_body),
                                     orientations_quat_wxyz=np.array(t.world_q_body_wxyz),
                                     timestamps=np.array(t.stamps_s))


def evo_aligned(ref: Trajectory, est: Trajectory, mode: str):
    r, e = sync.associate_trajectories(to_evo(ref), to_evo(est), max_diff=0.01)
    e = copy.deepcopy(e)
    if mode == "origin":
        e.align_origin(r)
    elif mode in ("se3", "sim3"):
        e.align(r, correct_scale=mode == "sim3")
    return r, e


def assert_stats_equal(ours, metric):
    theirs = metric.get_all_statistics()
    for name in STATS:
        assert getattr(ours, name) == pytest.approx(theirs[name], rel=1e-9, abs=1e-12), name


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_association_matches_evo(seed):
    ref, est = random_pair(seed)
    ours = associate(ref, est, 0.01)
    r, e = sync.associate_trajectories(to_evo(ref), to_evo(est), max_diff=0.01)
    assert ours.num_pairs == r.num_poses == len(est)
    np.testing.assert_array_equal(ours.ref.stamps_s, r.timestamps)
    np.testing.assert_array_equal(ours.est.stamps_s, e.timestamps)
    # the estimate is the shorter one here; swap roles so the reference is shorter as well
    ours2 = associate(est, ref, 0.004)
    r2, e2 = sync.associate_trajectories(to_evo(est), to_evo(ref), max_diff=0.004)
    np.testing.assert_array_equal(ours2.ref.stamps_s, r2.timestamps)
    np.testing.assert_array_equal(ours2.est.stamps_s, e2.timestamps)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("mode", ["none", "origin", "se3", "sim3"])
def test_ate_matches_evo(seed, mode):
    ref, est = random_pair(seed)
    pair = associate(ref, est, 0.01)
    ours = ate(pair.ref, pair.est, mode)
    r, e = evo_aligned(ref, est, mode)
    np.testing.assert_allclose(ours.alignment.aligned.world_t_body, e.positions_xyz, atol=1e-9)
    for field, relation in RELATIONS.items():
        metric = evo_metrics.APE(relation)
        metric.process_data((r, e))
        assert_stats_equal(getattr(ours, field), metric)


@pytest.mark.parametrize("seed", [0, 3])
@pytest.mark.parametrize("mode", ["none", "origin", "se3", "sim3"])
@pytest.mark.parametrize("delta, unit, all_pairs", [
    (1, "frames", False), (5, "frames", False), (7, "frames", True),
    (3.0, "m", False), (4.0, "m", True),
])
def test_rpe_matches_evo(seed, mode, delta, unit, all_pairs):
    ref, est = random_pair(seed)
    pair = associate(ref, est, 0.01)
    ours = rpe(pair.ref, pair.est, delta, unit, all_pairs, align_mode=mode)
    r, e = evo_aligned(ref, est, mode)
    evo_unit = evo_metrics.Unit.frames if unit == "frames" else evo_metrics.Unit.meters
    for field, relation in RELATIONS.items():
        metric = evo_metrics.RPE(relation, delta, evo_unit, all_pairs=all_pairs)
        metric.process_data((r, e))
        assert ours.num_pairs == len(metric.error)
        np.testing.assert_array_equal(ours.pairs[:, 1], metric.delta_ids)
        assert_stats_equal(getattr(ours, field), metric)


def test_rpe_pairs_from_reference_matches_evo():
    ref, est = random_pair(4)
    pair = associate(ref, est, 0.01)
    ours = rpe(pair.ref, pair.est, 2.5, "m", all_pairs=True, align_mode="sim3",
               pairs_from_reference=True)
    r, e = evo_aligned(ref, est, "sim3")
    metric = evo_metrics.RPE(evo_metrics.PoseRelation.translation_part, 2.5, evo_metrics.Unit.meters,
                             all_pairs=True, pairs_from_reference=True)
    metric.process_data((r, e))
    assert_stats_equal(ours.translation_m, metric)


def test_quaternion_sign_does_not_matter():
    ref, est = random_pair(5)
    flipped = Trajectory(est.stamps_s, est.world_t_body, -est.world_q_body_wxyz)
    a = associate(ref, est)
    b = associate(ref, flipped)
    assert ate(a.ref, a.est, "se3").rotation_rad.rmse == pytest.approx(
        ate(b.ref, b.est, "se3").rotation_rad.rmse, abs=1e-12)
