"""CARMEN laser logs: exact values from the benchmark's files, compression, malformed lines."""

from __future__ import annotations

import bz2
import gzip

import numpy as np
import pytest

from slamkit.data.formats.carmen import read_carmen
from slamkit.data.formats.rosbag import read_bag, write_bag
from slamkit.data.sequence import Odometry, Scan
from slamkit.errors import DataError


def _log(shared_datasets, name):
    return read_carmen(shared_datasets / "lidar_2d" / f"{name}.clf.bz2")


def test_message_counts_of_the_four_logs(shared_datasets) -> None:
    # MANIFEST counts: intel 13,631 FLASER + 26,915 ODOM; fr079 4,934 + 8,951; mit-csail 1,988 FLASER;
    # fr-clinic 6,917 ROBOTLASER1
    assert dict(_log(shared_datasets, "intel").counts) == {"PARAM": 2, "ODOM": 26915, "FLASER": 13631}
    fr079 = _log(shared_datasets, "fr079")
    assert (fr079.counts["FLASER"], fr079.counts["ODOM"], fr079.counts["PARAM"]) == (4934, 8951, 187)
    assert dict(_log(shared_datasets, "mit-csail").counts) == {"FLASER": 1988}
    clinic = _log(shared_datasets, "fr-clinic_robotlaser")
    assert dict(clinic.counts) == {"ROBOTLASER1": 6917}
    assert isinstance(clinic.front.angles_rad, tuple) and len(clinic.front.ranges_m) == 6917


def test_first_intel_scan_exact_values(shared_datasets) -> None:
    laser = _log(shared_datasets, "intel").front
    assert laser.max_range_m == 81.83  # the largest reading: Intel's "no return"
    assert laser.ranges_m.shape == (13631, 180) and laser.ranges_m.dtype == np.float32
    assert laser.stamps_s[0] == 976052857.33753
    assert laser.ranges_m[0, 0] == np.float32(1.07) and laser.ranges_m[0, -1] == np.float32(1.05)
    np.testing.assert_array_equal(laser.world_xytheta_robot[0], [0.0, 0.0, -0.002458])
    assert laser.angles_rad[0] == pytest.approx(-np.pi / 2, abs=1e-7) and laser.angles_rad[-1] == pytest.approx(np.pi / 2, abs=1e-6)
    assert np.isnan(laser.ranges_m).mean() == pytest.approx(0.0278, abs=1e-4)
    fr079 = _log(shared_datasets, "fr079").front
    assert fr079.max_range_m == 80.99  # PARAM robot_front_laser_max


def test_plain_gz_and_bz2_give_the_same_log(shared_datasets, tmp_path) -> None:
    text = bz2.decompress((shared_datasets / "lidar_2d" / "mit-csail.clf.bz2").read_bytes())
    (tmp_path / "m.clf").write_bytes(text)
    (tmp_path / "m.clf.gz").write_bytes(gzip.compress(text))
    logs = [read_carmen(p) for p in (tmp_path / "m.clf", tmp_path / "m.clf.gz",
                                     shared_datasets / "lidar_2d" / "mit-csail.clf.bz2")]
    for log in logs[1:]:
        np.testing.assert_array_equal(log.front.ranges_m, logs[0].front.ranges_m)
        np.testing.assert_array_equal(log.front.stamps_s, logs[0].front.stamps_s)


def test_malformed_lines_name_file_and_line(tmp_path) -> None:
    good = "FLASER 3 1.0 2.0 3.0 0 0 0 0 0 0 1.5 host 1.5\n"
    cases = {
        "short": ("# c\n" + good + "FLASER 3 1.0 2.0 0 0 0 0 0 0 2.5 host 2.5\n", r"short.clf:3: FLASER: 3 readings announced, 2 present"),
        "word": (good + "ODOM 1 x 0 0 0 0 2.0 host 2.0\n", r"word.clf:2: ODOM: field 3 is 'x', expected a number"),
        "digits": (good + "ODOM 1 \u0663 0 0 0 0 2.0 host 2.0\n", r"digits.clf:2: not an ASCII CARMEN log"),
        "ff": (good + "\x0c# form feed is not a line break\nODOM 1 2\n", r"ff.clf:3: ODOM: too few fields"),
    }
    for name, (text, message) in cases.items():
        path = tmp_path / f"{name}.clf"
        path.write_text(text)
        with pytest.raises(DataError, match=message):
            read_carmen(path)


@pytest.mark.slow
def test_intel_converts_to_a_ros2_bag_and_back_identically(shared_datasets, tmp_path) -> None:
    # a bag holds its messages in time order: what `slamkit data convert` writes is the stamp order
    seq = _log(shared_datasets, "intel").to_sequence(order="stamp")
    assert len(seq.of_type(Scan)) == 13631 and len(seq.of_type(Odometry)) == 13630
    write_bag(tmp_path / "intel", seq)
    back = read_bag(tmp_path / "intel", name=seq.name)
    assert [type(e) for e in back] == [type(e) for e in seq]
    for a, b in zip(seq, back):
        for f in a.__dataclass_fields__:
            assert np.array_equal(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)), equal_nan=True), (a, f)


def test_intel_in_log_order_is_the_order_the_scans_were_taken(shared_datasets) -> None:
    """Intel's ipc stamps are late in bursts: 631 scans are stamped before their predecessor in the
    log (by up to 0.9 s). The odometry each line carries says the log order is the physical one:
    in log order the heading never steps more than 15.8 deg from scan to scan, sorted by stamp it
    steps more than 20 deg 88 times (late scans interleave with later ones). Issue 28: a
    lidar-only matcher on the stamp order was on a knife edge (0.026 or 0.999 m)."""
    log = _log(shared_datasets, "intel")
    in_log, by_stamp = log.to_sequence(), log.to_sequence(order="stamp")
    assert in_log.metadata["event_order"] == "log" and by_stamp.metadata["event_order"] == "stamp"
    scans_log, scans_stamp = in_log.of_type(Scan), by_stamp.of_type(Scan)
    assert len(scans_log) == len(scans_stamp) == 13631
    assert sorted(s.stamp_s for s in scans_log) == [s.stamp_s for s in scans_stamp]
    stamps = np.array([s.stamp_s for s in scans_log])
    assert int(np.sum(np.diff(stamps) < 0)) == 631 and float(np.max(-np.diff(stamps))) == pytest.approx(0.897, abs=1e-3)

    def heading_steps_deg(seq):
        return np.rad2deg(np.abs([o.omega_radps * o.dt_s for o in seq.of_type(Odometry)]))

    assert heading_steps_deg(in_log).max() == pytest.approx(15.8, abs=0.05)
    assert int(np.sum(heading_steps_deg(by_stamp) > 20.0)) == 88
    # every odometry event goes right before the scan it ends at, with a positive dt: the
    # measured one, or the median scan period where the next scan's stamp is late
    events = in_log.events
    odo = [k for k, e in enumerate(events) if isinstance(e, Odometry)]
    assert all(isinstance(events[k + 1], Scan) and events[k + 1].stamp_s == events[k].stamp_s for k in odo)
    dts = np.array([events[k].dt_s for k in odo])
    period = np.median(np.diff(stamps)[np.diff(stamps) > 0])
    late = np.diff(stamps) < 0
    assert np.all(dts > 0) and np.all(dts[late] == period) and np.array_equal(dts[~late], np.diff(stamps)[~late])
