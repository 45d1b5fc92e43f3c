"""The navigation pipeline: config validation and the results folder of a short run."""

from __future__ import annotations

import json

import pytest

from slamkit.errors import ConfigError
from slamkit.experiments.pipeline import check_pipeline
from slamkit.experiments.navigation import _variants
from slamkit.experiments.pipeline import run_pipeline, validate_pipeline_config


def test_unknown_stack_keys_are_config_errors():
    with pytest.raises(ConfigError, match=r"variants\.nominal\.navigation: unknown parameter\(s\) \['particles'\]"):
        _variants({"navigation": {"particles": 10}})
    with pytest.raises(ConfigError, match=r"variants\.x\.navigation: NavigationConfig\.uncertainty"):
        _variants({"variants": [{"name": "x", "navigation": {"uncertainty": "maybe"}}]})
    nav = {"mcl": {"n_min": 100, "n_max": 100}, "controller": "rollout"}
    (name, cfg, ep), = _variants({"navigation": nav, "episode": {"max_time_s": 5.0}})
    assert (name, cfg.mcl.n_max, cfg.controller, ep.max_time_s) == ("nominal", 100, "rollout", 5.0)


def test_the_stack_config_nests_its_sections_and_names_moved_keys(tmp_path):
    # issue 30: planning, yielding, safety, goal and recovery are sections over their defaults
    (_, cfg, _), = _variants({"navigation": {"yielding": {"hedge": 0.3}, "safety": {"rest_check_s": 2.0}}})
    assert (cfg.yielding.hedge, cfg.yielding.reversed_hedge, cfg.safety.rest_check_s) == (0.3, 0.3, 2.0)
    with pytest.raises(ConfigError, match=r"moved into a section: yield_hedge -> yielding\.hedge"):
        _variants({"navigation": {"yield_hedge": 0.3}})
    with pytest.raises(ConfigError, match=r"navigation\.yielding: unknown parameter\(s\) \['hegde'\]"):
        _variants({"navigation": {"yielding": {"hegde": 0.3}}})
    with pytest.raises(ConfigError, match=r"navigation\.yielding: expected a mapping"):
        _variants({"navigation": {"yielding": 0.3}})
    with pytest.raises(ConfigError, match=r"YieldingConfig\.hedge must be in \[0, 1\]"):
        _variants({"variants": [{"name": "x", "navigation": {"yielding": {"hedge": 1.5}}}]})
    # refused by the pipeline's validation, before anything runs
    path = tmp_path / "c.yaml"
    path.write_text("pipeline: navigation\nnavigation:\n  planning: {path_margn_m: 0.1}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml:3: navigation\.planning\.path_margn_m: unknown key "
                                          r"\(did you mean 'path_margin_m'\?\)"):
        validate_pipeline_config(path)
    path.write_text("pipeline: navigation\nvariants:\n  - name: x\n    navigation: {yield_hedge: 0.3}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml:4: variants\.0\.navigation\.yield_hedge: moved into a section: "
                                          r"yield_hedge -> yielding\.hedge"):
        validate_pipeline_config(path)


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
#: (yielding.reversed_hedge 0.3): office 0.967 / 0 / 0, warehouse 0.90 / 0 / 2, Willow 0.90 / 0 / 1
#: (mean final error 1.70 / 1.79 / 1.25 cm); its failures that were not collisions were MCL
#: bias at the goal (office 27, warehouse 7, Willow 8: stopped 3.0-3.3 cm off) and Willow 13
#: stuck in recoveries. With the signed likelihood field, the roughening floor and the recovery
#: heading for a path point it can drive to, alone: office 0.967 / 0 / 1, warehouse 0.967 / 0 / 1,
#: Willow 1.0 / 0 / 0. With yielding choosing where it waits, alone: 0.967 / 0 / 0, 0.90 / 0 / 1,
#: 0.90 / 0 / 1. Both (2026-11-25): office 1.0 / 0 / 0, warehouse 0.967 / 0 / 1 (seed 24),
#: Willow 0.967 / 0 / 0 (seed 13 at the 90 s limit, 7.3 cm short); final error over the
#: successes mean 0.98 / 0.98 / 1.06 cm, max 1.46 / 1.35 / 1.60 cm; +1.5 / +1.2 / +0.9 s and
#: +0.8 / +0.7 / +0.3 m against the hedge alone on the seeds both reach. With a track's span
#: starting again once the track leaves its line (TrackerConfig.span_restart_m; warehouse 24's
#: track swapped lanes where two shuttlers met and kept the old lane's span, 2026-11-25): office
#: 1.0 / 0 / 0, warehouse 1.0 / 0 / 0, Willow 1.0 / 0 / 0 (seed 13 reached in 76.8 s); final error
#: mean 0.99 / 0.95 / 1.05 cm, max 1.46 / 1.35 / 1.60 cm; -0.3 / +0.2 / +0.0 s on the seeds both reach.
#: With issue 33's defaults (precise perception, the ramped evasion, standing tracks that may set
#: off; 2026-12-07, one run per seed): office 1.0 / 0 / 0, warehouse 1.0 / 0 / 0, Willow 0.967 / 0 / 0
#: (seed 16 at the 90 s limit); final error mean 0.75 / 0.81 / 0.75 cm, max 1.32 / 1.43 / 1.48 cm.
#: With the detour round lanes (detour_after_s 10, 2026-12-07): the same outcomes run for run.
MEASURED = (("office", 0.99, 0, 0), ("warehouse", 0.99, 0, 0), ("willow", 0.96, 0, 0))
#: (mean, max) final position error over the successes per world, every world (measured above)
MEASURED_FINAL_ERROR_M = (0.0125, 0.02)
#: over the 90 runs: at least 89 successes and no moving collision (main before the hedge: 81 and
#: 6; with it 83 and 3; before span_restart_m 88 and 1; then 90 and 0 until issue 33's defaults),
#: so a bound's slack cannot hide a loss elsewhere
MEASURED_ALL_WORLDS = (89, 0)
#: the issue's goals: success >= 95 %, no static collision, moving collisions < 2 % of the runs
GOALS = (0.95, 0, 0.02)


@pytest.fixture(scope="module")
def navigation_30_seeds(tmp_path_factory):
    import yaml
    from pathlib import Path

    config = yaml.safe_load((Path(__file__).resolve().parents[2] / "pipelines" / "navigation.yaml").read_text())
    config["record"] = False
    # the figures below are issue 14's development seeds 0-29; the pipeline's evaluation blocks
    # (issue 33) are measured on their own
    config["scenarios"]["seeds"] = {"start": 0, "count": 30}
    config["scenarios"].pop("evaluation", None)
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
        final = [m["final_position_error_m"] for m in runs if m["success"]]
        assert np.mean(final) <= MEASURED_FINAL_ERROR_M[0] and np.max(final) <= MEASURED_FINAL_ERROR_M[1]
    every = [m for runs in navigation_30_seeds.values() for m in runs]
    min_successes, max_moving_all = MEASURED_ALL_WORLDS
    assert sum(m["success"] for m in every) >= min_successes
    assert sum(m["collision_moving"] for m in every) <= max_moving_all


@pytest.mark.slow
def test_navigation_goals_30_seeds_per_world(navigation_30_seeds):
    import numpy as np

    min_success, max_static, max_moving_rate = GOALS
    for world, runs in navigation_30_seeds.items():
        assert np.mean([m["success"] for m in runs]) >= min_success
        assert sum(m["collision_static"] for m in runs) <= max_static
        assert np.mean([m["collision_moving"] for m in runs]) < max_moving_rate


#: issue 33: pipelines/navigation.yaml's evaluation blocks (seeds 5000-5089 per world, never used
#: while changing the code), measured 2026-12-07 with issue 33's defaults (precise perception, the
#: ramped evasion, standing tracks that may set off; the switch decided before this run: at least
#: the old defaults' 250 successes, no static and at most 9 moving collisions): (world, block) ->
#: (successes of 30, static, moving collisions, timeouts). Office 30/0/0/0, 30/0/0/0, 27/0/1/2;
#: warehouse 30/0/0/0, 30/0/0/0, 29/0/1/0; Willow 29/0/0/1, 29/0/0/1, 27/0/2/1: 261/270
#: (0.967 [0.938, 0.982] Wilson), 0 static, 4 moving (0.015 [0.006, 0.037]), 5 timeouts
#: (0.019 [0.008, 0.043]). Paired with the old defaults on the same seeds: 14 successes gained,
#: 3 lost (sign test p 0.013); 15 moving hits removed, none new.
#: History: the old defaults (2026-12-06, 9c3d558) office 30/0/0/0, 29/0/1/0, 25/0/5/0; warehouse
#: 28/0/2/0 x 3; Willow 28/0/2/0, 28/0/2/0, 26/0/3/1: 250/270, 19 moving, 1 timeout. Before that
#: the blocks were 1000-1089 (2026-11-28 at 8713452: 255/270, 0 static, 12 moving, 3 timeouts)
#: until stops 38-39 measured them repeatedly while choosing designs, which made them development
#: seeds; stops 45-47 ran three pre-fixed comparisons on 5000-5089 (none looked at). The goals
#: (>= 95% per block, moving < 2%): moving met, two blocks at 27/30; these are regression bounds.
#: Then (2026-12-07, the gate fixed before the run: >= 262 successes, no static, <= 5 moving hits)
#: the detour round lanes after 10 s without progress (GlobalPlanningConfig.detour_after_s),
#: paired with the above in the same run (which reproduced it run for run): office 30/0/0/0,
#: 30/0/0/0, 27/0/1/2; warehouse 30/0/0/0 x 3; Willow 29/0/0/1, 29/0/0/1, 28/0/1/1: 263/270
#: (0.974 [0.947, 0.987]), 0 static, 2 moving (0.007 [0.002, 0.027]), 5 timeouts; 2 successes
#: gained (warehouse 5064, Willow 5068, both moving hits before), none lost.
MEASURED_EVALUATION = {
    ("office", "eval1"): (30, 0, 0, 0), ("office", "eval2"): (30, 0, 0, 0), ("office", "eval3"): (27, 0, 1, 2),
    ("warehouse", "eval1"): (30, 0, 0, 0), ("warehouse", "eval2"): (30, 0, 0, 0),
    ("warehouse", "eval3"): (30, 0, 0, 0), ("willow", "eval1"): (29, 0, 0, 1), ("willow", "eval2"): (29, 0, 0, 1),
    ("willow", "eval3"): (28, 0, 1, 1),
}
#: over the 270: at least 263 successes, at most 2 moving collisions (a bound's slack per block
#: cannot hide a loss elsewhere)
MEASURED_EVALUATION_ALL = (263, 2)


@pytest.mark.slow
def test_navigation_evaluation_blocks(tmp_path):
    """The shipped pipeline's evaluation blocks (270 runs, 14 min on one core) against the
    measured figures: per world and block no fewer successes, no more collisions or timeouts."""
    import yaml
    from pathlib import Path

    config = yaml.safe_load((Path(__file__).resolve().parents[2] / "pipelines" / "navigation.yaml").read_text())
    config["record"] = False
    assert config["scenarios"]["evaluation"] == {"start": 5000, "blocks": 3, "block_size": 30}
    res = run_pipeline(config, tmp_path / "out", progress=False).results
    rows = {(r["world"], r["block"]): r for r in res["benchmark"]["rows"]}
    for key, (successes, static, moving, timeouts) in MEASURED_EVALUATION.items():
        r = rows[key]
        assert r["episodes"] == 30
        assert r["success_rate"]["events"] >= successes
        assert r["collision_static_rate"]["events"] <= static
        assert r["collision_moving_rate"]["events"] <= moving
        assert r["timeout_rate"]["events"] <= timeouts
    pooled = rows["all worlds", "eval (all)"]
    assert pooled["success_rate"]["events"] >= MEASURED_EVALUATION_ALL[0]
    assert pooled["collision_moving_rate"]["events"] <= MEASURED_EVALUATION_ALL[1]


#: issue 33's second traffic setting, pipelines/navigation_social.yaml (social-force people,
#: reversing forklifts), first evaluation block (seeds 5000-5029 per world), measured once
#: 2026-12-07 with issue 33's defaults: (world -> successes of 30, static, moving collisions,
#: timeouts). Office 30/0/0/0, warehouse 29/0/0/1, Willow 29/0/0/1: 88/90 (0.978 [0.923, 0.994]
#: Wilson), 0 moving (0.000 [0.000, 0.041]), 2 timeouts (a slow person walking ahead is followed,
#: not overtaken; NavigationConfig.standing_growth_mps). History: the old defaults (2026-12-06,
#: 9c3d558) 30/0/0/0 in every world; the precise perception and ramped evasion without the
#: standing growth 30/0/0/0, 27/0/3/0, 28/0/1/1; on 1000-1029 (2026-11-28, 2ae0f36) 27/0/3/0,
#: 30/0/0/0, 28/0/2/0. One block of 30 per world: regression bounds, not a claim.
MEASURED_SOCIAL_FORCE_EVAL1 = {"office": (30, 0, 0, 0), "warehouse": (29, 0, 0, 1), "willow": (29, 0, 0, 1)}


@pytest.mark.slow
def test_navigation_social_force_first_evaluation_block(tmp_path):
    """pipelines/navigation_social.yaml on its first evaluation block (90 runs, 5 min on one core)
    against the measured figures."""
    import yaml
    from pathlib import Path

    config = yaml.safe_load((Path(__file__).resolve().parents[2] / "pipelines" / "navigation_social.yaml").read_text())
    config["record"] = False
    assert config["scenarios"]["agents"] == "social_force"
    config["scenarios"]["seeds"] = [0]
    assert config["scenarios"]["evaluation"] == {"start": 5000, "blocks": 3, "block_size": 30}
    config["scenarios"]["evaluation"] = {"start": 5000, "blocks": 1, "block_size": 30}
    res = run_pipeline(config, tmp_path / "out", progress=False).results
    rows = {(r["world"], r["block"]): r for r in res["benchmark"]["rows"]}
    for world, (successes, static, moving, timeouts) in MEASURED_SOCIAL_FORCE_EVAL1.items():
        r = rows[world, "eval1"]
        assert r["episodes"] == 30
        assert r["success_rate"]["events"] >= successes
        assert r["collision_static_rate"]["events"] <= static
        assert r["collision_moving_rate"]["events"] <= moving
        assert r["timeout_rate"]["events"] <= timeouts
