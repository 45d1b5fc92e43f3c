"""Every config file is validated into typed models before anything runs (issue 10): unknown
keys with the nearest name, wrong types, NaN/inf and out-of-range numbers name the file, line
and field; YAML cannot blow up memory; a pipeline that would run nothing is an error."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from fuzzing import fuzz

from slamkit.errors import ConfigError
from slamkit.experiments.pipeline import run_pipeline, validate_pipeline_config
from slamkit.sim.ros_map import load_ros_map
from slamkit.sim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]


def _refused(tmp_path, text: str | bytes, loader=validate_pipeline_config) -> str:
    path = tmp_path / "c.yaml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(ConfigError) as info:
        loader(path)
    return str(info.value).replace(str(path), "c.yaml")


@pytest.mark.parametrize("text, message", [
    ("pipeline: pose_graph\ndatasets: [ring]\noptions: {max_iteratons: 10}\n",
     "c.yaml:3: options.max_iteratons: unknown key (did you mean 'max_iterations'?)"),
    ("pipeline: pose_graph\ndatasets: [ring]\noptions:\n  max_iterations: abc\n",
     "c.yaml:4: options.max_iterations: Input should be a valid integer, unable to parse string as an integer (got 'abc')"),
    ("pipeline: pose_graph\ndatasets: [ring, 5]\n", "c.yaml:2: datasets.1: Input should be a valid string (got 5)"),
    # a misspelt dataset fails at validation, not after the others were solved (issue 32)
    ("pipeline: pose_graph\ndatasets:\n  - ring\n  - intl_g2o\n",
     "c.yaml:4: datasets.1: 'intl_g2o' is neither an existing file nor a registry name (no dataset named "
     "'intl_g2o' in the registry; did you mean intel-g2o"),
    ("pipeline: pose_graph_outliers\ndatasets: [intel_g2o, ringg]\n", "c.yaml:2: datasets.1: 'ringg' is neither"),
    ("pipeline: pose_graph\ndatasets: [ring]\ninits: []\n",
     "c.yaml:3: inits: List should have at least 1 item after validation, not 0 (got [])"),
    ("pipeline: pose_graph\ndatasets: [ring]\nsolver: [gn]\n", "c.yaml:3: solver: unknown key (did you mean 'solvers'?)"),
    ("pipeline: filter_vs_smoother\nseed: 6\nscenarios: [mild]\nestimators: [ekf]\n",
     "c.yaml:2: seed: unknown key (did you mean 'seeds'?)"),
    # a bare scenario name that is no preset is a dataset: a misspelt one fails at validation (issue 32)
    ("pipeline: filter_vs_smoother\nestimators: [ekf]\nscenarios:\n  - mild\n  - citytres10000\n",
     "c.yaml:5: scenarios.1.dataset: no dataset named 'citytres10000' in the registry; did you mean citytrees10000"),
    ("pipeline: filter_vs_smoother\nestimators: [ekf]\nplugins: slamkit_example_plugin\nscenarios: [mild]\n",
     "c.yaml:3: plugins: a list of module names, got 'slamkit_example_plugin'"),
    ("pipeline: filter_vs_smoother\nscenarios: [{preset: mild, params: {duration_s: .nan}}]\nestimators: [ekf]\n",
     "c.yaml:2: scenarios.0.params.duration_s: Input should be a finite number (got nan)"),
    ("pipeline: filter_vs_smoother\nscenarios: [{preset: mild, params: {duration_s: 1.0e+20}}]\nestimators: [ekf]\n",
     "c.yaml:2: scenarios.0.params.duration_s: Input should be less than or equal to 86400 (got 1e+20)"),
    ("pipeline: filter_vs_smoother\nscenarios: [mild]\nestimators: {ekf: {gate_probabilty: 0.9}}\n",
     "c.yaml:3: estimators.ekf.gate_probabilty: unknown key (did you mean 'gate_probability'?)"),
    ("pipeline: filter_vs_smoother\nscenarios: [mild]\nestimators: [kalmann]\n",
     "unknown estimator 'kalmann'"),
    ("pipeline: filter_vs_smoother\nscenarios: [mild]\nestimators: [isam]\n",
     "c.yaml:3: estimators.isam: unknown estimator 'isam' (did you mean 'isam2'?); known: ekf, "),
    # one config per smoother: iSAM2's options are its own, the lag belongs to fixed_lag
    ("pipeline: filter_vs_smoother\nscenarios: [mild]\nestimators:\n  isam2: {relinearize_treshold: 0.1}\n",
     "c.yaml:4: estimators.isam2.relinearize_treshold: unknown key (did you mean 'relinearize_threshold'?)"),
    ("pipeline: filter_vs_smoother\nscenarios: [mild]\nestimators:\n  isam2: {lag_s: 2.0}\n",
     "c.yaml:4: estimators.isam2.lag_s: unknown key; valid keys: compute_covariances, noise, "),
    ("pipeline: filter_vs_smoother\nscenarios: [mild]\nestimators:\n  batch: {max_iterations: 0.5}\n",
     "c.yaml:4: estimators.batch.max_iterations: Input should be a valid integer"),
    ("pipeline: local_planning\nclosed_loop: {max_time_s: 1.0e+20}\n",
     "c.yaml:2: closed_loop.max_time_s: Input should be less than or equal to 86400 (got 1e+20)"),
    # navigation: the stack's section and each variant's overrides against NavigationConfig's and
    # EpisodeConfig's models, nested sections included; a former flat key names its section (issue 30)
    ("pipeline: navigation\nnavigation:\n  controller: dwa\n  yielding: {hegde: 0.3}\n",
     "c.yaml:4: navigation.yielding.hegde: unknown key (did you mean 'hedge'?)"),
    ("pipeline: navigation\nnavigation:\n  yielding: 0.3\n",
     "c.yaml:3: navigation.yielding: a section of fields (key: value), got 0.3"),
    ("pipeline: navigation\nvariants:\n  - name: a\n  - name: b\n    navigation:\n      yield_hedge: 0.2\n",
     "c.yaml:6: variants.1.navigation.yield_hedge: moved into a section: yield_hedge -> yielding.hedge"),
    ("pipeline: navigation\nnavigation: {stuck_s: 4.0}\n",
     "c.yaml:2: navigation.stuck_s: moved into a section: stuck_s -> recovery.stuck_s"),
    ("pipeline: navigation\nnavigation:\n  mcl: {n_maxx: 100}\n",
     "c.yaml:3: navigation.mcl.n_maxx: unknown key (did you mean 'n_max'?)"),
    ("pipeline: navigation\nepisode:\n  max_time_s: 30.0\nvariants:\n  - name: a\n    episode:\n"
     "      goal_tolerence_m: 0.1\n",
     "c.yaml:7: variants.0.episode.goal_tolerence_m: unknown key (did you mean 'goal_tolerance_m'?)"),
    ("pipeline: navigation\nepisode:\n  max_time_s: 1.0e+20\n",
     "c.yaml:3: episode.max_time_s: Input should be less than or equal to 86400 (got 1e+20)"),
    ("pipeline: lidar_slam\nworlds: [{world: office}]\nslam: {keyframes: {min_translaton_m: 1}}\n",
     "c.yaml:3: slam.keyframes.min_translaton_m: unknown key (did you mean 'min_translation_m'?)"),
    ("pipeline: pose_grap\ndatasets: [ring]\n", "c.yaml:1: pipeline: unknown pipeline 'pose_grap' (did you mean 'pose_graph'?)"),
    ("pipeline: pose_graph\nname: &a [*a]\ndatasets: [ring]\n",
     "c.yaml: line 2: alias *a refers to the node that contains it (a recursive structure)"),
    (b"pipeline: pose_graph\ndatasets: [ring]\n\xff\xfe: 1\n", "c.yaml:3: not UTF-8 text (byte 0xff)"),
])
def test_config_errors_name_file_line_and_field(tmp_path, text, message) -> None:
    assert message in _refused(tmp_path, text)


def test_an_alias_bomb_is_refused_quickly(tmp_path) -> None:
    rows = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for prev, cur in zip("abcdefgh", "bcdefghi"):
        rows.append(f"{cur}: &{cur} [" + ",".join([f"*{prev}"] * 9) + "]")
    bomb = "\n".join(rows) + "\npipeline: pose_graph\n"  # 9^9 = 387 M strings if expanded
    assert len(bomb) < 600
    t0 = time.process_time()
    message = _refused(tmp_path, bomb)
    assert message == "c.yaml: the YAML expands to more than 200000 nodes through its aliases; refused (an alias bomb?)"
    assert time.process_time() - t0 < 5.0  # (issue: > 60 s and > 2 GB before)


def test_a_pipeline_that_runs_nothing_is_an_error(tmp_path) -> None:
    cfg = {"pipeline": "pose_graph", "datasets": ["ring"], "inits": ["chordal"], "record": False}
    with pytest.raises(ConfigError, match="pipeline 'pose_graph' ran nothing"):
        run_pipeline(cfg, tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


FVS = "pipeline: filter_vs_smoother\nestimators: [es_ekf]\nscenarios:\n  - dataset: {dataset}\n    params: {params}\n"


@pytest.mark.parametrize("dataset, params, message", [
    # issue 31: dataset params were never validated: an unknown key was a TypeError at run time,
    # max_duration_s -1 or .nan ran to exit 0 with only total_time_s in the results
    ("kitti-imu-gps", "{foo: 10}", "c.yaml:5: scenarios.0.params.foo: unknown key; valid keys: "
     "first_outage_after_s, gap_s, max_duration_s, outage_s, start_fix"),
    ("kitti-imu-gps", "{max_duration_s: -1}",
     "c.yaml:5: scenarios.0.params.max_duration_s: Input should be greater than 0 (got -1)"),
    ("kitti-imu-gps", "{max_duration_s: 0}",
     "c.yaml:5: scenarios.0.params.max_duration_s: Input should be greater than 0 (got 0)"),
    ("plaza1", "{max_duration_s: 0.0}",
     "c.yaml:5: scenarios.0.params.max_duration_s: Input should be greater than 0 (got 0.0)"),
    ("kitti-imu-gps", "{max_duration_s: .nan}",
     "c.yaml:5: scenarios.0.params.max_duration_s: Input should be a finite number (got nan)"),
    ("kitti-imu-gps", "{gap_s: 1.0e+20}",
     "c.yaml:5: scenarios.0.params.gap_s: Input should be less than or equal to 86400 (got 1e+20)"),
    ("plaza1", "{range_scal: 2}", "c.yaml:5: scenarios.0.params.range_scal: unknown key (did you mean 'range_scale'?)"),
    ("citytrees10000", "{robot: A}", "c.yaml:5: scenarios.0.params.robot: unknown key; valid keys: max_poses, pose_dt_s"),
    ("citytrees10000", "{max_poses: -3}",
     "c.yaml:5: scenarios.0.params.max_poses: Input should be greater than or equal to 0 (got -3)"),
    ("mrclam1", "{max_duration_s: .inf}",
     "c.yaml:5: scenarios.0.params.max_duration_s: Input should be a finite number (got inf)"),
    ("no-such-set", "{}", "c.yaml:4: scenarios.0.dataset: no dataset named 'no-such-set'"),
])
def test_dataset_scenario_params_are_checked_against_the_readers_signature(tmp_path, dataset, params,
                                                                           message) -> None:
    assert message in _refused(tmp_path, FVS.format(dataset=dataset, params=params))


def test_the_shipped_dataset_params_are_valid(tmp_path) -> None:
    text = FVS.format(dataset="kitti-imu-gps", params="{outage_s: 10.0, gap_s: 30.0, max_duration_s: 120}")
    path = tmp_path / "c.yaml"
    path.write_text(text)
    validate_pipeline_config(path)


def test_scenario_and_ros_map_yaml_are_validated(tmp_path) -> None:
    assert "c.yaml:2: duration_s: Input should be less than or equal to 86400 (got 1e+20)" in _refused(
        tmp_path, "kind: grid\nduration_s: 1.0e+20\n", load_scenario)
    assert "c.yaml:2: num_landmark: unknown key (did you mean 'num_landmarks'?)" in _refused(
        tmp_path, "kind: landmark\nnum_landmark: 3\n", load_scenario)
    assert "c.yaml:2: resolution: Input should be greater than or equal to 0.0001 (got -0.1)" in _refused(
        tmp_path, "image: m.pgm\nresolution: -0.1\norigin: [0, 0, 0]\n", load_ros_map)


def test_every_shipped_config_is_valid() -> None:
    for path in sorted((ROOT / "pipelines").glob("*.yaml")):
        # a config is named after its kind, or after its kind and what it runs it on
        # (lidar_slam_logs.yaml: the lidar_slam kind on recorded logs)
        kind = validate_pipeline_config(path)["pipeline"]
        assert path.stem == kind or path.stem.startswith(f"{kind}_"), path.name
    for path in sorted((ROOT / "pipelines" / "scenarios").glob("*.yaml")):
        load_scenario(path)


# --- fuzz: 0 tracebacks, 0 hangs over every config kind ------------------------------------------

def _targets():
    shared = ROOT.parent / "shared" / "datasets" / "maps_ros"
    out = [(f"pipeline:{p.stem}", validate_pipeline_config, p.read_bytes(), None)
           for p in sorted((ROOT / "pipelines").glob("*.yaml"))]
    out += [(f"scenario:{p.stem}", load_scenario, p.read_bytes(), None)
            for p in sorted((ROOT / "pipelines" / "scenarios").glob("*.yaml"))]
    if (shared / "willow-2010-02-18-0.10.yaml").exists():
        def prepare(workdir, case):
            (workdir / "willow-2010-02-18-0.10.pgm").write_bytes((shared / "willow-2010-02-18-0.10.pgm").read_bytes())
            (workdir / "map.yaml").write_bytes(case)
            return workdir / "map.yaml"
        out.append(("ros_map_yaml", load_ros_map, (shared / "willow-2010-02-18-0.10.yaml").read_bytes(), prepare))
    return out


def _fuzz_all(tmp_path, cases: int) -> dict:
    reports = {}
    for name, target, seed_bytes, prepare in _targets():
        reports[name] = fuzz(target, seed_bytes, suffix=".yaml", cases=cases, seed=7,
                             workdir=tmp_path / name.replace(":", "_"), name=name, prepare=prepare,
                             check=lambda result: None, timeout_s=10.0)
    return reports


def test_config_fuzz_default(tmp_path) -> None:
    reports = _fuzz_all(tmp_path, 25)
    bad = [r.summary() for r in reports.values() if r.defect_count]
    assert not bad, "\n\n".join(bad)
    assert sum(r.counts["clean_error"] for r in reports.values()) > 0


@pytest.mark.slow
def test_config_fuzz_350_per_format(tmp_path) -> None:
    reports = _fuzz_all(tmp_path, 350)
    bad = [r.summary() for r in reports.values() if r.defect_count]
    assert not bad, "\n\n".join(bad)
