"""The filters-vs-smoothers tutorial runs top to bottom and prints the expected comparison."""

import re
from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "filters_vs_smoothers.ipynb"
ESTIMATORS = ("ekf", "ukf", "pf", "ekf_slam", "isam2", "batch")


def test_filters_vs_smoothers_notebook_runs(run_notebook) -> None:
    text = run_notebook(NOTEBOOK, timeout_s=120)
    # 20 s at 10 Hz: 200 odometry and 201 range-bearing events in a 40-landmark world, exact by
    # construction (the seeded simulator's rates and landmark count)
    counts = re.search(r"landmark_mild: (\d+) odometry events, (\d+) range-bearing events, (\d+) landmarks", text)
    assert tuple(map(int, counts.groups())) == (200, 201, 40)
    # the table's first column, ate_rmse_m, of every estimator that ran (isam2 and batch need GTSAM)
    ate = {name: float(v) for name, v in re.findall(rf"^({'|'.join(ESTIMATORS)})\s+([0-9.e+-]+)\s", text, re.M)}
    assert {"ekf", "ukf", "pf", "ekf_slam"} <= set(ate)
    # measured over perturbations 0-5 (start_offset, range_jitter 1e-6 m) of the sequence: every
    # estimator 0.0078-0.0091 m. Band 4-15 mm (the notebook's claim is 5 cm), while odometry
    # alone (an estimator that ignores the landmarks) is 0.34 m off
    for name, v in ate.items():
        assert 0.004 < v < 0.015, (name, v)
    assert "recording written: filters_vs_smoothers.rrd True" in text
    if {"isam2", "batch"} <= set(ate):
        # perturbations 0-5: iSAM2 and batch 0.14-0.21 % apart (the same MAP estimate; iSAM2
        # relinearises lazily); band 1 %. Smoothers ahead of EKF-SLAM in each, by 13-14 %
        # (0.0078-0.0080 m against 0.0088-0.0092 m)
        (apart_pct,) = map(float, re.search(r"iSAM2 vs batch ATE: ([0-9.]+)% apart", text).groups())
        assert apart_pct < 1.0
        assert abs(ate["isam2"] - ate["batch"]) / ate["batch"] < 0.01
        assert max(ate["batch"], ate["isam2"]) <= ate["ekf_slam"]
