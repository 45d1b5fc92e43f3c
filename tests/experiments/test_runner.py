"""The runner feeds every estimator the same events and scores them with stated numbers."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.data.estimate import Estimate, Prior
from slamkit.data.sequence import Odometry, RangeBearing, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError, DataError, EstimationError
from slamkit.experiments import estimators as registry
from slamkit.experiments.runner import (
    ErrorSeries,
    EstimatorRun,
    landmark_rmse_m,
    monte_carlo_nees,
    run_estimators,
    score,
    world_pose_covariances,
)
from slamkit.naming import SlamkitDeprecationWarning


def _straight_sequence(n: int = 21) -> Sequence:
    """Drive along x at 1 m/s for (n - 1) * 0.1 s; one observation of landmark 0 per stamp."""
    stamps = np.arange(n) * 0.1
    poses = np.column_stack([stamps, np.zeros(n), np.zeros(n)])
    events = []
    for k, t in enumerate(stamps):
        if k:
            events.append(Odometry(float(t), 0.1, 1.0, 0.0))
        events.append(RangeBearing(float(t), np.array([0]), np.array([5.0 - t]), np.array([0.0])))
    return Sequence("straight", tuple(events), Trajectory.from_se2(stamps, poses),
                    {0: np.array([5.0, 0.0]), 1: np.array([0.0, 3.0])}, poses[0].copy(),
                    {"initial_pose_sigma": [0.01, 0.01, 0.01]})


class OffsetFilter:
    """Reports the true pose + (0.1, 0, 0) with covariance diag(0.01, 1, 1): NEES = 1 exactly."""

    name = "offset"

    def __init__(self, sequence: Sequence):
        self.truth = sequence.ground_truth
        self.events: list = []

    def reset(self, prior: Prior) -> None:
        self.prior = prior
        self.events = []

    def step(self, event) -> None:
        self.events.append(event)

    def estimate(self) -> Estimate:
        stamps = sorted({e.stamp_s for e in self.events})
        xyt = self.truth.xytheta()[: len(stamps)] + [0.1, 0.0, 0.0]
        P = np.tile(np.diag([0.01, 1.0, 1.0]), (len(stamps), 1, 1))
        return Estimate(Trajectory.from_se2(np.array(stamps), xyt), P,
                        world_p_landmarks={0: np.array([5.1, 0.0]), 1: np.array([0.1, 3.0])},
                        nis=np.array([2.0, 4.0]))


class CountingBatch:
    name = "batch_count"

    def __init__(self, sequence: Sequence):
        self.calls = 0

    def solve(self, sequence: Sequence) -> Estimate:
        self.calls += 1
        gt = sequence.ground_truth
        return Estimate(gt, np.tile(np.eye(3) * 1e-4, (len(gt), 1, 1)))


class Failing(OffsetFilter):
    def step(self, event) -> None:
        raise EstimationError("diverged on purpose")


class Snapshots:
    wants_steps = True
    step_every = 5

    def __init__(self):
        self.snaps = []

    def on_step(self, snapshot) -> None:
        self.snaps.append(snapshot)


def test_every_online_estimator_sees_every_event_and_is_timed_per_step() -> None:
    seq = _straight_sequence()
    built = {}

    def make(cls):
        def f(sequence):
            built[cls.__name__] = cls(sequence)
            return built[cls.__name__]
        return f

    batch = make(CountingBatch)
    batch.kind = "batch"
    runs = run_estimators(seq, {"offset": make(OffsetFilter), "batch": batch, "bad": make(Failing)})
    assert len(built["OffsetFilter"].events) == len(seq) == 41
    assert [type(e) for e in built["OffsetFilter"].events] == [type(e) for e in seq.events]
    assert runs["offset"].step_latency_s.shape == (41,) and np.all(runs["offset"].step_latency_s >= 0)
    assert built["CountingBatch"].calls == 1 and runs["batch"].step_latency_s.shape == (1,)
    assert runs["batch"].kind == "batch" and not runs["batch"].online
    # the prior is the sequence's initial pose with metadata['initial_pose_sigma']
    np.testing.assert_allclose(built["OffsetFilter"].prior.covariance, np.diag([1e-4] * 3))
    assert runs["bad"].estimate is None and "diverged on purpose" in runs["bad"].failed


def test_snapshots_only_every_kth_step_and_only_when_wanted() -> None:
    seq = _straight_sequence()
    obs = Snapshots()
    run_estimators(seq, {"offset": OffsetFilter}, observer=obs, run_label="straight/seed0")
    # 41 events, every 5th (0, 5, ..., 40): 9 snapshots; the last event is index 40
    assert [s.index for s in obs.snaps] == list(range(0, 41, 5))
    s = obs.snaps[-1]
    assert s.run == "straight/seed0/offset" and s.stamp_s == pytest.approx(2.0)
    assert s.kind == "estimators" and s.state.estimator == "offset"
    np.testing.assert_allclose(s.state.pose.xytheta(), [[2.1, 0.0, 0.0]])
    np.testing.assert_allclose(s.state.covariance, np.diag([0.01, 1.0, 1.0]))
    assert s.state.observation.landmark_ids.tolist() == [0]
    assert set(s.state.landmark_ids.tolist()) == {0, 1}
    np.testing.assert_allclose(s.state.world_p_landmarks, [[5.1, 0.0], [0.1, 3.0]])
    quiet = Snapshots()
    quiet.wants_steps = False
    run_estimators(seq, {"offset": OffsetFilter}, observer=quiet)
    assert quiet.snaps == []


def test_score_of_a_constant_offset() -> None:
    seq = _straight_sequence()
    run = run_estimators(seq, {"offset": OffsetFilter})["offset"]
    scored = score(run, seq.ground_truth, seq.world_p_landmarks)
    m = scored.metrics
    # a constant offset is removed by the SE(2) alignment; NEES uses the unaligned error:
    # 0.1^2 / 0.01 = 1 at every pose, inside the single-sample chi2(3) band [0.216, 9.35]
    assert m["ate_rmse_m"] == pytest.approx(0.0, abs=1e-9)
    assert m["ate_rot_rmse_rad"] == pytest.approx(0.0, abs=1e-9)
    assert m["rpe_rmse_m"] == pytest.approx(0.0, abs=1e-9)
    assert m["nees_mean"] == pytest.approx(1.0)
    assert m["nees_in_band_fraction"] == 1.0
    assert m["nis_mean"] == pytest.approx(3.0)
    # the landmark map is shifted by (0.1, 0) as a whole: zero after alignment
    assert m["landmark_rmse_m"] == pytest.approx(0.0, abs=1e-9)
    assert set(m) >= {"step_latency_median_ms", "step_latency_p99_ms", "total_time_s"}
    np.testing.assert_allclose(scored.series.error[:, 0], 0.1)
    np.testing.assert_allclose(scored.series.sigma[0], [0.1, 1.0, 1.0])
    # against a non-truth reference NEES is not computed
    assert "nees_mean" not in score(run, seq.ground_truth, reference_is_truth=False).metrics


def _helix_sequence(n: int = 21) -> Sequence:
    """A 3D ground truth: a helix of radius 2 m at 1 m/s around z, climbing 0.5 m/s, for
    (n - 1) * 0.1 s."""
    from slamkit.geometry import so3

    stamps = np.arange(n) * 0.1
    t = np.column_stack([2.0 * np.sin(0.5 * stamps), 2.0 * (1.0 - np.cos(0.5 * stamps)), 0.5 * stamps])
    R = so3.exp(np.column_stack([np.zeros(n), np.zeros(n), 0.5 * stamps]))
    events = tuple(Odometry(float(s), 0.1, 1.0, 0.0) for s in stamps[1:])
    return Sequence("helix", events, Trajectory(stamps, t, so3.to_quat_wxyz(R)),
                    initial_world_xytheta_body=np.zeros(3))


class Offset3DFilter:
    """Reports every true pose moved by (0.1, 0, 0.2) m and turned by 0.05 rad about the world y
    axis (a left perturbation), with covariance diag(0.01, 1, 0.04, 1, 0.0025, 1) in the
    runner's world (x, y, z, rx, ry, rz) convention: NEES = 1 + 1 + 1 = 3 at every pose."""

    name = "offset3d"

    def __init__(self, sequence: Sequence):
        self.truth = sequence.ground_truth

    def reset(self, prior: Prior) -> None:
        self.k = 0

    def step(self, event) -> None:
        self.k += 1

    def estimate(self) -> Estimate:
        from slamkit.geometry import so3

        truth = self.truth.subset(np.arange(self.k + 1))
        R = so3.exp(np.array([0.0, 0.05, 0.0])) @ so3.from_quat_wxyz(truth.world_q_body_wxyz)
        traj = Trajectory(truth.stamps_s, truth.world_t_body + [0.1, 0.0, 0.2], so3.to_quat_wxyz(R))
        P = np.tile(np.diag([0.01, 1.0, 0.04, 1.0, 0.0025, 1.0]), (len(traj), 1, 1))
        return Estimate(traj, P)


def test_a_3d_estimate_is_scored_with_six_dof() -> None:
    seq = _helix_sequence()
    obs = Snapshots()
    run = run_estimators(seq, {"offset3d": Offset3DFilter}, observer=obs, kind="inertial")["offset3d"]
    scored = score(run, seq.ground_truth)
    m = scored.metrics
    # NEES 3 at every pose, inside the single-sample chi2(6) 95% band [1.237, 14.449]
    assert m["nees_mean"] == pytest.approx(3.0)
    assert m["nees_in_band_fraction"] == 1.0
    # the SE(3) alignment removes the constant translation, not the per-pose turn
    assert m["ate_rmse_m"] == pytest.approx(0.0, abs=1e-9)
    assert m["ate_rot_rmse_rad"] == pytest.approx(0.05, abs=1e-9)
    assert scored.series.dof == 6
    np.testing.assert_allclose(scored.series.error, np.tile([0.1, 0.0, 0.2, 0.0, 0.05, 0.0], (21, 1)), atol=1e-12)
    np.testing.assert_allclose(scored.series.sigma[0], [0.1, 1.0, 0.2, 1.0, 0.05, 1.0])
    np.testing.assert_allclose(scored.series.position_error_m, np.hypot(0.1, 0.2))
    # snapshots carry the 3D pose and its 6x6 covariance, tagged with the calling pipeline
    last = obs.snaps[-1]
    assert last.kind == "inertial" and not last.state.pose.planar
    np.testing.assert_allclose(last.state.pose.world_t_body, [[2 * np.sin(1.0) + 0.1, 2 * (1 - np.cos(1.0)), 1.2]])
    assert last.state.covariance.shape == (6, 6)
    # 20 runs of 6 dof: the two-sided 95% band of chi2(120) / 20 is [4.579, 7.611]
    stamps, anees, band = monte_carlo_nees([scored.series] * 20)
    np.testing.assert_allclose(anees, 3.0)
    assert band == pytest.approx((4.5786, 7.6106), abs=1e-3)


def test_nees_series_of_different_dimensions_are_not_averaged() -> None:
    planar = ErrorSeries(np.arange(2.0), np.zeros((2, 3)), None, np.ones(2))
    spatial = ErrorSeries(np.arange(2.0), np.zeros((2, 6)), None, np.ones(2))
    with pytest.raises(DataError, match=r"different pose dimensions \[3, 6\]"):
        monte_carlo_nees([planar, spatial])


def test_landmark_rmse_after_alignment_worked_example() -> None:
    truth = {0: np.array([0.0, 0.0]), 1: np.array([4.0, 0.0]), 2: np.array([0.0, 4.0]), 3: np.array([9.0, 9.0])}
    # rotate the true map by 90 degrees and shift it: a rigid motion, removed exactly
    R = np.array([[0.0, -1.0], [1.0, 0.0]])
    moved = {k: R @ v + [2.0, -1.0] for k, v in truth.items()}
    assert landmark_rmse_m(moved, truth) == pytest.approx(0.0, abs=1e-12)
    # two landmarks mirrored about the centroid axis cannot be aligned: errors remain
    est = {0: np.array([0.0, 0.0]), 1: np.array([2.0, 0.0])}
    ref = {0: np.array([0.0, 0.0]), 1: np.array([4.0, 0.0])}
    # the best rigid fit centres both segments: each endpoint is 1 m off
    assert landmark_rmse_m(est, ref) == pytest.approx(1.0)
    assert np.isnan(landmark_rmse_m({0: np.zeros(2)}, ref))


def test_body_frame_marginals_are_rotated_into_the_world_frame() -> None:
    from slamkit.geometry.se2 import covariance_body_to_world

    # heading +90 deg: body x (forward, variance 1) is world y, body y (variance 4) is world x
    world = covariance_body_to_world(np.array([0.0, 0.0, np.pi / 2]), np.diag([1.0, 4.0, 0.1]))
    np.testing.assert_allclose(world, np.diag([4.0, 1.0, 0.1]), atol=1e-12)
    traj = Trajectory.from_se2(np.array([0.0]), np.array([[0.0, 0.0, np.pi / 2]]))
    body = np.diag([1.0, 4.0, 0.1])[None]
    np.testing.assert_allclose(world_pose_covariances(Estimate(traj, body))[0], body[0])  # as reported


def test_monte_carlo_nees_band_for_twenty_runs() -> None:
    s = [ErrorSeries(np.arange(3.0), np.zeros((3, 3)), None, np.array([1.0, 3.0, 5.0]) + k / 20)
         for k in range(20)]
    stamps, anees, band = monte_carlo_nees(s)
    np.testing.assert_allclose(anees, [1.475, 3.475, 5.475])
    # chi2(60) 2.5% / 97.5% quantiles are 40.482 and 83.298; divided by M = 20
    assert band == pytest.approx((2.0241, 4.1649), abs=1e-3)


def test_registry_names_and_errors() -> None:
    assert {"ekf", "ukf", "pf", "mcl"} <= set(registry.available())
    assert set(registry.names()) >= {"ekf_slam", "fastslam", "batch", "isam2", "fixed_lag"}
    with pytest.raises(ConfigError, match="unknown estimator 'kf9'"):
        registry.factory("kf9")
    with pytest.raises(ConfigError, match=r"unknown estimator 'isam' \(did you mean 'isam2'\?\); known: ekf, "):
        registry.factory("isam")
    with pytest.warns(SlamkitDeprecationWarning, match="estimator name 'fixed-lag' is deprecated; write 'fixed_lag'"):
        assert registry.factory("fixed-lag").name == "fixed_lag"
    seq = _straight_sequence()
    with pytest.raises(ConfigError, match="unknown parameter"):
        registry.factory("pf", {"n_particle": 10})(seq)
    bare = Sequence("no_map", seq.events, seq.ground_truth)
    with pytest.raises(ConfigError, match="known landmark map"):
        registry.factory("ekf")(bare)


def test_ekf_through_the_registry_on_a_simulated_world() -> None:
    from slamkit.sim.landmark_world import mildly_nonlinear, simulate_landmark_sequence

    seq = simulate_landmark_sequence(mildly_nonlinear(duration_s=15.0), np.random.default_rng(3))
    pf = registry.factory("pf", {"n_particles": 200}, seed=1)
    runs = run_estimators(seq, {"ekf": registry.factory("ekf"), "pf": pf})
    for name, run in runs.items():
        m = score(run, seq.ground_truth, seq.world_p_landmarks).metrics
        # 0.1 m / 1 deg range-bearing noise to ~10 landmarks at 10 Hz: centimetre accuracy
        assert m["ate_rmse_m"] < 0.05, name
        assert 0.5 < m["nees_mean"] < 8.0, name
    # the same seed gives the same particle filter run
    again = run_estimators(seq, {"pf": registry.factory("pf", {"n_particles": 200}, seed=1)})["pf"]
    np.testing.assert_array_equal(again.estimate.trajectory.world_t_body,
                                  runs["pf"].estimate.trajectory.world_t_body)
