"""slamkit.systems.lidar_slam.LidarSlam: the streaming contract on a simulated warehouse, and the
system on the SLAM benchmark's Intel and Freiburg 079 logs scored by their relations (Kuemmerle
et al. 2009): a 120 s slice of Intel in the default run, the whole logs under ``slow`` with the
goals of issue 11 (Intel <= 0.031 m, fr079 <= 0.056 m mean translational relation error, below
1 deg rotational; lidar only within 1.5x of those).

The logs' configuration is the ``slam`` section of pipelines/lidar_slam_logs.yaml (what
``slamkit run`` uses). Logs come from the dataset registry (../shared/datasets, $SLAMKIT_DATA or
the cache); the tests skip when they are not available."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from slamkit.data import registry
from slamkit.data.sequence import Scan
from slamkit.errors import ConfigError, DataError
from slamkit.experiments.lidar_slam import (_sim_parts, _simulate, ate_keyframes_m, first_seconds, run_slam,
                                            slam_config_from)
from slamkit.experiments.pipeline import load_config
from slamkit.geometry import se2
from slamkit.metrics.relations import read_relations
from slamkit.systems.lidar_slam import LidarSlam, LidarSlamConfig

ROOT = Path(__file__).resolve().parents[2]
WORLD = {"name": "wh", "world": "warehouse", "world_size_m": [20.0, 20.0], "num_goals": 4, "duration_s": 60.0}


@pytest.fixture(scope="module")
def world():
    return _sim_parts(_simulate(WORLD, 0))


def same_poses(a: np.ndarray, b: np.ndarray, tol: float = 1e-9) -> bool:
    """Poses (N, 3) equal up to ``tol`` (headings compared on the circle)."""
    return bool(np.abs(se2.between(a, b)).max() <= tol)


class Recorder:
    def __init__(self):
        self.keyframes, self.loops = [], []

    def on_keyframe(self, kf):
        self.keyframes.append(kf)

    def on_loop_closure(self, closure):
        self.loops.append(closure)


def test_streaming_contract(world):
    seq, _ = world
    rec = Recorder()
    slam = LidarSlam(LidarSlamConfig(), seq.initial_world_xytheta_body, rec)
    scans = seq.of_type(Scan)
    for ev in seq:
        slam.step(ev)
    online = slam.estimate()
    # one pose per scan, stamped with the scan; keyframes are scans
    assert np.array_equal(online.stamps_s, [s.stamp_s for s in scans])
    assert online.world_xytheta_body.shape == (len(scans), 3)
    k = online.keyframe_scans
    assert len(k) == len(rec.keyframes) and [kf.index for kf in rec.keyframes] == list(range(len(k)))
    assert same_poses(online.world_xytheta_body[k], online.keyframe_poses)
    assert np.array_equal(online.keyframe_stamps_s, online.stamps_s[k])
    final = slam.finish()
    assert len(rec.loops) == len(final.loops) >= 10  # measured 27
    assert final.counters["loop_closures_online"] + final.counters["loop_closures_final"] == len(final.loops)
    assert same_poses(final.world_xytheta_body[k], final.keyframe_poses)
    # the first scan is where the sequence says the robot starts
    assert same_poses(final.world_xytheta_body[:1], np.reshape(seq.initial_world_xytheta_body, (1, 3)), 1e-3)
    with pytest.raises(DataError, match="after finish"):
        slam.step(scans[-1])
    grid = slam.map()
    assert grid.num_scans == len(k) and grid.resolution_m == LidarSlamConfig().map.resolution_m


def test_lidar_only_in_a_simulated_world(world):
    """Without wheel odometry (constant-velocity prior) the warehouse tour (69 keyframes) comes
    out about as well as with it. Measured ATE over the keyframes after SE(2) alignment: 0.0032 m
    with odometry, 0.0032 m without (27 loop closures each)."""
    seq, _ = world
    ate = {}
    for prior in ("odometry", "constant_velocity"):
        est = LidarSlam(LidarSlamConfig(motion_prior=prior), seq.initial_world_xytheta_body).run(seq).finish()
        ate[prior] = ate_keyframes_m(seq.ground_truth, est.keyframe_stamps_s, est.keyframe_poses)
    assert ate["odometry"] < 0.01
    assert ate["constant_velocity"] < 1.5 * ate["odometry"]


def test_config_is_checked():
    with pytest.raises(ConfigError, match="motion_prior"):
        LidarSlamConfig(motion_prior="imu")
    with pytest.raises(ConfigError, match="constant_velocity_per"):
        LidarSlamConfig(constant_velocity_per="minute")
    with pytest.raises(ConfigError, match="correlative"):
        LidarSlamConfig(correlative_below_fitness=1.5)
    with pytest.raises(ConfigError, match="robust"):
        LidarSlamConfig(robust="tukey")
    with pytest.raises(ConfigError, match="body_xytheta_lidar"):
        LidarSlamConfig(body_xytheta_lidar=(0.0, 0.0))
    cfg = slam_config_from({"motion_prior": "identity", "body_xytheta_lidar": [-0.04, 0, 0],
                            "isam2": {"relinearize_threshold": 0.05}})
    assert cfg.body_xytheta_lidar == (-0.04, 0.0, 0.0) and cfg.isam2.relinearize_threshold == 0.05


# ---- the SLAM benchmark's logs -------------------------------------------------------------------


def _log(name: str):
    entry = registry.get(f"{name}-log")
    if not registry.is_available(entry):
        pytest.skip(f"{entry.name} is not available locally (slamkit data fetch {entry.name})")
    return registry.load_recording(entry.name), read_relations(registry.relations_of(entry.name))


def logs_config() -> LidarSlamConfig:
    return slam_config_from(load_config(ROOT / "pipelines" / "lidar_slam_logs.yaml")["slam"])


@pytest.fixture(scope="module")
def intel():
    return _log("intel")


def test_intel_slice(intel):
    """The first 120 s of the Intel log (611 scans, the robot leaves its start room and drives
    ~25 m through two corridors; 48 relations fall inside): measured relation error
    0.016 +- 0.010 m / 0.18 +- 0.13 deg with odometry; raw odometry 0.02 +- 0.03 m."""
    seq, relations = intel
    piece = first_seconds(seq, 120.0)
    res = run_slam(piece, None, logs_config(), relations=relations)
    m = res.metrics
    assert m["relation_count"] == 48
    assert m["relation_trans_mean_m"] < 0.025 and m["relation_rot_mean_deg"] < 0.3
    assert m["relation_trans_mean_m"] < m["relation_trans_mean_m_odometry"]
    # the trajectory of every scan at the scans' ipc stamps
    stamps = [e.stamp_s for e in piece if isinstance(e, Scan)]
    assert np.array_equal(res.scan_stamps_s, stamps)
    assert m["num_scans"] == len(stamps) and m["realtime_factor"] > 0


GOALS = {"intel": 0.031, "fr079": 0.056}


LIDAR_ONLY_INTEL = pytest.mark.xfail(
    reason="Intel lidar only is not there yet: a few wrong matches (scans turning 30-50 deg between "
           "ipc stamps, corridors) break the map; measured 0.33-0.68 m mean, goal 0.047 m", strict=False)


@pytest.mark.slow
@pytest.mark.parametrize("name, prior", [("intel", "odometry"), ("fr079", "odometry"),
                                         pytest.param("intel", "constant_velocity", marks=LIDAR_ONLY_INTEL),
                                         ("fr079", "constant_velocity")])
def test_benchmark_goals(name, prior):
    """Issue 11's goals on the whole logs: the published graph-mapping result (Intel 0.031 m,
    fr079 0.056 m) with odometry, within 1.5x of it lidar only; rotation below 1 deg."""
    seq, relations = _log(name)
    m = run_slam(seq, None, replace(logs_config(), motion_prior=prior), relations=relations).metrics
    goal = GOALS[name] * (1.0 if prior == "odometry" else 1.5)
    assert m["relation_count"] == {"intel": 2984, "fr079": 1685}[name]
    assert m["relation_trans_mean_m"] <= goal
    assert m["relation_rot_mean_deg"] < 1.0
