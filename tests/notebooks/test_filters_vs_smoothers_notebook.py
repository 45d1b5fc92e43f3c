"""The filters-vs-smoothers tutorial runs top to bottom and prints the expected comparison."""

from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "filters_vs_smoothers.ipynb"


def test_filters_vs_smoothers_notebook_runs(run_notebook) -> None:
    nb = run_notebook(NOTEBOOK, timeout_s=120)
    text = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.outputs)
    # 20 s at 10 Hz: 200 odometry and 201 range-bearing events in a 40-landmark world
    assert "landmark_mild: 200 odometry events, 201 range-bearing events, 40 landmarks" in text
    assert "every estimator within 5 cm RMS: True" in text
    assert "recording written: filters_vs_smoothers.rrd True" in text
    if "isam2" in text and "batch" in text:
        assert "smoothers at least as accurate as EKF-SLAM: True" in text
