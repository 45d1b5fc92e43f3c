"""A pipeline runs on what validation accepted (issue 31's typed-config cases): numbers written as
strings are numbers, explicit nulls mean the default, a word where a section is expected is a
ConfigError naming file, line and field."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from slamkit.cli import app
from slamkit.errors import ConfigError
from slamkit.experiments.pipeline import check_pipeline

POSE_GRAPH = {"pipeline": "pose_graph", "name": "x", "datasets": ["intel"], "solvers": ["lm"], "inits": ["file"],
              "record": False}
LIDAR = {"pipeline": "lidar_slam", "name": "x", "seeds": [0], "record": False,
         "worlds": [{"name": "o", "world": "office", "world_size_m": [30.0, 30.0], "num_goals": 1, "duration_s": 10.0}]}


def test_a_number_written_as_a_string_becomes_the_number() -> None:
    config = {**POSE_GRAPH, "options": {"relative_error_tol": "1e-8", "max_iterations": 50}}
    check_pipeline(config)
    assert config["options"] == {"relative_error_tol": 1e-8, "max_iterations": 50}
    assert isinstance(config["options"]["relative_error_tol"], float)


def test_an_explicit_null_means_the_default_at_every_depth() -> None:
    config = {**LIDAR, "slam": {"keyframes": {"min_rotation_rad": None, "min_translation_m": 0.4}, "robust": None}}
    check_pipeline(config)
    assert config["slam"] == {"keyframes": {"min_translation_m": 0.4}}
    options = {**POSE_GRAPH, "options": {"max_iterations": None}}
    check_pipeline(options)
    assert options["options"] == {}


@pytest.mark.parametrize("section, config", [
    ("slam.map", {**LIDAR, "slam": {"map": "x"}}),
    ("vo.ba", {"pipeline": "visual_odometry", "name": "x", "sequences": ["kitti-vo-a"], "vo": {"ba": "x"}}),
])
def test_a_word_where_a_section_is_expected_is_refused(section: str, config: dict) -> None:
    with pytest.raises(ConfigError, match=rf"{section}: a section of fields \(key: value\), got 'x'"):
        check_pipeline(config)


def test_a_preset_name_still_stands_for_a_section_that_has_presets() -> None:
    from slamkit.config import model_of
    from slamkit.systems.visual_inertial import VioConfig

    model = model_of(VioConfig)
    assert model.model_validate({"imu_noise": "consumer_mems"}).imu_noise == "consumer_mems"
    assert model.model_validate({"imu_noise": {"preset": "consumer_mems"}}).imu_noise is not None


def test_slamkit_run_with_a_string_tolerance_and_a_null_option_succeeds(tmp_path: Path) -> None:
    config = tmp_path / "pg.yaml"
    config.write_text("pipeline: pose_graph\nname: pg\ndatasets: [intel]\nsolvers: [lm]\ninits: [file]\n"
                      "options: {relative_error_tol: 1e-8, max_iterations: null}\nrecord: false\n")
    done = CliRunner().invoke(app, ["run", str(config), "--out", str(tmp_path / "out")])
    assert done.exit_code == 0, done.output
    written = (tmp_path / "out" / "config.yaml").read_text()
    assert "relative_error_tol" in written
