"""slamkit.systems.lidar_slam.LidarSlam: the streaming contract on a simulated warehouse, and the
system on the SLAM benchmark's Intel and Freiburg 079 logs scored by their relations (Kuemmerle
et al. 2009): a 120 s slice of Intel in the default run, the whole logs under ``slow`` with the
goals of issue 11 (Intel <= 0.031 m, fr079 <= 0.056 m mean translational relation error, below
1 deg rotational; lidar only within 1.5x of those).

The logs' configuration is the ``slam`` section of pipelines/lidar_slam_logs.yaml with the
motion prior's ``slam_by_motion_prior`` entry merged in (what ``slamkit run`` uses). Logs come from the dataset registry (../shared/datasets, $SLAMKIT_DATA or
the cache); the tests skip when they are not available."""

from __future__ import annotations

import dataclasses

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from slamkit.data import registry
from slamkit.data.perturb import PerturbationConfig, perturb
from slamkit.data.sequence import Odometry, Scan
from slamkit.config import build
from slamkit.errors import ConfigError, DataError
from slamkit.experiments.lidar_slam import _sim_parts, _simulate, first_seconds, run_slam, slam_section_for
from slamkit.experiments.pipeline import load_config
from slamkit.geometry import se2
from slamkit.metrics.alignment import umeyama
from slamkit.metrics.relations import read_relations
from slamkit.frontend.loop_closure import LoopClosureConfig
from slamkit.metrics.trajectory_score import ate_at_stamps_m
from slamkit.systems.lidar_slam import LidarSlam, LidarSlamConfig, LidarSlamCounters
from slamkit.systems.slam_map import config_for

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
    assert final.counters.loop_closures_online + final.counters.loop_closures_final == len(final.loops)
    # the counters are a frozen value (issue 30), a copy: the running system's tally moves on alone
    assert isinstance(final.counters, LidarSlamCounters) and final.counters == slam.counters
    assert final.counters.scans == len(scans) and 0 < final.counters.matched_scans <= final.counters.scans
    with pytest.raises(dataclasses.FrozenInstanceError):
        final.counters.scans = 0
    assert same_poses(final.world_xytheta_body[k], final.keyframe_poses)
    # the first scan is where the sequence says the robot starts
    assert same_poses(final.world_xytheta_body[:1], np.reshape(seq.initial_world_xytheta_body, (1, 3)), 1e-3)
    with pytest.raises(DataError, match="after finish"):
        slam.step(scans[-1])
    grid = slam.map()
    assert grid.num_scans == len(k) and grid.resolution_m == LidarSlamConfig().map.resolution_m


def test_keyframes_are_placed_on_the_matched_motion(world):
    """The keyframe rule (``KeyframeConfig.exceeded_by``) is applied to the scan-matched motion
    since the newest keyframe, also with wheel odometry: no scan between keyframes passes it by
    its matched pose, every keyframe's scan-match edge does. The old experiment applied it to
    the odometry (it matched keyframes only), which can pick a different set (26 of 69 in common
    here) and, measured on the whole Intel log with odometry, gave 0.189 +- 0.743 m relation
    error instead of 0.0155 +- 0.0136 m (issue 11)."""
    seq, _ = world
    cfg = LidarSlamConfig()
    slam = LidarSlam(cfg, seq.initial_world_xytheta_body).run(seq)
    est = slam.estimate()
    k = est.keyframe_scans
    anchor = np.searchsorted(k, np.arange(len(est.stamps_s)), side="right") - 1
    k_T_scan = se2.between(est.keyframe_poses[anchor], est.world_xytheta_body)
    since_s = est.stamps_s - est.keyframe_stamps_s[anchor]
    between = np.setdiff1d(np.arange(len(est.stamps_s)), k)
    # 442 scans: the seeded simulator's 60 s tour, trimmed to free space (exact, no decision).
    # Keyframes depend on the matched motion: perturbations 0-5 (start_offset, range_jitter 1e-6 m)
    # select 69, 69, 69, 68, 68, 67 keyframes; band 62-76. How many of them
    # an odometry-based selection would share is a knife edge (26, 30, 30, 68, 68, 67 of them: one
    # borderline scan early on shifts every later keyframe), so it is not a check; the rule
    # checks below pin the set down instead: with the rule applied to the matched motion, no
    # scan between keyframes passes it and every keyframe's edge does
    assert len(est.stamps_s) == 442
    assert 62 <= len(k) <= 76 and len(between) == len(est.stamps_s) - len(k)
    assert not any(cfg.keyframes.exceeded_by(k_T_scan[n], since_s[n]) for n in between)
    g = slam.graph()
    chain = g.edge_to == g.edge_from + 1
    assert chain.sum() == len(k) - 1
    assert all(cfg.keyframes.exceeded_by(z, 0.0) for z in g.measurements[chain])


def test_lidar_only_in_a_simulated_world(world):
    """Without wheel odometry (constant-velocity prior) the warehouse tour (69 keyframes) comes
    out about as well as with it. Measured ATE over the keyframes after SE(2) alignment: 0.0032 m
    with odometry, 0.0032 m without (27 loop closures each)."""
    seq, _ = world
    ate = {}
    for prior in ("odometry", "constant_velocity"):
        est = LidarSlam(LidarSlamConfig(motion_prior=prior), seq.initial_world_xytheta_body).run(seq).finish()
        ate[prior] = ate_at_stamps_m(seq.ground_truth, est.keyframe_stamps_s, est.keyframe_poses)
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
    with pytest.raises(ConfigError, match="odometry_check"):
        LidarSlamConfig(odometry_check_deg=-1.0)
    for bad in ({"lost_restart_s": -1.0}, {"lost_restart_s": float("nan")}, {"lost_restart_s": 1e5}):
        with pytest.raises(ConfigError, match="lost_restart_s"):
            LidarSlamConfig(**bad)
    for bad in ((1.0, 1.0), (1.0, 0.0, 0.2), (1.0, float("nan"), 0.2), (1.0, float("inf"), 0.2)):
        with pytest.raises(ConfigError, match="lost_sigmas"):
            LidarSlamConfig(lost_sigmas=bad)
        with pytest.raises(ConfigError, match="fallback_sigmas"):
            LidarSlamConfig(fallback_sigmas=bad)
    cfg = build(LidarSlamConfig, {"motion_prior": "identity", "body_xytheta_lidar": [-0.04, 0, 0],
                            "isam2": {"relinearize_threshold": 0.05}})
    assert cfg.body_xytheta_lidar == (-0.04, 0.0, 0.0) and cfg.isam2.relinearize_threshold == 0.05


# ---- the SLAM benchmark's logs -------------------------------------------------------------------


def _log(name: str):
    entry = registry.get(f"{name}-log")
    if not registry.is_available(entry):
        pytest.skip(f"{entry.name} is not available locally (slamkit data fetch {entry.name})")
    return registry.load_recording(entry.name), read_relations(registry.relations_of(entry.name))


def logs_config(prior: str = "odometry") -> LidarSlamConfig:
    """The logs pipeline's slam config for one motion prior (its slam_by_motion_prior merged in)."""
    config = load_config(ROOT / "pipelines" / "lidar_slam_logs.yaml")
    return build(LidarSlamConfig, slam_section_for(config.get("slam"), config.get("slam_by_motion_prior"), prior))


@pytest.fixture(scope="module")
def intel():
    return _log("intel")


def test_intel_slice(intel):
    """The first 120 s of the Intel log (611 scans, the robot leaves its start room and drives
    ~25 m through two corridors; 48 relations fall inside): measured relation error
    0.016 +- 0.010 m / 0.18 +- 0.13 deg with odometry (0.0158 +- 0.0094 m / 0.17 +- 0.10 deg
    since the log is read in the order it was taken); raw odometry 0.019 +- 0.03 m."""
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
    assert m["num_scans"] == len(stamps) and m["real_time_factor"] > 0


def test_speed_ups_change_nothing(intel, monkeypatch):
    """The first 400 s of the Intel log with odometry (100 local and 7 global loop candidates):
    without the loop-verification target cache (``LOOP_TARGET_CACHE`` 0: every target rebuilt)
    and with the branch and bound's Python descent (``SLAMKIT_NO_NATIVE=1``) the system returns
    the same trajectory, keyframe poses, closures and counters, bit for bit (issue 29's speed-ups
    must not change a result). The compiled ICP is off in both runs: it is not bit for bit (its
    pose is numpy's within 1e-15, tests/frontend/test_icp_kernel.py), and on this piece those last
    bits already part the two runs (a match from starts 8e-5 m apart stops after 4 or 7
    iterations at scan 230; 19 or 35 closures by 400 s) -- the same chaos as any perturbed twin,
    so the kernel is judged over the twins (pipelines/lidar_slam_logs.yaml)."""
    from slamkit.frontend import icp as icp_module
    monkeypatch.setattr(icp_module, "_kernel", lambda: None)
    seq, _ = intel
    piece = first_seconds(seq, 400.0)

    def run():
        return LidarSlam(logs_config(), seq.initial_world_xytheta_body).run(piece).finish()

    fast = run()
    assert fast.counters.loop_candidates > 0 and fast.counters.loop_candidates_global > 0
    monkeypatch.setattr(LidarSlam, "LOOP_TARGET_CACHE", 0)
    monkeypatch.setenv("SLAMKIT_NO_NATIVE", "1")
    plain = run()
    assert np.array_equal(fast.world_xytheta_body, plain.world_xytheta_body)
    assert np.array_equal(fast.keyframe_poses, plain.keyframe_poses)
    assert [(c.i, c.j) for c in fast.loops] == [(c.i, c.j) for c in plain.loops]
    assert all(np.array_equal(a.i_T_j, b.i_T_j) for a, b in zip(fast.loops, plain.loops))
    assert fast.counters == plain.counters


def test_odometry_that_froze_then_jumped_is_checked_against_the_scans():
    """MIT CSAIL's scan-synchronous odometry holds still for scans 1580-1583 while the robot
    turns (the scans matched 13-17 deg each) and then jumps 85 deg at scan 1584. Matched from
    that odometry, ICP starts 70 deg off and fits a corridor backwards (-163 deg between scans
    1583 and 1584); the check (the odometry disagrees with the constant-velocity prediction by
    more than ``odometry_check_deg``) repeats the match from the best heading around the
    odometry, the prediction and the previous pose: 15.4 deg. Measured on scans 1560-1600 with
    the logs pipeline's config (15 checks, 7 won); on the whole log the map consistency went
    from 0.143 m (a revisit drawn twice) to 0.062 m."""
    entry = registry.get("mit-csail-log")
    if not registry.is_available(entry):
        pytest.skip("mit-csail-log is not available locally")
    seq = registry.load_recording(entry.name)
    events = list(seq.events)
    at = [k for k, e in enumerate(events) if isinstance(e, Scan)]
    first = 1560
    piece = replace(seq, events=tuple(events[at[first]:at[1600] + 1]), initial_world_xytheta_body=None)
    base = config_for(seq, logs_config())
    turns = {}
    for on in (False, True):
        cfg = base if on else replace(base, odometry_check_deg=0.0, odometry_check_m=0.0)
        est = LidarSlam(cfg).run(piece).estimate()
        turn_deg = np.rad2deg(np.diff(np.unwrap(est.world_xytheta_body[:, 2])))
        turns[on] = turn_deg[1580 - first:1588 - first]   # scan n-1 -> n for n = 1581..1588
        assert (est.counters.odometry_check_wins >= 1) == on
    # the scans turn 13-24 deg each; without the check one match is off by ~180 deg
    assert np.all((turns[True] > 12.0) & (turns[True] < 25.0)), turns[True]
    assert turns[False].min() < -150.0


def test_a_lidar_only_match_lost_in_a_fast_turn_is_found_again_by_the_correlative_search(monkeypatch):
    """MIT CSAIL lidar only: the pipeline's second perturbed twin (started 0.43 s later, ranges
    jittered by 1e-6 m) failed one match at 51.9 s, in a wiggle of +-18 deg a scan, where the log
    as given fits just above ``min_match_fitness``. A failed match leaves the scan where the
    previous one was; the robot drove on at ~0.8 m/s, every next scan started beyond ICP's 0.5 m
    gate, 33 matches in a row fell back and the first loop was never closed (map consistency
    0.110 m against 0.070 m). That knife edge depends on the last bits, so the test makes the loss
    itself: the scans of 1.2 s from 51.8 s of the log as given are not matched. Measured: without
    the retry 47 matches fall back and the first 62 s end 7.1 m / 73 deg off the run without the
    loss; with the logs pipeline's retry of a failing lidar-only match from a correlative search
    (+-2 m, +-45 deg) 6 fall back (1 search won) and it ends 0.01 m / 0.2 deg off. (Before the
    lidar-only matches were refined trimmed, ``icp.refine_trim_fraction``, losing two scans, 0.4 s,
    was enough: 30 fell back, 4.5 m / 54 deg off; refined, the match after a 0.4 or 0.8 s loss
    still converges, 3-4 fall back, 0.01 m off.) The submap restart after 2 s of failed matches
    (``lost_restart_s``) does not stand in for the retry: alone it keeps the robot tracking
    (11 fall back, one restart) but the motion of the lost seconds stays lost, 5.1 m / 32 deg
    off; with the retry no restart is needed."""
    entry = registry.get("mit-csail-log")
    if not registry.is_available(entry):
        pytest.skip("mit-csail-log is not available locally")
    seq = registry.load_recording(entry.name)
    piece = first_seconds(seq, 62.0)
    cfg = config_for(seq, logs_config("constant_velocity"))
    assert cfg.correlative_below_fitness == cfg.min_match_fitness == 0.3 and cfg.correlative.window_xy_m == 2.0
    kept = LidarSlam(cfg).run(piece).estimate()
    # (0 fall back here; the scan at 51.9 s fits just above the threshold, so on other last bits
    # one may fail -- and be found again, the retry's very job)
    assert kept.counters.match_fallbacks <= 8
    t0, match = piece.events[0].stamp_s, LidarSlam._match

    def lossy(self, pts, guess, hold=None, check=None):
        if 51.8 <= self._last_stamp - t0 < 53.0:   # the previous scan's stamp: 1.2 s of scans lost
            self._counts["match_fallbacks"] += 1
            return guess, None
        return match(self, pts, guess, hold, check)

    monkeypatch.setattr(LidarSlam, "_match", lossy)
    lost = LidarSlam(replace(cfg, correlative_below_fitness=0.0, lost_restart_s=0.0)).run(piece).estimate()
    restarted = LidarSlam(replace(cfg, correlative_below_fitness=0.0)).run(piece).estimate()
    found = LidarSlam(cfg).run(piece).estimate()
    assert lost.counters.match_fallbacks >= 20 and found.counters.match_fallbacks <= 8
    assert found.counters.correlative_wins >= 1 and found.counters.lost_restarts == 0
    assert restarted.counters.lost_restarts >= 1 and restarted.counters.match_fallbacks <= 15

    def off(est):
        d = se2.between(kept.world_xytheta_body[-1], est.world_xytheta_body[-1])
        return float(np.hypot(d[0], d[1])), float(np.rad2deg(abs(d[2])))

    assert off(lost)[0] > 2.0 and off(lost)[1] > 30.0
    assert off(restarted)[0] > 2.0 and off(restarted)[1] > 15.0
    assert off(found)[0] < 0.3 and off(found)[1] < 2.0


def test_a_lidar_only_run_lost_out_of_its_submaps_sight_restarts_the_submap():
    """The Freiburg hospital, lidar only, 2190-2300 s of the log: at 2223 s the robot turns through
    a doorway and four scans match neither the submap nor each other (fitness 0.01-0.08). A
    failed lidar-only match leaves the scan where the previous one was; standing there, the
    scans of the robot driving on never overlap the submap again, and every match fails until
    it comes back -- in the whole log 340 s later, with 100 m of corridor missing from the map.
    After ``lost_restart_s`` of failed matches the scan becomes a keyframe anyway (a weak edge,
    ``lost_sigmas``): the submap restarts from what the robot sees and the next scans match.
    Measured against the log's wheel odometry (37.0 m of path): standing 11.2 m of path, 128 of
    183 matches failed; restarted (2 s) 30.0 m, 47 failed, 7 restarts (what is still missing:
    the lost seconds themselves, and a turn in the open at 2253 s where the scans hardly match
    each other either)."""
    entry = registry.get("fr-clinic-log")
    if not registry.is_available(entry):
        pytest.skip("fr-clinic-log is not available locally")
    seq = registry.load_recording(entry.name)
    t0 = seq.events[0].stamp_s
    piece = replace(seq, events=tuple(e for e in seq.events if 2190.0 <= e.stamp_s - t0 <= 2300.0))
    cfg = config_for(seq, logs_config("constant_velocity"))
    assert cfg.lost_restart_s == 2.0
    wheel_path_m = sum(abs(e.v_mps) * e.dt_s for e in piece.events if isinstance(e, Odometry))

    def path_m(est) -> float:
        return float(np.sum(np.hypot(*np.diff(est.world_xytheta_body[:, :2], axis=0).T)))

    standing = LidarSlam(replace(cfg, lost_restart_s=0.0)).run(piece).estimate()
    restarted = LidarSlam(cfg).run(piece).estimate()
    assert standing.counters.lost_restarts == 0 and restarted.counters.lost_restarts >= 2
    assert path_m(standing) < 0.45 * wheel_path_m
    assert 0.7 * wheel_path_m < path_m(restarted) < 1.1 * wheel_path_m
    assert restarted.counters.match_fallbacks < 0.5 * standing.counters.match_fallbacks


def test_isam2_cholesky_giving_up_on_a_long_loop_free_chain_moves_the_graph_to_qr():
    """GTSAM's Cholesky calls a clique underconstrained when its factor's last two diagonal
    entries differ by 2^12 or more: a chain without loop closures whose newest edge is ~4096x
    more precise (in sigma) than the newest pose's marginal. A straight chain of 1 m edges with
    sigmas 1 mm / 10 mrad gets there at pose 127 (measured; the hospital's chain, 5 mm / 1.6
    mrad per 0.4 m keyframe, at keyframe 2349 of 927 m; the synthetic 0.4 m, 5 mm / 1.6 mrad
    chain at 2308). Nothing is indeterminate: QR solves it. The system moves its graph to a QR
    iSAM2 then and goes on, with every pose where the chain puts it."""
    from slamkit.backend.isam2 import Isam2PoseGraph

    info = np.linalg.inv(np.diag([1e-3 ** 2, 1e-3 ** 2, 1e-2 ** 2]))
    z = np.array([1.0, 0.0, 0.0])
    plain = Isam2PoseGraph("cauchy", params=LidarSlamConfig().isam2)
    plain.add_pose(0, np.zeros(3))
    plain.update()
    with pytest.raises(RuntimeError, match="ndetermin"):
        for j in range(1, 200):
            plain.add_pose(j, se2.compose(plain.poses()[-1], z))
            plain.add_edge(j - 1, j, z, info, robust_edge=False)
            plain.update()
    assert 100 <= j <= 160          # 127 measured
    slam = LidarSlam(LidarSlamConfig())
    slam._graph.add_pose(0, np.zeros(3))
    slam._update()
    for j in range(1, 200):
        slam._graph.add_pose(j, se2.compose(slam._graph.poses()[-1], z))
        slam._graph.add_edge(j - 1, j, z, info, robust_edge=False)
        slam._edge_kind.append("odometry")
        slam._update()
    assert slam.counters.isam2_qr_fallbacks == 1
    assert isinstance(slam._graph, Isam2PoseGraph) and slam._graph_qr
    np.testing.assert_allclose(slam._graph.poses(), np.column_stack([np.arange(200.0), np.zeros(200), np.zeros(200)]),
                               atol=1e-9)


GOALS = {"intel": 0.031, "fr079": 0.056}


def wall_curvature(res, sensor_poses: np.ndarray, box: tuple[float, float, float, float], along: str
                   ) -> tuple[float, float, float]:
    """The bend of one wall in the map, against what single scans see of it. ``box`` (x0, x1, y0,
    y1, m, the frame of ``sensor_poses``, the keyframes' sensor poses) holds the wall, ``along``
    the axis it runs along ("x" or "y"). Every keyframe's returns inside the box are taken at
    their sensor poses, a parabola across the wall is fitted (points more than 0.1 m off are
    dropped, three times). Returns (curvature of the wall in the map (1/m), the median curvature
    of the same fit within every single scan that sees >= 2.5 m of it (1/m): a rigid pose cannot
    bend a scan, so this is the wall's own shape, and the rms residual of a straight line through
    the map's wall (m))."""
    a, b = (0, 1) if along == "x" else (1, 0)
    x0, x1, y0, y1 = box
    rows = []
    for k, pose in enumerate(sensor_poses):
        r, ang = res.keyframe_ranges_m[k], res.keyframe_angles_rad[k]
        ok = np.isfinite(r)
        xy = se2.transform_points(pose, np.column_stack([r[ok] * np.cos(ang[ok]), r[ok] * np.sin(ang[ok])]))
        inside = (xy[:, 0] > x0) & (xy[:, 0] < x1) & (xy[:, 1] > y0) & (xy[:, 1] < y1)
        rows.append(np.column_stack([xy[inside], np.full(inside.sum(), k)]))
    pts = np.concatenate(rows)
    fit = np.polyfit(pts[:, a], pts[:, b], 2)
    for _ in range(3):
        pts = pts[np.abs(pts[:, b] - np.polyval(fit, pts[:, a])) < 0.1]
        fit = np.polyfit(pts[:, a], pts[:, b], 2)
    line = pts[:, b] - np.polyval(np.polyfit(pts[:, a], pts[:, b], 1), pts[:, a])
    per_scan = []
    for k in np.unique(pts[:, 2]):
        q = pts[pts[:, 2] == k][:, :2]
        if np.ptp(q[:, a]) >= 2.5 and len(q) >= 12:
            # in the segment's own axes (the normal pointing along the map's axis b, as the map's fit)
            _, _, vt = np.linalg.svd(q - q.mean(axis=0))
            local = (q - q.mean(axis=0)) @ np.column_stack([vt[0], vt[1] * np.sign(vt[1][b])])
            per_scan.append(2 * np.polyfit(local[:, 0], local[:, 1], 2)[0])
    return 2 * float(fit[0]), float(np.median(per_scan)), float(line.std())


#: Intel walls in the frame they were drawn in: the inner walls of the left and right corridors
#: and the inner block's long wall along the bottom corridor (15 m)
INTEL_INNER_WALLS = {"left": (-6.6, -4.4, -16.2, -2.5), "right": (10.2, 11.8, -17.8, -6.5)}
INTEL_BOTTOM_WALL = (-4.5, 10.8, -18.75, -17.9)
#: that frame, by the sensor positions (stamp s, x m, y m) of seven scans round the building in
#: it (the stamp-ordered run before a78dd5d, which gives the figures measured when the boxes were
#: drawn). A map's own frame is its first pose, and Intel's first scan does not fix it: the robot
#: stands 28 s in a corridor before it drives, and the first keyframe slides along it -- at a78dd5d
#: and since, the first pose sits 0.41 m from where it sat before relative to the rest of the map,
#: which agrees with the earlier one within 0.013 m at these scans and 0.01 m mean over every
#: keyframe; both first scans fit the final map equally (median end-point distance 3 mm). No
#: relation reaches the first 39 s, so the relations do not see it; fixed boxes did (the bottom
#: wall's step at its left end moved into its box: curvature -0.0104 1/m, line residual 0.081 m)
INTEL_WALL_FRAME_SCANS = ((976054837.202, -6.662, -2.485), (976053130.250, -6.139, -15.967),
                          (976053093.618, 0.015, -18.751), (976054155.561, 7.997, -18.599),
                          (976055031.354, 11.458, -6.755), (976054998.251, 12.252, -16.041),
                          (976052923.293, 3.185, -0.317))


def in_wall_frame(res) -> tuple[np.ndarray, float]:
    """The keyframes' sensor poses moved into the frame of the wall boxes (the least-squares
    rotation and translation of the scans at ``INTEL_WALL_FRAME_SCANS``' stamps onto their
    positions there) and the largest distance left between them and those positions (m)."""
    anchors = np.asarray(INTEL_WALL_FRAME_SCANS)
    at = np.abs(res.scan_stamps_s[None, :] - anchors[:, :1]).argmin(axis=1)
    assert np.abs(res.scan_stamps_s[at] - anchors[:, 0]).max() < 1e-3
    xy = res.sensor_poses(res.scan_poses)[at, :2]
    R, t, _ = umeyama(xy, anchors[:, 1:])
    poses = res.sensor_poses(res.optimised_poses)
    moved = np.column_stack([poses[:, :2] @ R.T + t, poses[:, 2] + np.arctan2(R[1, 0], R[0, 0])])
    return moved, float(np.hypot(*(xy @ R.T + t - anchors[:, 1:]).T).max())


@pytest.mark.slow
@pytest.mark.parametrize("name, prior", [("intel", "odometry"), ("fr079", "odometry"),
                                         ("intel", "constant_velocity"), ("fr079", "constant_velocity")])
def test_benchmark_goals(name, prior):
    """Issue 11's goals on the whole logs, as the worst over the log as given and 5 seeded
    perturbations of it (issue 28: start 1-5 scans later, 1e-6 m range jitter): the published
    graph-mapping result (Intel 0.031 m, fr079 0.056 m) with odometry, within 1.5x of it lidar
    only; rotation below 1 deg. The measured distributions are in the README's laser-log table
    (``slamkit run pipelines/lidar_slam_logs.yaml``)."""
    seq, relations = _log(name)
    twins = PerturbationConfig(count=5)
    goal = GOALS[name] * (1.0 if prior == "odometry" else 1.5)
    full = {"intel": 2984, "fr079": 1685}[name]
    for twin in range(twins.count + 1):
        res = run_slam(perturb(seq, twin, twins), None, logs_config(prior), relations=relations)
        m = res.metrics
        # a later start can only drop relations that begin in the first scans
        assert full - 10 <= m["relation_count"] <= full and (twin > 0 or m["relation_count"] == full)
        assert m["relation_trans_mean_m"] <= goal, (twin, m["relation_trans_mean_m"])
        assert m["relation_rot_mean_deg"] < 1.0, (twin, m["relation_rot_mean_deg"])
    if (name, prior) == ("intel", "odometry"):
        # the check is of the back end (no bend of its own) on the stamp-ordered log (0.0152 m
        # relation error), moved into the boxes' frame (INTEL_WALL_FRAME_SCANS: 0.013 m left at
        # its scans). Read in the order it was taken, the log (and its twins) gives an equally
        # good map turned ~0.2 deg from it (0.05-0.13 m left at those scans) whose single scans
        # keep 2.5 m of the left wall in its box in 0-2 scans, too few for their median
        res = run_slam(registry.load_recording(f"{name}-log", order="stamp"), None, logs_config(prior),
                       relations=relations)
        poses, off_m = in_wall_frame(res)
        assert off_m < 0.05
        # Intel's inner corridor walls are arcs (radius ~21 m) in the raw scans themselves: the
        # map must show the bend single scans see and add none of its own. Measured (map / single
        # scans, 1/m): left +0.048 / +0.050, right -0.045 / -0.044 (+0.049 / +0.045 and -0.046 /
        # -0.044 since the final solve keeps the chain out of the robust kernel; +0.051 / +0.055
        # from 5 scans and -0.046 / -0.044 since a78dd5d). The inner block's 15 m wall along the
        # bottom corridor is straight (two steps of ~5 cm): curvature -0.0045 1/m, line residual
        # 0.032 m (-0.0039, 0.031; -0.0053, 0.035 since a78dd5d); a graph that bends the loops
        # fails here (odometry edges' information x 0.1: -0.016 1/m, 0.10 m; no robust kernel:
        # -0.009 1/m, 0.069 m)
        for side, box in INTEL_INNER_WALLS.items():
            in_map, in_scans, _ = wall_curvature(res, poses, box, "y")
            assert abs(in_scans) > 0.03, side
            assert abs(in_map - in_scans) < 0.005, side
        in_map, _, line_rms_m = wall_curvature(res, poses, INTEL_BOTTOM_WALL, "x")
        assert abs(in_map) < 0.008 and line_rms_m < 0.05


def lidar_blackouts(seq, count: int, duration_s: float, seed: int, omega_bias_radps: float, v_scale: float):
    """``seq`` with the scans of ``count`` seeded ``duration_s`` windows removed (one window at a
    uniform position in each of ``count`` equal slices of the log, 60 s from either end) and the
    wheel odometry biased (heading rate + ``omega_bias_radps`` while moving, speed x ``v_scale``):
    across each window the system has only the biased odometry, so it comes out of it drifted
    and its later revisits arrive after metres of drift."""
    from dataclasses import replace as _replace

    from slamkit.data.sequence import Odometry
    stamps = np.array([e.stamp_s for e in seq.events if isinstance(e, Scan)])
    rng = np.random.default_rng(seed)
    edges = np.linspace(stamps[0] + 60.0, stamps[-1] - 60.0 - duration_s, count + 1)
    starts = edges[:-1] + rng.uniform(0, 1, count) * np.diff(edges)

    def keep(e) -> bool:
        return not (isinstance(e, Scan) and np.any((e.stamp_s >= starts) & (e.stamp_s < starts + duration_s)))

    def bias(e):
        if not isinstance(e, Odometry):
            return e
        moving = abs(e.v_mps) + abs(e.omega_radps) > 0
        return _replace(e, v_mps=e.v_mps * v_scale, omega_radps=e.omega_radps + (omega_bias_radps if moving else 0.0))

    return _replace(seq, events=tuple(bias(e) for e in seq.events if keep(e)))


@pytest.mark.slow
def test_revisits_after_drift_beyond_the_fixed_radius():
    """Issue 29: loop closure that does not depend on a small drift. The whole Intel log with four
    seeded 45 s lidar blackouts and the odometry biased by 0.4 deg/s heading rate and +5% speed
    (``lidar_blackouts``; biased odometry alone does no harm: the scan matcher absorbs it, 0.0150 m
    with 3 deg/s and +10%): after each blackout the map is drifted and its revisits arrive
    metres off. Measured (one run each, 2610 relations; the log as given: 0.0156 m):

    - fixed 2 m search radius alone (``region_probability: 0``): 0.208 +- 0.687 m, 218
      relations above 0.5 m (max 5.1 m); loop precision 0.978, recall 0.507
    - drift region (0.99) with the branch-and-bound global matcher, also after local closures:
      0.074 +- 0.310 m, 97 above 0.5 m (max 2.2 m); 548 global closures, the largest correcting
      3.5 m of drift; precision 0.981, recall 0.593
    - the same since a far global closure (moving the estimate > 0.3 m) needs fitness 0.85 and the
      odometry check skips gaps > 5 s: 0.069 +- 0.317 m, 74 above 0.5 m (max 2.5 m); 545 global
      closures, 46 far ones refused; precision 0.981, recall 0.608 (with the check after every
      gap, the matcher started the first scan after a blackout from the pose before it: 1.585 m)

    The fixed radius's figure above was measured before that gap rule, which helps it too: since
    a2b835e (found by git bisect, 2026-12-08) it gives 0.087 m / 102 there and, at 1f70139,
    0.0962 +- 0.391 m, 120 relations above 0.5 m (max 3.20 m), precision 0.986, recall 0.546;
    the drift region with the global matcher 0.0703 +- 0.324 m, 74 above 0.5 m (max 2.52 m),
    precision 0.983, recall 0.607. The baseline's bounds below are those measured figures' (the
    test asserted 150 and 0.15 m, unmet since a2b835e).

    Closer to the clean figure, not at it: some drifted stretches are still not tied back."""
    seq, relations = _log("intel")
    bad = lidar_blackouts(seq, 4, 45.0, 2, np.deg2rad(0.4), 1.05)
    base = logs_config()

    def with_loops(**kw) -> LidarSlamConfig:
        return LidarSlamConfig(**{**base.__dict__, "loops": LoopClosureConfig(**{**base.loops.__dict__, **kw})})

    old = run_slam(bad, None, with_loops(region_probability=0.0), relations=relations)
    new = run_slam(bad, None, with_loops(region_probability=0.99, global_after_local_closure=True),
                   relations=relations)
    old_bad, new_bad = int(np.sum(old.relations.errors_m > 0.5)), int(np.sum(new.relations.errors_m > 0.5))
    assert old_bad >= 110 and old.metrics["relation_trans_mean_m"] > 0.09
    assert new_bad < old_bad / 1.5 and new.metrics["relation_trans_mean_m"] < 0.12
