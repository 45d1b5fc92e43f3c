"""The filter_vs_smoother pipeline end to end, and the issue's claims over >= 20 seeds."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from slamkit.errors import ConfigError
from slamkit.experiments import estimators as registry
from slamkit.experiments.config_models import seed_list
from slamkit.experiments.filter_vs_smoother import (
    assemble,
    estimators_of,
    scenarios_of,
    run_monte_carlo,
)
from slamkit.experiments.pipeline import run_pipeline
from slamkit.viz.pipelines import observer_for

ROOT = Path(__file__).resolve().parents[2]

#: heading noise 0.6 rad/s and a sighting every 2 s: the heading uncertainty between sightings
#: is large enough that the EKF's linearisation makes it overconfident (measured: average NEES
#: about 15 over 20 seeds against a band of [2.02, 4.16])
STRONG = {"preset": "strong", "name": "strong",
          "params": {"duration_s": 20.0, "odometry_sigma_v_mps": 0.1, "odometry_sigma_omega_radps": 0.6,
                     "sensor": {"rate_hz": 0.5, "sigma_range_m": 0.02, "sigma_bearing_rad": 0.01}}}


def _consistency(output, scenario: str, estimator: str) -> dict:
    return next(r for r in output.extra["consistency"]
                if r["dataset"] == scenario and r["estimator"] == estimator)


def _summary(output, scenario: str, estimator: str, metric: str) -> dict:
    return next(s for s in output.summary
                if (s["dataset"], s["estimator"], s["metric"]) == (scenario, estimator, metric))


def test_pipeline_writes_the_documented_folder_and_recording(tmp_path, verify_rrd) -> None:
    config = {"pipeline": "filter_vs_smoother", "name": "fvs_test", "seeds": 3, "workers": 2,
              "scenarios": [{"preset": "mild", "params": {"duration_s": 5.0}}],
              "estimators": {"ekf": {}, "pf_small": {"type": "pf", "n_particles": 200}}}
    result = run_pipeline(config, tmp_path / "out", progress=False, observer_factory=observer_for)
    out = result.out_dir
    data = json.loads((out / "results.json").read_text())
    assert data["pipeline"] == "filter_vs_smoother"
    assert len(data["runs"]) == 2 * 3
    assert {r["seed"] for r in data["runs"]} == {0, 1, 2}
    metrics = set(data["runs"][0]["metrics"])
    assert {"ate_rmse_m", "ate_rot_rmse_rad", "rpe_rmse_m", "nees_mean", "nees_in_band_fraction",
            "nis_mean", "step_latency_median_ms", "step_latency_p99_ms", "total_time_s"} <= metrics
    ate = next(s for s in data["summary"] if s["estimator"] == "ekf" and s["metric"] == "ate_rmse_m")
    assert ate["n"] == 3 and ate["ci95"][0] <= ate["mean"] <= ate["ci95"][1]
    assert {r["estimator"] for r in data["consistency"]} == {"ekf", "pf_small"}
    assert sorted(p.name for p in (out / "plots").iterdir()) == ["ate_rmse.png", "error_mild.png", "nees_mild.png"]
    assert len(list((out / "trajectories").glob("mild_*_seed*.tum"))) == 6
    report = (out / "report.md").read_text()
    assert "| mild | ekf |" in report and "## Consistency" in report
    # every run pairs the two estimators on one seed: one paired row per ranked metric
    ate_pair = next(r for r in data["paired"] if r["metric"] == "ate_rmse_m")
    assert ate_pair["pairs"] == 3 and {ate_pair["treatment"], ate_pair["best"]} == {"ekf", "pf_small"}
    assert ate_pair["mean_difference"] >= 0 and "## Paired differences to the best estimator" in report
    assert yaml.safe_load((out / "config.yaml").read_text())["seeds"] == 3
    entities = verify_rrd(out / "recording.rrd")
    expected = {"/mild/world/ground_truth", "/mild/world/landmarks", "/mild/world/estimate/ekf",
                "/mild/world/estimate/ekf/covariance", "/mild/world/estimate/ekf/pose",
                "/mild/world/estimate/ekf/ellipse", "/mild/world/estimate/ekf/associations",
                "/mild/world/estimate/pf_small/particles", "/mild/plots/error/ekf",
                "/mild/plots/nees/ekf", "/mild/plots/nees/band_lower", "/mild/plots/nees/band_upper"}
    assert expected <= entities, expected - entities


def test_config_errors_name_the_field() -> None:
    with pytest.raises(ConfigError, match=r"scenarios\[0\]: needs exactly one of 'preset', 'dataset' or 'scenario'"):
        scenarios_of([{"preset": "mild", "dataset": "x"}])
    with pytest.raises(ConfigError, match="preset must be one of mild, strong, car3d"):
        scenarios_of([{"preset": "wild"}])
    with pytest.raises(ConfigError, match="unknown estimator 'kalmann'"):
        estimators_of(["kalmann"])
    from slamkit.experiments.pipeline import check_pipeline

    with pytest.raises(ConfigError, match=r"seeds: Input should be greater than or equal to 1 \(got 0\)"):
        check_pipeline({"pipeline": "filter_vs_smoother", "seeds": 0, "scenarios": ["mild"], "estimators": ["ekf"]})
    assert seed_list(check_pipeline({"pipeline": "filter_vs_smoother", "seeds": [3, 7], "scenarios": ["mild"],
                                     "estimators": ["ekf"]}).seeds) == [3, 7]
    assert [c.label for c in estimators_of(["ekf", {"pf": {"n_particles": 10}}])] == ["ekf", "pf"]


def test_a_scenario_may_leave_out_an_estimator_and_override_another() -> None:
    from slamkit.experiments.pipeline import check_pipeline

    config = {"pipeline": "filter_vs_smoother", "estimators": {"ekf": {}, "batch": {}, "isam2": {}},
              "scenarios": ["mild", {"preset": "strong", "estimators": {"batch": False, "isam2": {"update_every": 5}}}]}
    check_pipeline(config)
    mild, strong = scenarios_of(config["scenarios"])
    choices = estimators_of(config["estimators"])
    assert [c.label for c in mild.estimator_choices(choices)] == ["ekf", "batch", "isam2"]
    assert [(c.label, dict(c.params)) for c in strong.estimator_choices(choices)] == [
        ("ekf", {}), ("isam2", {"update_every": 5})]
    with pytest.raises(ConfigError, match=r"scenarios\.1\.ScenarioEntry\.estimators\.batch\.literal\[False\]: "
                                          r"Input should be False"):
        check_pipeline({**config, "scenarios": ["mild", {"preset": "strong", "estimators": {"batch": True}}]})


def test_scenario_files_with_overrides_are_checked_before_running() -> None:
    from slamkit.experiments.pipeline import check_pipeline

    office = str(ROOT / "pipelines" / "scenarios" / "office_tour.yaml")
    base = {"pipeline": "filter_vs_smoother", "estimators": {"fusion_ekf": {"ekf": {"lidar_noise": "measured"}}}}
    check_pipeline({**base, "scenarios": [{"scenario": office, "params": {"wheel_radius_error": 0.03}}]})
    with pytest.raises(ConfigError, match=r"scenarios\.0: .*office_tour\.yaml.*wheel_radius_eror: unknown key"):
        check_pipeline({**base, "scenarios": [{"scenario": office, "params": {"wheel_radius_eror": 0.03}}]})
    with pytest.raises(ConfigError, match=r"scenarios\.0: scenario .*nowhere\.yaml does not exist"):
        check_pipeline({**base, "scenarios": [{"scenario": "nowhere.yaml"}]})
    with pytest.raises(ConfigError, match="needs exactly one of 'preset', 'dataset' or 'scenario'"):
        check_pipeline({**base, "scenarios": [{"scenario": office, "preset": "mild"}]})
    with pytest.raises(ConfigError, match="lidar_noise"):
        check_pipeline({**base, "scenarios": ["mild"], "estimators": {"fusion_ekf": {"ekf": {"lidar_noise": 3}}}})
    (spec,) = scenarios_of([{"scenario": office, "params": {"slip_episodes": 1}}])
    assert (spec.name, spec.simulated, spec.params) == ("office_tour", True, {"slip_episodes": 1})


def test_shipped_fusion_config_is_valid(monkeypatch) -> None:
    from slamkit.experiments.pipeline import load_config

    monkeypatch.chdir(ROOT)
    config = load_config(ROOT / "pipelines" / "filter_vs_smoother_fusion.yaml")
    assert [s.name for s in scenarios_of(config["scenarios"])] == ["office_tour", "warehouse_tour", "office_radius_only"]
    assert {c.type for c in estimators_of(config["estimators"])} == {"dead_reckoning", "fusion_ekf", "fusion_isam2"}


def test_shipped_pipeline_config_is_valid() -> None:
    config = yaml.safe_load((ROOT / "pipelines" / "filter_vs_smoother.yaml").read_text())
    assert config["pipeline"] == "filter_vs_smoother"
    assert len(scenarios_of(config["scenarios"])) >= 2
    assert all(registry.is_available(c.type) or c.type in registry.REGISTRY for c in estimators_of(config["estimators"]))


def test_ekf_nees_inside_its_band_when_mild_and_outside_when_strong() -> None:
    """The issue's consistency claim over 20 seeds: the EKF's Monte-Carlo average NEES stays in
    the chi2(60)/20 95% band [2.02, 4.16] on the mildly nonlinear world and leaves it (above:
    overconfident) when heading noise is large and sightings sparse."""
    config = {"seeds": 20, "workers": 2,
              "scenarios": [{"preset": "mild", "params": {"duration_s": 6.0}}, STRONG],
              "estimators": {"ekf": {}}}
    results, scenarios, choices = run_monte_carlo(config)
    output = assemble(config, results, scenarios, choices)
    mild, strong = _consistency(output, "mild", "ekf"), _consistency(output, "strong", "ekf")
    assert mild["runs"] == strong["runs"] == 20
    assert mild["band95"] == pytest.approx([2.0241, 4.1649], abs=1e-3)
    assert mild["inside_band"] and 2.4 < mild["anees_mean"] < 3.6
    assert mild["steps_in_band_fraction"] > 0.8
    assert not strong["inside_band"] and strong["anees_mean"] > 2 * strong["band95"][1]
    assert "**above: overconfident**" in output.report_md
    # the per-run NEES agrees: mild runs average close to the 3 dof a consistent filter shows
    assert _summary(output, "mild", "ekf", "nees_mean")["mean"] == pytest.approx(3.0, abs=0.6)


@pytest.mark.slow
def test_smoothers_beat_ekf_slam_over_twenty_seeds() -> None:
    """Mean ATE batch <= iSAM2 <= EKF-SLAM over 20 seeds, iSAM2 within 2% of batch.

    Both solve the same MAP problem; batch LM reaches the lower objective on every seed 0-19
    (after raising LM's lambda ceiling: with GTSAM's default 1e5 it gave up on seed 16 at error
    17672 vs 3822), but ATE against the truth is not the objective, so per seed either may
    score lower by a fraction of a percent (measured over seeds 0-19, 30 s: batch 9.69 mm,
    iSAM2 9.68 mm; seed 16: batch 8.84 mm at error 3822, iSAM2 8.60 mm at error 7002).
    "batch <= iSAM2" is therefore asserted within the issue's own 2% tolerance."""
    missing = [n for n in ("batch", "isam2", "ekf_slam") if not registry.is_available(n)]
    if missing:
        pytest.skip(f"estimators not in this installation yet: {missing}")
    config = {"seeds": 20, "workers": 2,
              "scenarios": [{"preset": "mild", "params": {"duration_s": 30.0}}],
              "estimators": {"batch": {}, "isam2": {}, "ekf_slam": {}}}
    results, scenarios, choices = run_monte_carlo(config)
    output = assemble(config, results, scenarios, choices)
    ate = {e: _summary(output, "mild", e, "ate_rmse_m") for e in ("batch", "isam2", "ekf_slam")}
    assert all(a["n"] == 20 for a in ate.values())
    mean = {e: a["mean"] for e, a in ate.items()}
    assert mean["batch"] <= 1.02 * mean["isam2"]
    assert mean["isam2"] <= mean["ekf_slam"]
    assert abs(mean["isam2"] - mean["batch"]) <= 0.02 * mean["batch"]
    # paired on the 20 seeds, EKF-SLAM's ATE excess over the best smoother is significant
    ekf_slam = next(r for r in output.extra["paired"] if r["metric"] == "ate_rmse_m" and r["treatment"] == "ekf_slam")
    assert ekf_slam["pairs"] == 20 and ekf_slam["best"] in ("batch", "isam2")
    assert ekf_slam["ci95"][0] > 0 and ekf_slam["wilcoxon_p"] < 0.05 and ekf_slam["significant"]
    # Not asserted: per seed the two can differ by more than 2% (seed 16 above: 2.8%); the
    # issue's 2% holds for the mean over seeds.


def test_outside_references_stand_beside_the_matching_means() -> None:
    from slamkit.experiments.pipeline import check_pipeline
    from slamkit.experiments.filter_vs_smoother.report import outside_references_markdown

    summary = [{"dataset": "w", "estimator": "ekf", "metric": "final_position_error_m", "mean": 0.006,
                "ci95": [0.005, 0.007], "n": 3},
               {"dataset": "w", "estimator": "dr", "metric": "final_position_error_m", "mean": 1.0,
                "ci95": [0.9, 1.1], "n": 3},
               {"dataset": "v", "estimator": "ekf", "metric": "final_position_error_m", "mean": 9.0,
                "ci95": [8.0, 10.0], "n": 3}]
    ref = {"scenario": "w", "metric": "final_position_error_m", "value": 0.015, "source": "outside: fused",
           "estimators": ["ekf"]}
    text = outside_references_markdown([ref], summary)
    rows = [line for line in text.splitlines() if line.startswith("| w ")]
    assert rows == ["| w | final_position_error_m | outside: fused | 0.015 | ekf | 0.006 | [0.005, 0.007] | 0.4 |"]
    assert outside_references_markdown([{**ref, "scenario": "nowhere"}], summary) == ""
    base = {"pipeline": "filter_vs_smoother", "scenarios": ["mild"], "estimators": ["ekf"]}
    check_pipeline({**base, "outside_references": [ref]})
    with pytest.raises(ConfigError, match="outside_references.0.valu"):
        check_pipeline({**base, "outside_references": [{**{k: v for k, v in ref.items() if k != "value"},
                                                        "valu": 0.015}]})
