"""filter_vs_smoother on the real range-only recordings Plaza 1 and 2 (issue 12).

Default run: the first 60 s of Plaza 2 through the pipeline (every estimator, the report's
localisation / SLAM separation, the range gate's counts, the one-run NEES label). Under
``slow``: the whole runs and the issue's accuracy goals."""

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


def test_raw_ranges_are_gated_and_counted():
    """Without the calibration half the ranges lie > 2 m from the truth's prediction: the
    localisation filters' 3 m gate rejects the same kind of range in each (counted, not hidden)."""
    output = _run([{"dataset": "plaza2", "params": {"max_duration_s": 60.0}, "estimators": SMOOTHER_OVERRIDES}])
    for name in ("ekf", "ukf", "pf"):
        rejected, _ = _metric(output, "plaza2", name, "rejected_ranges")
        assert rejected > 0, name


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
    """The issue's goals on the whole runs (measured: Plaza 2 iSAM2 0.238 m vs EKF-SLAM 0.514 m,
    Plaza 1 iSAM2 0.251 m vs EKF-SLAM 0.327 m; the beacons of EKF-SLAM, batch and iSAM2 within
    0.07 m RMS after alignment; the 5 s fixed-lag smoother re-initialises Plaza 1's beacons (the
    vehicle needs ~10 s for a 10 m baseline) and ends 0.37 m off there, not asserted)."""
    output = _run([{"dataset": "plaza1", "params": {"range_scale": 1.0694}, "estimators": SMOOTHER_OVERRIDES},
                   {"dataset": "plaza2", "params": {"range_scale": 1.0696}, "estimators": SMOOTHER_OVERRIDES}])
    for scenario in ("plaza1", "plaza2"):
        isam2 = _metric(output, scenario, "isam2", "ate_rmse_m")[0]
        assert isam2 < 0.5, (scenario, isam2)
        for name in ("ekf_slam", "batch", "isam2"):
            assert _metric(output, scenario, name, "landmark_rmse_m")[0] < 0.15, (scenario, name)
    # Plaza 2: iSAM2 at least twice as accurate as EKF-SLAM (on Plaza 1 it is 1.3x: not claimed)
    assert 2.0 * _metric(output, "plaza2", "isam2", "ate_rmse_m")[0] <= _metric(output, "plaza2", "ekf_slam",
                                                                                 "ate_rmse_m")[0]
