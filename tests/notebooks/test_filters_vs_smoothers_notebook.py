"""The filters-vs-smoothers tutorial runs top to bottom and prints the expected comparison."""

from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "filters_vs_smoothers.ipynb"


def test_filters_vs_smoothers_notebook_runs(run_notebook) -> None:
    text = run_notebook(NOTEBOOK, timeout_s=120)
    # 20 s at 10 Hz: 200 odometry and 201 range-bearing events in a 40-landmark world
    assert "landmark_mild: 200 odometry events, 201 range-bearing events, 40 landmarks" in text
    assert "every estimator within 5 cm RMS: True" in text
    assert "recording written: filters_vs_smoothers.rrd True" in text
    if "isam2" in text and "batch" in text:
        assert "smoothers at least as accurate as EKF-SLAM: True" in text
