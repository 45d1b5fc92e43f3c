"""One table of pipeline kinds: each pipeline declares its name, config model, payload type and run
function; the viz layer's recorders are registered against it; names follow slamkit.naming."""

from __future__ import annotations

import subprocess
import sys

import pytest

from slamkit.errors import ConfigError
from slamkit.experiments import pipeline as pipeline_mod
from slamkit.experiments.config_models import PipelineConfig
from slamkit.experiments.pipeline import check_pipeline
from slamkit.experiments.pipeline import PIPELINES, Pipeline, PipelineOutput, pipeline_of, register_pipeline
from slamkit.experiments.results import RunRecord
from slamkit.naming import SlamkitDeprecationWarning


def test_every_pipeline_declares_its_name_model_and_payload() -> None:
    assert PIPELINES.names() == ["pose_graph", "pose_graph_outliers", "filter_vs_smoother", "local_planning",
                                 "lidar_slam", "visual_odometry", "navigation"]
    for name in PIPELINES:
        p = pipeline_of(name)
        assert isinstance(p, Pipeline) and p.name == name
        assert issubclass(p.config_model, PipelineConfig)
        assert p.config_model.model_fields["pipeline"].annotation.__args__ == (name,)
        assert p.payload_type is not None and callable(p.run)


def test_importing_the_pipeline_module_imports_no_pipeline() -> None:
    code = ("import sys, slamkit.experiments.pipeline; "
            "print(sorted(m for m in ('slamkit.experiments.pose_graph', 'slamkit.experiments.filter_vs_smoother', "
            "'slamkit.experiments.closed_loop', 'slamkit.experiments.lidar_slam', "
            "'slamkit.experiments.pose_graph_outliers', 'slamkit.experiments.visual_odometry', "
            "'slamkit.experiments.navigation') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_old_spellings_warn_and_unknown_names_suggest() -> None:
    config = {"pipeline": "Filter-Vs-Smoother", "scenarios": ["mild"], "estimators": ["ekf"]}
    with pytest.warns(SlamkitDeprecationWarning, match="write 'filter_vs_smoother'"):
        check_pipeline(config)
    assert config["pipeline"] == "filter_vs_smoother"
    with pytest.raises(ConfigError, match=r"<config>: pipeline: unknown pipeline 'lidar_slma' "
                                          r"\(did you mean 'lidar_slam'\?\)"):
        check_pipeline({"pipeline": "lidar_slma"})


def _toy(config, folder, progress, observer) -> PipelineOutput[None]:
    return PipelineOutput([RunRecord("toy", "est", {"ate_rmse_m": 1.0})], "# toy\n")


def test_a_users_pipeline_is_registered_once_and_checked_for_the_common_fields() -> None:
    register_pipeline(Pipeline("my_toy", _toy))
    try:
        with pytest.raises(ConfigError, match="pipeline 'my_toy' is already registered"):
            register_pipeline(Pipeline("my_toy", _toy))
        assert check_pipeline({"pipeline": "my_toy", "anything": 1}).record is True
        with pytest.raises(ConfigError, match=r"record: Input should be a valid boolean"):
            check_pipeline({"pipeline": "my_toy", "record": "maybe"})
    finally:
        PIPELINES.unregister("my_toy")
    assert "my_toy" not in PIPELINES
    with pytest.raises(ConfigError, match="names must be snake_case"):
        register_pipeline(Pipeline("My Toy", _toy))


def test_a_lazy_target_must_be_the_pipeline_it_is_registered_as(monkeypatch) -> None:
    monkeypatch.setattr(sys.modules[__name__], "WRONG", Pipeline("other", _toy), raising=False)
    entry = pipeline_mod._Entry(f"{__name__}:WRONG")
    with pytest.raises(TypeError, match="must be a Pipeline named 'mine'"):
        entry.pipeline("mine")
