"""The laser-log report pieces of the lidar_slam pipeline on the first 60 s of the Intel log: the
relations drawn on the map where they are wrong (between the estimated poses at their two
stamps), the map figure's title, axes and scale bar, the map consistency figure and the real-time
factor beside Cartographer's."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from slamkit.config import build
from slamkit.data import registry
from slamkit.data.sequence import Scan
from slamkit.experiments.lidar_slam import (
    BAD_RELATION_M,
    CARTOGRAPHER_REALTIME_FACTOR,
    _scale_bar_m,
    first_seconds,
    log_map_figure,
    run_slam,
    slam_section_for,
)
from slamkit.experiments.pipeline import load_config
from slamkit.metrics.relations import read_relations
from slamkit.geometry import se2
from slamkit.systems.lidar_slam import LidarSlam, LidarSlamConfig
from slamkit.systems.slam_map import config_for
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _logs_slam_config(prior: str) -> LidarSlamConfig:
    """pipelines/lidar_slam_logs.yaml's slam section for one motion prior, built."""
    config = load_config(ROOT / "pipelines" / "lidar_slam_logs.yaml")
    return build(LidarSlamConfig, slam_section_for(config.get("slam"), config.get("slam_by_motion_prior"), prior))


@pytest.fixture(scope="module")
def intel_60s():
    entry = registry.get("intel-log")
    if not registry.is_available(entry):
        pytest.skip("intel-log is not available locally")
    seq = replace(first_seconds(registry.load_recording(entry.name), 60.0), name="intel")
    relations = read_relations(registry.relations_of(entry.name))
    cfg = _logs_slam_config("odometry")
    return run_slam(seq, None, cfg, relations=relations, label="intel"), relations


def test_relation_segments_join_the_poses_at_the_relation_stamps(intel_60s):
    res, relations = intel_60s
    seg = res.relation_segments
    assert seg.shape == (res.metrics["relation_count"], 5) == (6, 5)
    np.testing.assert_array_equal(seg[:, 4], res.relations.errors_m)
    for row, k in zip(seg, res.relations.index):
        i = int(np.argmin(np.abs(res.scan_stamps_s - relations.t1_s[k])))
        j = int(np.argmin(np.abs(res.scan_stamps_s - relations.t2_s[k])))
        np.testing.assert_array_equal(row[:4], np.r_[res.scan_poses[i, :2], res.scan_poses[j, :2]])
    # the relation error is the error of the displacement between those two poses: its length
    # differs from the relation's own by at most the error
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    truth = np.hypot(*relations.delta_xytheta[res.relations.index, :2].T)
    assert np.all(np.abs(length - truth) <= seg[:, 4] + 1e-9)


def test_map_figure_draws_the_wrong_relations(intel_60s):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    res, _ = intel_60s
    # measured on the first 60 s: 0.024 +- 0.012 m, none above 0.2 m; two relations made wrong
    assert res.metrics["relations_over_0_2_m"] == 0
    seg = res.relation_segments.copy()
    seg[[1, 4], 4] = [0.5, 1.5]
    metrics = {**res.metrics, "relations_over_0_2_m": 2.0}
    fig = log_map_figure(plt, replace(res, relation_segments=seg, metrics=metrics))
    try:
        ax = fig.axes[0]
        (lines,) = [c for c in ax.collections if isinstance(c, LineCollection)]
        np.testing.assert_array_equal(np.asarray(lines.get_array()), [0.5, 1.5])
        np.testing.assert_array_equal(lines.get_segments()[1], seg[4, :4].reshape(2, 2))
        assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
        title = fig._suptitle.get_text()
        assert "intel, motion prior odometry" in title
        assert f"relation error {res.metrics['relation_trans_mean_m']:.3f}" in title
        assert "2 above 0.2 m" in title and "map consistency" in title
        assert len(fig.axes) == 2 and fig.axes[1].get_ylabel() == "relation error (m)"  # the colour bar
        # the scale bar: an anchored artist labelled in metres
        assert any(type(a).__name__ == "AnchoredSizeBar" for a in ax.artists)
    finally:
        plt.close(fig)
    assert BAD_RELATION_M == 0.2


def test_scale_bar_is_a_round_fifth():
    assert [_scale_bar_m(w) for w in (4.0, 9.0, 26.0, 60.0, 130.0, 0.6)] == [0.5, 1.0, 5.0, 10.0, 20.0, 0.1]


def test_consistency_and_realtime_metrics(intel_60s):
    res, _ = intel_60s
    m = res.metrics
    # the first 60 s: the robot turns on the spot in its start room and leaves it down one
    # corridor; no place is seen on two visits (more than 5 m of travel apart): no figure
    assert m["map_consistency_overlap"] == 0.0 and np.isnan(m["map_consistency_mean_m"])
    assert m["real_time_factor_vs_cartographer"] == pytest.approx(m["real_time_factor"] / 15.0)
    assert CARTOGRAPHER_REALTIME_FACTOR == {"intel": 15.0, "fr079": 17.0, "mit-csail": 12.0}
    assert m["real_time_factor_cpu"] > 0 and m["time_cpu_s"] > 0
    # no revisit in the first 60 s: no closure, none of the log's revisits recalled (the revisits
    # are counted over the whole relations file, 1210 on Intel, not only those inside the slice)
    assert m["loop_closures"] == m["num_loop_closures"] == 0 and m["loop_recall"] == 0.0
    assert len([e for e in first_seconds(registry.load_recording("intel-log"), 60.0) if isinstance(e, Scan)]) \
        == m["num_scans"]


def _shipped_logs() -> list[str]:
    return sorted(n for n in registry.names() if registry.get(n).kind == "laser_log_2d")


def test_logs_pipeline_has_one_config_and_registry_logs():
    """pipelines/lidar_slam_logs.yaml runs registry laser logs with one slam configuration
    (per-motion-prior overrides only, no per-log section)."""
    cfg = load_config(ROOT / "pipelines" / "lidar_slam_logs.yaml")
    assert _shipped_logs() == ["fr-clinic-log", "fr079-log", "intel-log", "mit-csail-log"]
    assert {"intel-log", "fr079-log", "mit-csail-log"} <= set(cfg["logs"]) <= set(_shipped_logs())
    assert set(cfg.get("slam_by_motion_prior") or {}) <= {"odometry", "constant_velocity", "identity"}
    assert not any(isinstance(x, dict) for x in cfg["logs"])


def test_logs_pipeline_runs_every_registry_laser_log():
    """Issue 29 item 3: every raw laser log the registry ships (the hospital since the system
    moves its graph to QR when iSAM2's Cholesky gives up on its loop-free chain: whole log with
    odometry 1 fallback, map consistency 0.239 m; lidar only 0.254 m, 0.245 m before failing matches
    were retried from a correlative search)."""
    assert sorted(load_config(ROOT / "pipelines" / "lidar_slam_logs.yaml")["logs"]) == _shipped_logs()


@pytest.fixture(scope="module")
def intel_whole_consistency_m():
    entry = registry.get("intel-log")
    if not registry.is_available(entry):
        pytest.skip("intel-log is not available locally")
    cfg = _logs_slam_config("odometry")
    return run_slam(registry.load_recording(entry.name), None, cfg).metrics["map_consistency_mean_m"]


@pytest.mark.slow
@pytest.mark.parametrize("prior", ["odometry", "constant_velocity"])
def test_mit_csail_map_is_as_consistent_as_intel(prior, intel_whole_consistency_m):
    """Issue 29's goal for the logs without relations: the map consistency figure within 1.5x of
    Intel's (Intel with odometry, 0.0156 m relation error: 0.064 m mean). Measured on the whole
    MIT CSAIL log: lidar only 0.070 m (single walls on the map, looked at), with odometry 0.062 m
    (single walls, looked at; 0.143 m, a revisit drawn twice, before the odometry check:
    tests/systems/test_lidar_slam_system.py, the odometry that froze then jumped); Intel 0.064 m."""
    entry = registry.get("mit-csail-log")
    if not registry.is_available(entry):
        pytest.skip("mit-csail-log is not available locally")
    cfg = _logs_slam_config(prior)
    m = run_slam(registry.load_recording(entry.name), None, cfg).metrics
    assert m["map_consistency_overlap"] > 0.6
    assert m["map_consistency_mean_m"] <= 1.5 * intel_whole_consistency_m


def _west_wing_revisit(sequence, config: LidarSlamConfig):
    """The closures of a whole-slice run that tie the hospital's second pass down the west wing
    (keyframes 1530-1690 s into the log) to its first (290-440 s), and the final estimate."""
    system = LidarSlam(config_for(sequence, config), sequence.initial_world_xytheta_body, name=sequence.name)
    est = system.run(sequence).finish()
    t = est.keyframe_stamps_s - est.keyframe_stamps_s[0]
    return [lc for lc in est.loops if 290.0 <= t[lc.i] <= 440.0 and 1530.0 <= t[lc.j] <= 1690.0], est


@pytest.mark.slow
def test_hospital_revisit_after_15_m_of_drift_is_closed():
    """Issue 29, the hospital with odometry: the robot drives round the west wing's courtyard
    (keyframes 113-224, 301-435 s) and comes back down the same corridor 1530-1680 s later
    (keyframes 1140-1260) with the estimate 15.3 m / 8.0 deg off at the first keyframe of the
    revisit (11.5 m / 8.1 deg at the last; no closure on the 450 m in between). The true place
    lies well inside the drift region's 99% ellipse (squared Mahalanobis distance 3.4-5.1 of
    9.21; the ellipse's major semi-axis 40-44 m, heading sigma 8.7 deg) but 13.5-16 m away in the
    estimate, beyond the region's old 8 m cap: never a candidate, the corridor drawn twice. The
    shipped cap (20 m) lets the region try it. Measured on this slice: 122 closures tie the two
    passes (the region's first, then the local search's along the corrected corridor), the final
    estimate within 7 mm of them (median; 56 mm the largest); with the 8 m cap none, and the same
    keyframe pairs stay 11.7-15.4 m off. pipelines/lidar_slam_logs.yaml: the whole log."""
    entry = registry.get("fr-clinic-log")
    if not registry.is_available(entry):
        pytest.skip("fr-clinic-log is not available locally")
    sequence = first_seconds(registry.load_recording(entry.name), 1750.0)
    shipped = _logs_slam_config("odometry")
    assert shipped.loops.max_search_radius_m >= 20.0
    closures, est = _west_wing_revisit(sequence, shipped)
    assert len(closures) >= 20
    # the closures agree with each other: the final estimate keeps each within a few cm
    poses = est.keyframe_poses
    agree = [np.hypot(*se2.between(se2.between(poses[lc.i], poses[lc.j]), lc.i_T_j)[:2]) for lc in closures]
    assert np.median(agree) < 0.1
    # with the old 8 m cap the revisit is not closed, and those keyframes stay beyond the cap
    old, old_est = _west_wing_revisit(sequence, replace(shipped, loops=replace(shipped.loops, max_search_radius_m=8.0)))
    assert old == []
    # (keyframes by stamp: after the revisit the two runs may pick different scans)
    at = {k: int(np.argmin(np.abs(old_est.keyframe_stamps_s - s))) for k, s in enumerate(est.keyframe_stamps_s)}
    p = old_est.keyframe_poses
    off = [np.hypot(*se2.between(se2.between(p[at[lc.i]], p[at[lc.j]]), lc.i_T_j)[:2]) for lc in closures]
    assert min(off) > 8.0


def test_log_table_shows_the_consistency_floor_beside_the_figure():
    """The laser-log table puts the same-pass floor of the map consistency figure beside it
    (slamkit.metrics.map_consistency), so a log whose surfaces scatter can be read."""
    from slamkit.experiments.lidar_slam.report import _log_report
    from slamkit.experiments.results import RunRecord

    metrics = {"map_consistency_mean_m": 0.2273, "map_consistency_p95_m": 0.746,
               "map_consistency_same_pass_mean_m": 0.0887, "map_consistency_overlap": 0.83,
               "num_keyframes": 3528.0, "loop_closures_online": 113.0, "loop_closures_final": 10.0,
               "real_time_factor": 60.0, "real_time_factor_cpu": 82.5, "time_total_s": 80.0,
               "time_per_scan_median_ms": 5.0, "time_per_scan_p99_ms": 40.0, "peak_rss_mb": 900.0}
    text = _log_report([RunRecord("fr-clinic", "lidar_slam/cauchy", metrics)])
    header = next(line for line in text.splitlines() if line.startswith("| log |"))
    row = next(line for line in text.splitlines() if line.startswith("| fr-clinic |"))
    cells = dict(zip([c.strip() for c in header.split("|")], [c.strip() for c in row.split("|")]))
    assert cells["map consistency mean / p95 (m)"] == "0.227 / 0.746"
    assert cells["same pass (m)"] == "0.089"
    assert cells["seen twice"] == "83%"


def test_lidar_only_matches_are_refined_trimmed():
    """The logs pipeline's lidar-only matcher runs untrimmed to convergence (the door jambs must
    pull along a corridor) and then trimmed from there (``icp.refine_trim_fraction``: the chairs
    and people no longer bias it). The first 120 s of Intel, lidar only (48 relations), as given
    and on the two twins of the perturbation harness where either setting did worst: measured
    0.0181 / 0.0201 / 0.0172 m refined against 0.0348 / 0.0353 / 0.0472 m without (twins 1-5:
    0.016-0.020 m against 0.032-0.047 m)."""
    from slamkit.data.perturb import perturb
    from slamkit.experiments.perturbation import perturbation_config

    entry = registry.get("intel-log")
    if not registry.is_available(entry):
        pytest.skip("intel-log is not available locally")
    relations = read_relations(registry.relations_of(entry.name))
    seq = replace(first_seconds(registry.load_recording(entry.name), 120.0), name="intel")
    twins = perturbation_config({"count": 5, "kinds": ["start_offset", "range_jitter"]})
    refined = _logs_slam_config("constant_velocity")
    assert refined.icp.trim_fraction == 1.0 and refined.icp.refine_trim_fraction == 0.9
    untrimmed = replace(refined, icp=replace(refined.icp, refine_trim_fraction=None))
    for twin in (0, 1, 2):
        twin_seq = perturb(seq, twin, twins)
        on = run_slam(twin_seq, None, refined, relations=relations).metrics
        off = run_slam(twin_seq, None, untrimmed, relations=relations).metrics
        assert on["relation_count"] == off["relation_count"] == 48
        assert on["relation_trans_mean_m"] < 0.023 and off["relation_trans_mean_m"] > 0.03


def test_a_run_without_maps_scores_the_same(intel_60s):
    """The logs pipeline builds maps for the log as given only (its plots); a twin is scored
    without them and every figure but the timings is the one a run with maps gives."""
    res, relations = intel_60s
    seq = replace(first_seconds(registry.load_recording("intel-log"), 60.0), name="intel")
    bare = run_slam(seq, None, _logs_slam_config("odometry"), relations=relations, label="intel", build_maps=False)
    assert bare.map is None and bare.frontend_map is None and res.map is not None
    timing = {"time_map_s", "peak_rss_mb"}
    same = {k: v for k, v in res.metrics.items() if not (k.startswith(("time_", "real_time_factor")) or k in timing)}
    assert {k: bare.metrics[k] for k in same} == pytest.approx(same, nan_ok=True)
    assert "time_map_s" not in bare.metrics and "time_map_s" in res.metrics
    np.testing.assert_array_equal(bare.optimised_poses, res.optimised_poses)


def test_maps_scored_against_truth_cannot_be_left_out():
    from slamkit.data.sequence import Sequence
    from slamkit.errors import ConfigError
    from slamkit.maps.occupancy_grid import OccupancyGrid

    grid = OccupancyGrid(np.zeros((4, 4), bool), 0.1)
    with pytest.raises(ConfigError, match="build_maps"):
        run_slam(Sequence(name="empty", events=()), grid, build_maps=False)
