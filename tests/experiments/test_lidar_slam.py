"""Lidar SLAM end to end on a loop-rich simulated warehouse: loop closure against ATE, map IoU
against the world's ground-truth grid, a false loop closure against the robust kernel, and the
pipeline's result folder and Rerun recording.

Map IoU (slamkit.maps.log_odds): occupied cells (p > 0.5) of the 0.1 m log-odds map against the
ground truth max-pooled to 0.1 m, counted only on the cells the map observed, with the map built
from the SE(2)-aligned keyframe poses (the alignment ATE uses). ATE: RMSE over keyframes after
SE(2) alignment.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from slamkit.config import build
from slamkit.errors import ConfigError
from slamkit.experiments.lidar_slam import (
    LidarSlamSnapshot,
    MclCheckConfig,
    _sim_parts,
    _simulate,
    localize_on_map,
    run_slam,
    slam_section_for,
    trim_to_free_space,
)
from slamkit.systems.lidar_slam import LidarSlamConfig
from slamkit.experiments.pipeline import run_pipeline, validate_pipeline_config
from slamkit.frontend.icp import IcpConfig
from slamkit.sim.grid_world import simulate_grid_sequence
from slamkit.viz.pipelines import observer_for

# 20 m x 20 m warehouse, 8 goals: the tour goes round shelf blocks and revisits aisles (160
# keyframes over 80 m, 150+ verified loop closures)
WORLD = {"name": "warehouse_loops", "world": "warehouse", "world_size_m": [20.0, 20.0], "num_goals": 8,
         "duration_s": 200.0}


@pytest.fixture(scope="module")
def world():
    return _sim_parts(_simulate(WORLD, 0))


@pytest.fixture(scope="module")
def default_run(world):
    seq, grid = world
    return run_slam(seq, grid, LidarSlamConfig())


def test_default_pipeline_map_matches_ground_truth(default_run):
    m = default_run.metrics
    # measured: wheel odometry ATE 0.030 m; ICP front-end (point-to-line against a 3-keyframe
    # submap, 10% trimmed) 0.0077 m; after 153 loop closures 0.0040 m (1.9x); map IoU 0.930
    # (precision 0.996, recall 0.934). This front-end is close to the noise floor already, so
    # loop closure has little left to remove here; the next test shows it on a drifting one.
    assert m["num_loop_closures"] >= 100
    assert m["ate_rmse_m"] < 0.01
    assert m["ate_rmse_m"] <= 0.75 * m["ate_frontend_m"]
    assert m["map_iou"] >= 0.9 and m["map_precision"] >= 0.95 and m["map_recall"] >= 0.9


def test_mcl_check_is_a_rate_over_filter_seeds(default_run):
    """Global localization on one built map is a coin flip in a world with near-twins: along the
    same second tour on the same map, filter seeds 0-3 and 5 localize, 4, 6 and 7 settle 3.1-4.6 m
    away (measured on two maps of this world: before and after the final solve kept the
    scan-match chain out of the robust kernel, issue 28; the successes converged after 4, 3, 2,
    4, 11 and 3, 2, 2, 4, 9 updates). Which seeds succeed is chaotic (it follows the last bits of
    the map), so the test checks the invariant -- the check's numbers are exactly the single-seed
    runs pooled -- and that the outcome is a rate, not one verdict: both outcomes occur (issue
    11: filter seed 0 alone flipped on office seed 1 between two maps that localize in 4 and 3 of
    10 runs)."""
    sim = _simulate(WORLD, 0)
    second, _ = simulate_grid_sequence(sim.scenario, np.random.default_rng(1000), grid=sim.grid)
    second = trim_to_free_space(second, sim.grid)
    cfg = MclCheckConfig(max_updates=30, filter_seeds=8)
    pooled = localize_on_map(default_run, second, cfg)
    single = [localize_on_map(default_run, second, replace(cfg, filter_seed=k, filter_seeds=1)) for k in range(8)]
    rates = np.array([m["mcl_success_rate"] for m in single])
    after = np.array([m["mcl_converged_after_updates"] for m in single])
    assert set(rates.tolist()) == {0.0, 1.0} and np.array_equal(np.isfinite(after), rates == 1.0)
    # measured 5 of 8 on both maps; a map that lost its twin structure (or its walls) leaves the band
    assert 2 / 8 <= rates.mean() <= 7 / 8
    assert np.all(after[np.isfinite(after)] <= 15)
    assert pooled["mcl_runs"] == 8 and pooled["mcl_updates"] == 30
    assert pooled["mcl_success_rate"] == rates.mean()
    assert pooled["mcl_converged_after_updates"] == np.median(after[np.isfinite(after)])
    assert pooled["mcl_final_error_m"] == np.median([m["mcl_final_error_m"] for m in single])
    with pytest.raises(ConfigError, match="filter_seeds"):
        MclCheckConfig(filter_seeds=0)


def test_loop_closure_halves_ate_of_a_drifting_frontend(world):
    # the same data through an untrimmed front-end (every correspondence within 1 m counts, so
    # parts of the new scan the submap never saw pull the match): it drifts, loop closure fixes it
    seq, grid = world
    cfg = LidarSlamConfig(icp=IcpConfig(trim_fraction=1.0))
    m = run_slam(seq, grid, cfg).metrics
    # measured: ATE before loop closure 0.0723 m, after 0.0193 m (3.7x); map IoU 0.680 -> 0.901
    assert m["ate_frontend_m"] >= 2.0 * m["ate_rmse_m"]
    assert m["map_iou"] >= 0.9 and m["map_iou"] > m["map_frontend_iou"] + 0.15


TINY = {"pipeline": "lidar_slam", "name": "tiny", "seeds": [0],
        "worlds": [{"name": "wh", "world": "warehouse", "world_size_m": [20.0, 20.0], "num_goals": 2,
                    "duration_s": 40.0}],
        "false_loop_closures": 1, "robust_variants": ["cauchy", "none"],
        "mcl": {"max_updates": 20}}


def test_pipeline_false_loop_closure_and_recording(tmp_path, verify_rrd):
    """One wrong closure (keyframes > 10 m apart claimed to coincide, information diag(400, 400,
    2500)): Cauchy keeps the map, least squares bends the trajectory onto it."""
    res = run_pipeline(TINY, tmp_path / "run", progress=False, observer_factory=observer_for)
    runs = {r["estimator"]: r["metrics"] for r in res.results["runs"]}
    cauchy, none = runs["lidar_slam/cauchy"], runs["lidar_slam/none"]
    # measured: ATE with the false closure: cauchy 0.0040 m (front-end 0.0049 m), none 0.83 m;
    # map IoU 0.972 vs 0.143
    assert cauchy["num_false_loop_closures"] == 1
    assert cauchy["ate_rmse_m"] < 0.01 and none["ate_rmse_m"] > 0.3
    assert cauchy["map_iou"] > 0.9 and none["map_iou"] < 0.5
    # global localization on each built map along a second tour (scored while the robot stays
    # in the mapped part of the world, at most 20 updates)
    for m in (cauchy, none):
        assert 1 <= m["mcl_updates"] <= 20 and m["mcl_runs"] == 10 and 0 <= m["mcl_success_rate"] <= 1
    out = res.out_dir
    for name in ("config.yaml", "results.json", "report.md", "recording.rrd"):
        assert (out / name).is_file()
    assert len(list((out / "plots").glob("*.png"))) == 2
    assert {p.name for p in (out / "trajectories").iterdir()} == {
        "wh_s0_cauchy.tum", "wh_s0_cauchy_frontend.tum", "wh_s0_none.tum", "wh_s0_none_frontend.tum"}
    assert "ATE after LC (m)" in (out / "report.md").read_text()
    summary = json.loads((out / "results.json").read_text())["summary"]
    assert {s["metric"] for s in summary} >= {"ate_rmse_m", "ate_frontend_m", "map_iou"}
    paths = verify_rrd(out / "recording.rrd")
    for run in ("wh_cauchy", "wh_none"):
        for entity in ("world/ground_truth_map", "world/ground_truth", "world/trajectory/frontend",
                       "world/trajectory/optimised", "world/keyframes", "world/loop_closures",
                       "world/false_loop_closures", "world/robot", "world/robot/scan", "map/occupancy"):
            assert f"/{run}/{entity}" in paths, f"/{run}/{entity}"


class _Steps:
    """An observer that keeps every step snapshot."""

    wants_steps = True

    def __init__(self):
        self.snaps = []

    def on_step(self, snap) -> None:
        self.snaps.append(snap)


def test_keyframe_snapshots_are_typed_read_only_copies():
    # issue 30: the lidar SLAM seam sends a LidarSlamSnapshot per keyframe, not a dict of keys
    seq, grid = _sim_parts(_simulate({"name": "short", "world": "office", "world_size_m": [20.0, 20.0],
                                      "num_goals": 2, "duration_s": 30.0}, 0))
    steps = _Steps()
    res = run_slam(seq, grid, LidarSlamConfig(), observer=steps)
    assert [s.index for s in steps.snaps] == list(range(len(res.stamps_s))) and len(steps.snaps) >= 5
    assert all(s.kind == "lidar_slam" and isinstance(s.state, LidarSlamSnapshot) for s in steps.snaps)
    np.testing.assert_array_equal([s.stamp_s for s in steps.snaps], res.stamps_s)
    for k in (0, len(steps.snaps) - 1):
        state = steps.snaps[k].state
        assert state.world_xytheta_body.shape == (3,) and state.body_p_scan.shape[1] == 2
        np.testing.assert_array_equal(state.body_p_scan, res.keyframe_points[k])
        with pytest.raises(ValueError):
            state.body_p_scan[0, 0] = 1.0
    # the first keyframe is added at the known start, and snapshots are the poses when added
    np.testing.assert_allclose(steps.snaps[0].state.world_xytheta_body, res.frontend_poses[0])


def test_config_errors():
    with pytest.raises(ConfigError, match=r"lidar_slam\.slam\.icp: unknown parameter\(s\) \['methd'\] for IcpConfig"):
        build(LidarSlamConfig, {"icp": {"methd": "point_to_line"}}, "lidar_slam.slam")
    with pytest.raises(ConfigError):
        build(LidarSlamConfig, {"robust": "tukey"})
    with pytest.raises(ConfigError, match="worlds"):
        run_pipeline({"pipeline": "lidar_slam", "name": "x"}, "/tmp/never_written", progress=False)
    cfg = build(LidarSlamConfig, {"loops": {"search_radius_m": 2.0, "icp": {"trim_fraction": 0.8}},
                                  "map": {"resolution_m": 0.05}})
    assert cfg.loops.search_radius_m == 2.0 and cfg.loops.icp.trim_fraction == 0.8
    assert cfg.map.resolution_m == 0.05
    # a section overrides the system's default section, not its class's defaults (issue 30): the
    # scan matcher's trimmed ICP (0.9, IcpConfig's own default is 1.0) survives a partial section
    partial = build(LidarSlamConfig, {"icp": {"max_iterations": 20}, "loops": {"min_fitness": 0.7}})
    assert (partial.icp.max_iterations, partial.icp.trim_fraction) == (20, 0.9)
    assert (partial.loops.min_fitness, partial.loops.icp.trim_fraction) == (0.7, 0.9)


def test_slam_by_motion_prior_is_merged_into_slam_key_by_key():
    config = {"slam": {"submap_keyframes": 8, "icp": {"trim_fraction": 0.9, "max_iterations": 30},
                       "loops": {"min_fitness": 0.6, "icp": {"trim_fraction": 0.9}}},
              "slam_by_motion_prior": {"constant_velocity": {"icp": {"trim_fraction": 1.0, "target_voxel_m": 0.05},
                                                             "loops": {"icp": {"target_voxel_m": 0.05}}}}}
    lidar_only = build(LidarSlamConfig, slam_section_for(config["slam"], config["slam_by_motion_prior"], "constant_velocity"))
    assert lidar_only.motion_prior == "constant_velocity" and lidar_only.submap_keyframes == 8
    assert (lidar_only.icp.trim_fraction, lidar_only.icp.max_iterations, lidar_only.icp.target_voxel_m) == (1.0, 30, 0.05)
    assert (lidar_only.loops.min_fitness, lidar_only.loops.icp.trim_fraction,
            lidar_only.loops.icp.target_voxel_m) == (0.6, 0.9, 0.05)
    with_odometry = build(LidarSlamConfig, slam_section_for(config["slam"], config["slam_by_motion_prior"], "odometry"))
    assert with_odometry.icp.trim_fraction == 0.9 and with_odometry.icp.target_voxel_m == 0.0
    from slamkit.experiments.pipeline import check_pipeline

    with pytest.raises(ConfigError, match="slam_by_motion_prior"):
        check_pipeline({"pipeline": "lidar_slam", "logs": ["intel-log"],
                        "slam_by_motion_prior": {"constant_velocity": {"icp": {"voxel": 0.05}}}})


def test_trim_to_free_space(world):
    seq, grid = world
    assert trim_to_free_space(seq, grid) is seq  # this tour stays in free space
    # a grid that is occupied right of x = 10 m cuts the tour where it first crosses
    occ = grid.occupied.copy()
    occ[:, int(10.0 / grid.resolution_m):] = True
    blocked = replace(grid, occupied=occ)
    cut = trim_to_free_space(seq, blocked)
    x = seq.ground_truth.world_t_body[:, 0]
    first = seq.ground_truth.stamps_s[np.flatnonzero(x >= 10.0)[0]]
    assert cut.ground_truth.stamps_s[-1] < first and all(e.stamp_s < first for e in cut.events)
    assert cut.metadata["trimmed_s"] == pytest.approx(seq.ground_truth.stamps_s[-1] - first)


@pytest.mark.slow
def test_shipped_pipeline_config(tmp_path):
    """pipelines/lidar_slam.yaml as shipped: every run of the loop-rich warehouse keeps a map IoU
    of at least 0.9 and loop closure never makes ATE worse by more than noise."""
    from pathlib import Path

    cfg = Path(__file__).resolve().parents[2] / "pipelines" / "lidar_slam.yaml"
    res = run_pipeline(cfg, tmp_path / "run", progress=False)
    runs = res.results["runs"]
    assert len(runs) == 4
    for r in runs:
        m = r["metrics"]
        assert m["ate_rmse_m"] <= 1.2 * m["ate_frontend_m"] + 0.002
        if r["dataset"] == "warehouse_loops":
            assert m["num_loop_closures"] >= 50 and m["map_iou"] >= 0.9


def test_log_pipeline_on_an_intel_slice(tmp_path, verify_rrd):
    """A laser-log entry ({name, path: registry name, duration_s}) through the pipeline: the
    relation metrics, the TUM trajectory at the scans' ipc stamps, the map and timing plots, the
    report beside the published numbers, and the recording."""
    from slamkit.data import registry

    if not registry.is_available(registry.get("intel-log")):
        pytest.skip("intel-log is not available locally")
    from pathlib import Path

    from slamkit.data.formats.tum import read_tum
    from slamkit.experiments.pipeline import load_config

    cfg = load_config(Path(__file__).resolve().parents[2] / "pipelines" / "lidar_slam_logs.yaml")
    cfg.update(logs=[{"name": "intel", "path": "intel-log", "duration_s": 60.0}], motion_priors=["odometry"],
               perturbations=None)
    res = run_pipeline(cfg, tmp_path / "run", progress=False, observer_factory=observer_for)
    (run,) = res.results["runs"]
    m = run["metrics"]
    # measured on the first 60 s (306 scans, 6 relations): 0.024 +- 0.012 m (the robot turns on the spot in a corridor)
    assert m["relation_count"] == 6 and m["relation_trans_mean_m"] < 0.03
    for key in ("relation_trans_std_m", "relation_rot_mean_deg", "relation_rot_std_deg", "real_time_factor",
                "time_total_s", "num_loop_closures", "loop_closures_online", "loop_closures_final",
                "relation_trans_mean_m_odometry", "peak_rss_mb", "time_per_scan_median_ms"):
        assert key in m, key
    out = res.out_dir
    traj = read_tum(out / "trajectories" / "intel.tum")
    assert len(traj) == m["num_scans"] == 306
    assert {p.name for p in (out / "plots").iterdir()} == {"map_intel.png", "time_per_scan_intel.png"}
    report = (out / "report.md").read_text()
    assert "graph mapping" in report and "0.031 +- 0.026" in report
    paths = verify_rrd(out / "recording.rrd")
    for entity in ("world/trajectory/scans", "world/trajectory/optimised", "world/keyframes", "world/robot/scan",
                   "map/occupancy"):
        assert f"/intel/{entity}" in paths, entity


def test_a_dataclass_bound_of_a_per_prior_section_is_refused_where_it_was_written(tmp_path):
    """The dataclasses' own checks run on every config a run would build, before anything runs,
    named by file and line: a correlative window of 100 m at 5 cm (2000 cells each side, a search
    that would not end) in the lidar-only prior's section of the logs pipeline."""
    text = (Path(__file__).resolve().parents[2] / "pipelines" / "lidar_slam_logs.yaml").read_text()
    assert text.count("correlative: {window_xy_m: 2.0}") == 1
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("correlative: {window_xy_m: 2.0}", "correlative: {window_xy_m: 100}"))
    line = 1 + text.splitlines().index("  constant_velocity:")
    with pytest.raises(ConfigError, match=rf"bad\.yaml:{line}: slam_by_motion_prior\.constant_velocity\.correlative: "
                                          r"CorrelativeConfig: window_xy_m 100 m is more than 200 cells"):
        validate_pipeline_config(bad)
