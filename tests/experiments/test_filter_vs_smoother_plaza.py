"""filter_vs_smoother on the real range-only recordings Plaza 1 and 2 (issue 12).

Default run: the first 60 s of Plaza 2 through the pipeline, with the ranges calibrated against
the ground truth (every estimator, the report's localisation / SLAM separation, the one-run NEES
label) and with the range scale estimated (``range_scale: estimate``, no ground truth: the
scale each estimator finds, the range gate's counts). Under ``slow``: the whole runs and the
issue's accuracy goals in the estimate mode (``make run``'s)."""

from __future__ import annotations

from pathlib import Path

import pytest

from slamkit.data import registry as datasets
from slamkit.errors import ConfigError
from slamkit.experiments.filter_vs_smoother import assemble, run_monte_carlo
from slamkit.experiments.pipeline import load_config

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(not datasets.is_available(datasets.get("plaza2")),
                                reason="the gtsam wheel's Plaza files are not available")

#: the settings make run uses for Plaza 2 (pipelines/filter_vs_smoother.yaml)
SMOOTHER_OVERRIDES = {"isam2": {"update_every": 10, "relinearize_threshold": 0.1, "relinearize_skip": 10},
                      "fixed_lag": {"relinearize_threshold": 0.1, "relinearize_skip": 10}}
ESTIMATORS = {"ekf": {}, "ukf": {}, "pf": {"n_particles": 500}, "ekf_slam": {}, "batch": {}, "isam2": {},
              "fixed_lag": {"lag_s": 5.0}}


def _run(scenarios):
    config = {"pipeline": "filter_vs_smoother", "seeds": 1, "workers": 1, "scenarios": scenarios,
              "estimators": ESTIMATORS}
    results, specs, choices = run_monte_carlo(config)
    return assemble(config, results, specs, choices)


def _metric(output, scenario, estimator, metric):
    rec = next(r for r in output.runs if (r.dataset, r.estimator) == (scenario, estimator))
    return rec.metrics.get(metric), rec.params


def test_plaza2_first_minute_through_the_pipeline():
    output = _run([{"dataset": "plaza2", "params": {"range_scale": 1.0696, "max_duration_s": 60.0},
                    "estimators": SMOOTHER_OVERRIDES}])
    for name in ESTIMATORS:
        ate, params = _metric(output, "plaza2", name, "ate_rmse_m")
        assert "failed" not in params, params
        # measured on this slice: ekf 0.33, ukf 0.33, pf 0.31, ekf_slam 0.27, batch 0.21,
        # isam2 0.20, fixed_lag 0.18 m
        assert ate < 0.45, (name, ate)
        assert params["setting"] == ("localisation" if name in ("ekf", "ukf", "pf") else "slam")
        assert _metric(output, "plaza2", name, "rejected_ranges")[0] == 0.0  # calibrated: no outliers
    # the scenario's overrides reached iSAM2 and the pipeline's params the rest
    assert _metric(output, "plaza2", "isam2", "ate_rmse_m")[1]["update_every"] == 10
    assert _metric(output, "plaza2", "fixed_lag", "ate_rmse_m")[1]["lag_s"] == 5.0
    # the beacons the SLAM estimators found
    for name in ("ekf_slam", "batch", "isam2", "fixed_lag"):
        assert _metric(output, "plaza2", name, "landmark_rmse_m")[0] < 0.3, name
    report = output.report_md
    metrics = report.split("## Metrics")[1].split("## Consistency")[0]
    localisation, slam = metrics.split("### SLAM (map estimated)")
    assert "### Localisation (map known)" in localisation
    assert "| plaza2 | ekf |" in localisation and "| plaza2 | isam2 |" not in localisation
    assert "| plaza2 | isam2 |" in slam and "| plaza2 | ekf |" not in slam
    assert "1 (one run, no Monte Carlo)" in report


def test_estimated_range_scale_first_minute():
    """The ranges as recorded, their scale declared unknown: every range-only estimator
    estimates it (the ground-truth fit over the whole run is 1.0696) and stays accurate.
    Measured on this slice: s (ATE) pf 1.0708 (0.32 m), ekf_slam 1.0669 (0.24 m), batch and
    isam2 1.0716 (0.20 m), ekf and ukf (s in their state; before, they gated 94 ranges and
    ended 1.40 m off) 1.0700 (0.34 m, 1 range gated). The 5 s
    fixed-lag smoother is not asserted: its s stays at 1.024 and it ends 0.93 m off (an open
    problem: the scale's information leaves with the marginalised ranges)."""
    output = _run([{"dataset": "plaza2", "params": {"range_scale": "estimate", "max_duration_s": 60.0},
                    "estimators": SMOOTHER_OVERRIDES}])
    for name in ("ekf", "ukf", "pf", "ekf_slam", "batch", "isam2"):
        scale, params = _metric(output, "plaza2", name, "range_scale")
        assert "failed" not in params, params
        assert 1.04 < scale < 1.10, (name, scale)
        assert _metric(output, "plaza2", name, "ate_rmse_m")[0] < 0.45, name
    assert "range scale **estimated**" in output.report_md


def test_scenario_estimator_overrides_are_validated(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("pipeline: filter_vs_smoother\nscenarios:\n  - dataset: plaza2\n    estimators:\n"
                    "      isam3: {update_every: 10}\nestimators: {isam2: {}}\n")
    with pytest.raises(ConfigError, match="isam3"):
        load_config(path)
    path.write_text("pipeline: filter_vs_smoother\nscenarios:\n  - dataset: plaza2\n    estimators:\n"
                    "      isam2: {update_evry: 10}\nestimators: {isam2: {}}\n")
    with pytest.raises(ConfigError, match="update_evry"):
        load_config(path)
    assert load_config(ROOT / "pipelines" / "filter_vs_smoother.yaml")["scenarios"][2]["dataset"] == "plaza2"


@pytest.mark.slow
def test_plaza_goals():
    """The issue's goals on the whole runs, the range scale estimated (no ground truth; measured
    Plaza 2: iSAM2 0.245 m, s 1.0669 (ground-truth fit 1.0696) vs EKF-SLAM 0.523 m, s 1.0656;
    Plaza 1: iSAM2 0.259 m, s 1.0658 (fit 1.0694) vs EKF-SLAM 0.396 m, s 1.0649, 1.5x: the 2x
    goal is asserted on Plaza 2 only, as before; beacons within 0.21 m RMS after alignment)."""
    params = {"range_scale": "estimate"}
    output = _run([{"dataset": "plaza1", "params": params, "estimators": SMOOTHER_OVERRIDES},
                   {"dataset": "plaza2", "params": params, "estimators": SMOOTHER_OVERRIDES}])
    for scenario in ("plaza1", "plaza2"):
        isam2 = _metric(output, scenario, "isam2", "ate_rmse_m")[0]
        assert isam2 < 0.5, (scenario, isam2)
        for name in ("batch", "isam2"):
            assert _metric(output, scenario, name, "range_scale")[0] == pytest.approx(1.0695, abs=0.01)
        for name in ("ekf_slam", "batch", "isam2"):
            assert _metric(output, scenario, name, "landmark_rmse_m")[0] < 0.25, (scenario, name)
        # the localisation filters with s in their state (measured: ekf / ukf 0.316 / 0.316 m on
        # Plaza 1, 0.424 / 0.424 m on Plaza 2, s 1.070 / 1.069; 3.8 m when they took the ranges raw)
        for name in ("ekf", "ukf"):
            assert _metric(output, scenario, name, "ate_rmse_m")[0] < 0.5, (scenario, name)
            assert _metric(output, scenario, name, "range_scale")[0] == pytest.approx(1.0695, abs=0.01)
    # Plaza 2: iSAM2 at least twice as accurate as EKF-SLAM (on Plaza 1 it is 1.3x: not claimed)
    assert 2.0 * _metric(output, "plaza2", "isam2", "ate_rmse_m")[0] <= _metric(output, "plaza2", "ekf_slam",
                                                                                 "ate_rmse_m")[0]
