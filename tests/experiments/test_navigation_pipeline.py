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


#: (world, success rate, static collisions, moving collisions) over 30 seeds of
#: ``pipelines/navigation.yaml`` (2026-11-24). Before yielding, the back-off recovery, acting on
#: the safe stop, the 0.65 m/s cruise cap and the evasion kept off the walls: office 0.867 / 1 /
#: 2, warehouse 0.90 / 0 / 0, Willow 0.70 / 4 / 1. With them: office 0.90 / 0 / 2, warehouse
#: 0.933 / 0 / 1, Willow 0.867 / 0 / 3. With yielding hedged for tracks seen reversing
#: (yield_reversed_hedge 0.3: a shuttler's trailing edge is not trusted to recede at its full
#: speed): office 0.967 / 0 / 0, warehouse 0.90 / 0 / 2, Willow 0.90 / 0 / 1 (mean final error
#: 1.70 / 1.79 / 1.25 cm; +1.5-3 s and +0.14-0.19 m on the seeds both versions reach). Moving
#: collisions 6 -> 3 of 90 and success 81 -> 83 of 90, at the price of warehouse (seed 29 a new
#: moving collision). With yielding choosing where it waits (outside every track's sweep and
#: seen span, backing off along the way it came; 2026-11-25): office 0.967 / 0 / 0, warehouse
#: 0.90 / 0 / 1, Willow 0.90 / 0 / 1 (warehouse 5/29 and Willow 19 no longer hit, warehouse 6 and
#: Willow 10 are; mean final error 1.65 / 1.78 / 1.29 cm; +0.3 / +2.3 / +0.7 s and +0.9 / +1.1 /
#: +0.3 m on the seeds both versions reach). The bounds are the stricter of both per world; the
#: issue's goals are the xfail below.
MEASURED = (("office", 0.96, 0, 0), ("warehouse", 0.90, 0, 1), ("willow", 0.89, 0, 1))
#: over the 90 runs: at least 83 successes and at most 2 moving collisions (before the hedge:
#: 81 and 6; with it, before waiting places: 83 and 3)
MEASURED_ALL_WORLDS = (83, 2)
#: the issue's goals: success >= 95 %, no static collision, moving collisions < 2 % of the runs
GOALS = (0.95, 0, 0.02)


@pytest.fixture(scope="module")
def navigation_30_seeds(tmp_path_factory):
    import yaml
    from pathlib import Path

    config = yaml.safe_load((Path(__file__).resolve().parents[2] / "pipelines" / "navigation.yaml").read_text())
    config["record"] = False
    res = run_pipeline(config, tmp_path_factory.mktemp("nav30") / "out", progress=False).results
    return {world: [r["metrics"] for r in res["runs"] if r["dataset"] == world] for world, *_ in MEASURED}


@pytest.mark.slow
def test_shipped_navigation_pipeline_30_seeds_per_world(navigation_30_seeds):
    """pipelines/navigation.yaml (30 seeds x office, warehouse, Willow) against the measured
    figures (``MEASURED``)."""
    import numpy as np

    for world, min_success, max_static, max_moving in MEASURED:
        runs = navigation_30_seeds[world]
        assert len(runs) == 30
        assert np.mean([m["success"] for m in runs]) >= min_success
        assert sum(m["collision_static"] for m in runs) <= max_static
        assert sum(m["collision_moving"] for m in runs) <= max_moving
        reached = [m["final_position_error_m"] for m in runs if m["reached_by_belief"]]
        assert np.mean(reached) < 0.03
    every = [m for runs in navigation_30_seeds.values() for m in runs]
    min_successes, max_moving_all = MEASURED_ALL_WORLDS
    assert sum(m["success"] for m in every) >= min_successes
    assert sum(m["collision_moving"] for m in every) <= max_moving_all


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="issue 14's goals not reached yet: success 0.967 / 0.90 / 0.90 "
                   "(goal 0.95), moving collisions 0 / 1 / 1 of 30 (goal < 2 %, i.e. 0 of 30)")
def test_navigation_goals_30_seeds_per_world(navigation_30_seeds):
    import numpy as np

    min_success, max_static, max_moving_rate = GOALS
    for world, runs in navigation_30_seeds.items():
        assert np.mean([m["success"] for m in runs]) >= min_success
        assert sum(m["collision_static"] for m in runs) <= max_static
        assert np.mean([m["collision_moving"] for m in runs]) < max_moving_rate
