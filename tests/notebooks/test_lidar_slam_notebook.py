"""The lidar SLAM tutorial (raw scans -> ICP -> loop closure -> optimised map -> MCL) runs top to
bottom in the test suite and prints the numbers it promises."""

from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "lidar_slam.ipynb"


def test_lidar_slam_notebook_runs(run_notebook) -> None:
    nb = run_notebook(NOTEBOOK, timeout_s=120)
    text = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.outputs)
    # office 20 m x 20 m, seed 1: 519 scans; ICP on scans 10/20: point-to-point 7 iterations,
    # point-to-line 5 and about half the error (6.3 mm vs 3.9 mm)
    assert "519 scans of 360 beams" in text
    assert "point_to_point    7 iterations" in text and "point_to_line     5 iterations" in text
    # 75 keyframes, 40 loop closures; ATE 0.096 (wheels) / 0.006 (ICP) / 0.004 m; IoU 0.945
    assert "75 keyframes, 40 loop closures" in text
    assert "after loop closure 0.004 m" in text
    assert "map IoU 0.945" in text
    assert "robust kernel keeps the map: True" in text
    assert "MCL converged after 5 scan updates; particles 2000 -> 500" in text
    assert "recording written: lidar_slam.rrd True" in text
