"""The lidar SLAM tutorial (raw scans -> ICP -> loop closure -> optimised map -> MCL -> a real
laser log) runs top to bottom in the test suite and prints the numbers it promises."""

from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "lidar_slam.ipynb"


def test_lidar_slam_notebook_runs(run_notebook) -> None:
    text = run_notebook(NOTEBOOK, timeout_s=120)
    # office 20 m x 20 m, seed 1: 455 scans; ICP on scans 10/20 (0.8 m apart): point-to-point
    # 14 iterations and 18 mm off (biased), point-to-line 7 iterations and 0.9 mm off
    assert "455 scans of 360 beams" in text
    assert "point_to_point   14 iterations, error 18.0 mm" in text
    assert "point_to_line     7 iterations, error 0.9 mm" in text
    # 72 keyframes, 39 loop closures; ATE 0.083 (wheels) / 0.016 (ICP) / 0.004 m; IoU 0.963
    # (0.964 when the front-end matched keyframes only and closed loops in two batch rounds)
    assert "72 keyframes, 39 loop closures" in text
    assert "after loop closure 0.004 m" in text
    assert "map IoU 0.963" in text
    assert "robust kernel keeps the map: True" in text
    # global localization: two of three runs lock on within 4 scans, one commits to a twin room
    assert "MCL run 11: not converged in 100 updates" in text
    assert "MCL run 12: converged after 4 scan updates" in text
    assert "MCL run 13: converged after 2 scan updates" in text
    assert "recording written: lidar_slam.rrd True" in text
    # the real-log section: the first 120 s of the Intel log, scored on the 48 relations inside
    from slamkit.data import registry

    if registry.is_available(registry.get("intel-log")):
        assert "Intel, first 120 s: 611 scans, 80 keyframes" in text
        assert "odometry          relation error on 48 relations: 0.016 +- 0.010 m, 0.18 +- 0.13 deg" in text
        assert "constant_velocity relation error on 48 relations: 0.035 +- 0.021 m, 0.32 +- 0.42 deg" in text
    else:
        assert "intel-log is not available here" in text
