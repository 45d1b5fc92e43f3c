"""tools/compare_runs.py: identical folders pass, every kind of difference is found and named,
wall-clock fields are ignored (issue 30's before/after proof)."""

from __future__ import annotations

import copy
import importlib.util
import json
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "tools" / "compare_runs.py"


@pytest.fixture(scope="module")
def cr():
    spec = importlib.util.spec_from_file_location("compare_runs", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


RESULTS = {
    "pipeline": "filter_vs_smoother", "slamkit_version": "0.1.0", "created": "2026-01-01T00:00:00",
    "runs": [{"dataset": "mild", "estimator": "ekf", "seed": 0,
              "metrics": {"ate_rmse_m": 0.41, "rpe_rmse_m": 0.05, "total_time_s": 0.06,
                          "step_latency_median_ms": 0.08, "frontend_ms_median": 140.0,
                          "nees_mean": float("nan")}}],
    "summary": [{"dataset": "mild", "estimator": "ekf", "metric": "ate_rmse_m", "mean": 0.41, "n": 1},
                {"dataset": "mild", "estimator": "ekf", "metric": "step_latency_median_ms", "mean": 0.08, "n": 1}],
}
TUM = "0.0 0.0 0.0 0.0 0.0 0.0 0.0 1.0\n1.0 1.0 0.0 0.0 0.0 0.0 0.0 1.0\n"


def _write(folder: Path, results: dict, trajectories: dict[str, str]) -> Path:
    (folder / "trajectories").mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(results))
    for name, text in trajectories.items():
        (folder / "trajectories" / name).write_text(text)
    return folder


def test_identical_runs_pass_and_timing_is_ignored(cr, tmp_path, capsys):
    a = _write(tmp_path / "a", RESULTS, {"mild_ekf_seed0.tum": TUM})
    other = copy.deepcopy(RESULTS)
    other["created"] = "2026-02-02T00:00:00"
    other["runs"][0]["metrics"]["total_time_s"] = 9.0
    other["runs"][0]["metrics"]["step_latency_median_ms"] = 7.0
    other["runs"][0]["metrics"]["frontend_ms_median"] = 150.0
    other["summary"][1]["mean"] = 7.0
    b = _write(tmp_path / "b", other, {"mild_ekf_seed0.tum": TUM})
    assert cr.compare(a, b) == []
    assert cr.main(["compare", str(a), str(b)]) == 0
    assert "identical" in capsys.readouterr().out


def test_a_changed_metric_is_named_with_its_run(cr, tmp_path):
    a = _write(tmp_path / "a", RESULTS, {})
    other = copy.deepcopy(RESULTS)
    other["runs"][0]["metrics"]["ate_rmse_m"] = 0.41 + 1e-12   # the last bits count
    b = _write(tmp_path / "b", other, {})
    diffs = cr.compare(a, b)
    assert len(diffs) == 1
    assert "runs{dataset=mild,estimator=ekf,seed=0}.metrics.ate_rmse_m" in diffs[0]
    assert cr.compare(a, b, rtol=1e-9) == []
    assert cr.main(["compare", str(a), str(b)]) == 1


def test_renamed_missing_and_extra_fields_and_runs_are_differences(cr, tmp_path):
    a = _write(tmp_path / "a", RESULTS, {})
    other = copy.deepcopy(RESULTS)
    other["runs"][0]["metrics"]["ate_se3_m"] = other["runs"][0]["metrics"].pop("ate_rmse_m")
    other["runs"].append(copy.deepcopy(other["runs"][0]))
    b = _write(tmp_path / "b", other, {})
    diffs = "\n".join(cr.compare(a, b))
    assert "ate_rmse_m: only in first" in diffs
    assert "ate_se3_m: only in second" in diffs
    assert "runs: 1 items against 2" in diffs


def test_an_added_row_is_reported_once_not_as_a_shift(cr, tmp_path):
    a = _write(tmp_path / "a", RESULTS, {})
    other = copy.deepcopy(RESULTS)
    other["summary"].insert(0, {"dataset": "mild", "estimator": "ekf", "metric": "new_metric_m", "mean": 1.0,
                                "n": 1})
    b = _write(tmp_path / "b", other, {})
    assert cr.compare(a, b) == [
        "results.json.summary{dataset=mild,estimator=ekf,metric=new_metric_m}: only in second"]


def test_trajectory_files_compared_byte_for_byte(cr, tmp_path):
    a = _write(tmp_path / "a", RESULTS, {"x.tum": TUM, "gone.tum": TUM})
    b = _write(tmp_path / "b", RESULTS, {"x.tum": TUM.replace("1.0 1.0 0.0", "1.0 1.0 0.25"), "new.tum": TUM})
    diffs = "\n".join(cr.compare(a, b))
    assert "trajectories/gone.tum: only in first" in diffs
    assert "trajectories/new.tum: only in second" in diffs
    assert "trajectories/x.tum: differs (largest numeric difference 0.25)" in diffs


def test_folders_of_runs_are_compared_by_pipeline(cr, tmp_path):
    _write(tmp_path / "a" / "pose_graph", RESULTS, {})
    _write(tmp_path / "a" / "navigation", RESULTS, {})
    _write(tmp_path / "b" / "pose_graph", RESULTS, {})
    assert cr.compare(tmp_path / "a", tmp_path / "b") == ["navigation: run only in first"]
    assert cr.main(["compare", str(tmp_path / "a"), str(tmp_path / "missing")]) == 2


def test_small_configs_are_valid_pipeline_configs(cr, tmp_path):
    from slamkit.experiments.pipeline import validate_pipeline_config

    assert set(cr.SMALL_CONFIGS) == {"filter_vs_smoother", "pose_graph", "lidar_slam", "navigation"}
    for name, config in cr.SMALL_CONFIGS.items():
        path = tmp_path / f"{name}.yaml"
        path.write_text(json.dumps(config))
        assert validate_pipeline_config(path)["pipeline"] == name
