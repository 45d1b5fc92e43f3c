"""``slamkit simulate`` and scenario YAMLs: same seed same bytes, recordings verified, bad
scenarios named precisely."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from slamkit.cli import app
from slamkit.data.formats.sequence import load_sequence
from slamkit.data.sequence import RangeBearing, Scan
from slamkit.errors import ConfigError
from slamkit.models.imu import ImuNoise
from slamkit.sim.grid_world import GridScenario
from slamkit.sim.landmark_world import LandmarkScenario
from slamkit.sim.scenario import load_scenario, scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = sorted((ROOT / "pipelines" / "scenarios").glob("*.yaml"))
runner = CliRunner()


def _run(*args: str) -> dict:
    result = runner.invoke(app, ["simulate", *args, "--json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_every_shipped_scenario_parses(path):
    scenario = load_scenario(path)
    assert isinstance(scenario, (LandmarkScenario, GridScenario))
    assert scenario.duration_s >= 60.0


def test_same_seed_same_bytes_and_recording(tmp_path, verify_rrd):
    yaml_path = tmp_path / "short.yaml"
    yaml_path.write_text("kind: landmark\npreset: mild\nduration_s: 15.0\n")
    a = _run(str(yaml_path), "--seed", "4", "--out", str(tmp_path / "a.slamseq"),
             "--rrd", str(tmp_path / "a.rrd"))
    b = _run(str(yaml_path), "--seed", "4", "--out", str(tmp_path / "b.slamseq"))
    c = _run(str(yaml_path), "--seed", "5", "--out", str(tmp_path / "c.slamseq"))
    assert a["sha256"] == b["sha256"] != c["sha256"]
    assert (tmp_path / "a.slamseq").read_bytes() == (tmp_path / "b.slamseq").read_bytes()
    assert a["events"] == {"Odometry": 150, "RangeBearing": 151} and a["num_landmarks"] == 40
    seq = load_sequence(tmp_path / "a.slamseq")
    assert seq.metadata["seed"] == 4 and len(seq.of_type(RangeBearing)) == 151
    entities = verify_rrd(tmp_path / "a.rrd")
    assert {"/world/landmarks", "/world/ground_truth", "/world/robot", "/world/robot/observations",
            "/plots/odometry/v_mps"} <= entities


def test_simulate_to_file_is_the_library_behind_the_command(tmp_path):
    from slamkit.sim.scenario import simulate_to_file

    yaml_path = tmp_path / "short.yaml"
    yaml_path.write_text("kind: landmark\npreset: mild\nduration_s: 15.0\n")
    written = simulate_to_file(yaml_path, 4, tmp_path / "a.slamseq")
    summary = written.summary()
    printed = _run(str(yaml_path), "--seed", "4", "--out", str(tmp_path / "b.slamseq"))
    assert printed == {**summary, "out": str(tmp_path / "b.slamseq"), "rrd": None}
    assert written.sha256 == printed["sha256"] and written.path == tmp_path / "a.slamseq"
    assert summary["events"] == {"Odometry": 150, "RangeBearing": 151} and summary["num_landmarks"] == 40
    assert summary["duration_s"] == pytest.approx(15.0) and written.simulation.seed == 4


def test_grid_scenario_recording_has_map_scan_and_gps(tmp_path, verify_rrd):
    yaml_path = tmp_path / "grid.yaml"
    yaml_path.write_text(
        "kind: grid\nworld: warehouse\nworld_size_m: [20, 20]\nworld_resolution_m: 0.1\n"
        "duration_s: 6.0\nimu_rate_hz: null\nencoder: null\nlidar: {num_beams: 60}\n"
        "moving_obstacles: 2\n")
    out = _run(str(yaml_path), "--seed", "0", "--out", str(tmp_path / "g.slamseq"),
               "--rrd", str(tmp_path / "g.rrd"))
    assert set(out["events"]) == {"Odometry", "Scan", "Gps"}
    seq = load_sequence(tmp_path / "g.slamseq")
    assert len(seq.of_type(Scan)[0].ranges_m) == 60
    entities = verify_rrd(tmp_path / "g.rrd")
    assert {"/world/map", "/world/robot/scan", "/world/robot/scan/beams", "/world/gps",
            "/world/ground_truth", "/world/moving_obstacles"} <= entities


def test_bad_scenario_exits_with_the_key_named(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("kind: landmark\nsensor: {sigma_range: 0.1}\n")
    result = runner.invoke(app, ["simulate", str(bad), "--out", str(tmp_path / "x.slamseq")])
    assert result.exit_code == 2
    assert "bad.yaml:2: sensor.sigma_range: unknown key (did you mean 'sigma_range_m'?)" in result.output
    assert not (tmp_path / "x.slamseq").exists()


def test_scenario_dicts_presets_nesting_and_switches():
    s = scenario_from_dict({"kind": "landmark", "preset": "strong", "duration_s": 30.0})
    assert s.name == "landmark_strong" and s.duration_s == 30.0 and s.sensor.rate_hz == 5.0
    s = scenario_from_dict({"kind": "landmark", "preset": "mild", "gps": {"sigma_m": 0.5, "rate_hz": 2.0}})
    assert s.gps.sigma_m == 0.5 and s.gps.rate_hz == 2.0
    s = scenario_from_dict({"kind": "landmark", "gps": {"preset": "rtk"}})
    assert s.gps.sigma_m < 0.1
    s = scenario_from_dict({"kind": "landmark", "profile": [[1.0, 0.5, 0.0]], "path": "profile"})
    assert s.profile == ((1.0, 0.5, 0.0),)
    g = scenario_from_dict({"kind": "grid", "imu_noise": "ideal", "gps": {"preset": "rtk"},
                            "lidar": {"num_beams": 10, "beam_model": {"z_hit": 1.0, "z_short": 0.0,
                                                                       "z_max": 0.0, "z_rand": 0.0}},
                            "encoder": None})
    assert g.imu_noise == ImuNoise.preset("ideal") and g.encoder is None
    assert g.gps.sigma_m < 0.1 and g.lidar.num_beams == 10 and g.lidar.beam_model.z_hit == 1.0
    for bad, match in [({"kind": "boat"}, "kind"), ({"kind": "grid", "world": "moon"}, "moon"),
                       ({"kind": "landmark", "preset": "wild"}, "preset"),
                       ({"kind": "grid", "lidar": {"num_beams": "many", "beam_model": 3}}, "beam_model"),
                       ({"kind": "landmark", "duration": 3}, "duration")]:
        with pytest.raises(ConfigError, match=match):
            scenario_from_dict(bad, "s.yaml")


def test_map_file_worlds_ros_yaml_and_movingai(tmp_path, shared_datasets):
    from slamkit.maps.generators import OfficeConfig, office
    from slamkit.sim.ros_map import save_ros_map
    from slamkit.sim.scenario import simulate

    grid = office(np.random.default_rng(2), OfficeConfig(width_m=20.0, height_m=20.0, resolution_m=0.1))
    save_ros_map(tmp_path / "maps" / "office.yaml", grid)
    (tmp_path / "s.yaml").write_text(
        "kind: grid\nworld: file\nmap_file: maps/office.yaml\nduration_s: 5.0\n"
        "imu_rate_hz: null\nencoder: null\ngps: null\nlidar: {num_beams: 30}\n")
    result = simulate(load_scenario(tmp_path / "s.yaml"), seed=1)
    np.testing.assert_array_equal(result.grid.occupied, grid.occupied)  # lossless through PGM
    assert len(result.sequence.of_type(Scan)) == 51

    den = load_scenario(ROOT / "pipelines" / "scenarios" / "movingai_den312d.yaml")
    den = type(den)(**{**den.__dict__, "duration_s": 5.0})
    result = simulate(den, seed=0)
    assert result.grid.shape == (81, 65) and result.grid.resolution_m == 0.5
    gt = result.sequence.ground_truth.xytheta()
    assert result.grid.is_free_world(gt[:, :2]).all()
