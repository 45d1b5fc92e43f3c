"""``slamkit bench inertial`` (quick: the first 60 s of KITTI): one case per estimator, each
against real time; the numbers themselves are never asserted."""

from __future__ import annotations

import pytest

from slamkit.data import registry


@pytest.mark.skipif(not registry.is_available(registry.get("kitti-imu-gps")), reason="gtsam wheel Data not found")
def test_quick_bench_cases() -> None:
    from slamkit.bench.inertial import run

    cases = run(quick=True)
    assert [c.name for c in cases] == ["es_ekf_kitti_60s", "isam2_imu_kitti_60s", "fixed_lag_imu_kitti_60s"]
    assert all(c.reference_value == pytest.approx(60.0, abs=0.1) and c.ratio > 0 for c in cases)
    assert [c.goal for c in cases] == [">= 500", ">= 50", None]
    # the filter keeps a pose per IMU event, the smoothers one per GPS fix
    assert cases[0].extra["poses"] > 50 * cases[1].extra["poses"]
