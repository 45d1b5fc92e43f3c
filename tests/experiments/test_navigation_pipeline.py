"""The navigation pipeline: config validation and the results folder of a short run."""

from __future__ import annotations

import json

import pytest

from slamkit.errors import ConfigError
from slamkit.experiments.config_models import check_pipeline
from slamkit.experiments.navigation import _variants
from slamkit.experiments.pipeline import run_pipeline


def test_unknown_stack_keys_are_config_errors():
    with pytest.raises(ConfigError, match="unknown keys"):
        _variants({"navigation": {"particles": 10}})
    with pytest.raises(ConfigError, match="uncertainty"):
        _variants({"variants": [{"name": "x", "navigation": {"uncertainty": "maybe"}}]})
    nav = {"mcl": {"n_min": 100, "n_max": 100}, "controller": "rollout"}
    (name, cfg, ep), = _variants({"navigation": nav, "episode": {"max_time_s": 5.0}})
    assert (name, cfg.mcl.n_max, cfg.controller, ep.max_time_s) == ("nominal", 100, "rollout", 5.0)


def test_a_short_run_writes_the_results_folder(tmp_path):
    config = {"pipeline": "navigation", "name": "nav_test",
              "scenarios": {"worlds": ["office"], "seeds": [1], "n_obstacles": 1},
              "episode": {"max_time_s": 3.0}, "variants": [{"name": "fixed"}], "record": False}
    check_pipeline(config)
    res = run_pipeline(config, tmp_path / "out", progress=False).results
    assert res["pipeline"] == "navigation"
    (run,) = res["runs"]
    assert (run["dataset"], run["estimator"], run["seed"]) == ("office", "fixed", 1)
    m = run["metrics"]
    # 3 s is too short to arrive; nothing may be hit on the way
    assert m["success"] == 0.0 and m["collision_static"] == 0.0 and m["collision_moving"] == 0.0
    assert m["path_length_m"] > 0.5 and m["localisation_error_max_m"] < 0.1
    for layer in ("localisation", "perception", "global_planner", "local_planner"):
        assert m[f"{layer}_median_ms"] > 0 and m[f"{layer}_p99_ms"] >= m[f"{layer}_median_ms"]
    assert (tmp_path / "out" / "report.md").is_file() and (tmp_path / "out" / "plots" / "trajectory.png").is_file()
    assert json.loads((tmp_path / "out" / "results.json").read_text())["summary"]
