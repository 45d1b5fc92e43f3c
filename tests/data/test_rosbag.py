"""ROS 1 / ROS 2 bags through rosbags: real bags written and read back, exact values stated."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slamkit.data.formats.rosbag import BagTopics, lla_to_local, local_to_lla, read_bag, write_bag
from slamkit.data.odometry import arc_increments, odometry_from_poses
from slamkit.data.sequence import Gps, Imu, Odometry, RangeBearing, Scan, Sequence, beam_angles_rad
from slamkit.errors import DataError, OutputError
from slamkit.models.diff_drive import motion

ORIGIN = (49.0, 8.4, 110.0)


def _sequence() -> Sequence:
    angles = beam_angles_rad(-math.pi / 2, math.pi / 180, 181)
    stamps = np.round(1070722935.567 + 0.1 * np.arange(21), 3)
    events = []
    for k in range(1, 21):
        t = float(stamps[k])
        events.append(Odometry(t, t - float(stamps[k - 1]), 0.5, 0.05 * k))
        r = np.linspace(0.5, 12.0, 181).astype(np.float32)
        r[5] = np.nan
        events.append(Scan(round(t + 0.013, 3), angles, r, 81.83))
        events.append(Imu(round(t + 0.021, 3), np.array([0.0, 0.0, 0.1]), np.array([0.1, 0.0, 9.81])))
        events.append(Gps(round(t + 0.05, 3), np.array([3.0 * k, -2.0, 0.5]), 0.5))
    events.append(RangeBearing(1070722936.0, np.array([1]), np.array([2.0]), np.array([0.1])))
    return Sequence.from_events("toy", events)


def _assert_same(a: Sequence, b: Sequence, gps_tol_m: float = 0.0) -> None:
    assert [type(e) for e in a] == [type(e) for e in b]
    for x, y in zip(a, b):
        for f in x.__dataclass_fields__:
            u, v = np.asarray(getattr(x, f)), np.asarray(getattr(y, f))
            if isinstance(x, Gps) and f == "world_p_body":
                np.testing.assert_allclose(u, v, atol=gps_tol_m, rtol=0)
            else:
                assert u.dtype == v.dtype or f != "ranges_m"
                assert np.array_equal(u, v, equal_nan=True), (type(x).__name__, f, u, v)


@pytest.mark.parametrize("ros_version, name", [(2, "bag2"), (1, "run.bag")])
def test_write_then_read_gives_the_same_sequence(tmp_path, ros_version, name) -> None:
    seq = _sequence()
    summary = write_bag(tmp_path / name, seq, ros_version=ros_version, gps_origin_lla=ORIGIN)
    # 21 odometry messages: the start pose, then one per event; RangeBearing has no ROS message
    assert summary.messages == {"/odom": 21, "/scan": 20, "/imu": 20, "/fix": 20}
    assert summary.skipped_events == {"RangeBearing": 1}
    back = read_bag(tmp_path / name, name="toy", gps_origin_lla=ORIGIN)
    without_rb = Sequence.from_events("toy", [e for e in seq if not isinstance(e, RangeBearing)])
    _assert_same(without_rb, back, gps_tol_m=1e-8)
    assert back.metadata["odometry_source"] == "twist"
    assert back.of_type(Scan)[0].ranges_m.dtype == np.float32


def test_pose_odometry_is_the_inverse_of_the_exact_arc(tmp_path) -> None:
    seq = _sequence()
    write_bag(tmp_path / "b", seq, gps_origin_lla=ORIGIN)
    back = read_bag(tmp_path / "b", odometry_source="pose", topics=BagTopics(scan=None, imu=None, gps=None))
    odo, ref = back.of_type(Odometry), seq.of_type(Odometry)
    assert len(odo) == 20
    np.testing.assert_allclose([e.v_mps for e in odo], [e.v_mps for e in ref], atol=1e-9)
    np.testing.assert_allclose([e.omega_radps for e in odo], [e.omega_radps for e in ref], atol=1e-9)


def test_arc_increments_worked_example() -> None:
    # a quarter circle of radius 1 from the origin heading +x: arc length pi/2, heading change pi/2
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, math.pi / 2]])
    d, a = arc_increments(poses)
    assert d[0] == pytest.approx(math.pi / 2, abs=1e-12) and a[0] == pytest.approx(math.pi / 2, abs=1e-12)
    back = motion(poses[0], np.array([d[0], a[0]]), 1.0)
    np.testing.assert_allclose(back, poses[1], atol=1e-12)
    with pytest.raises(DataError, match=r"odometry: stamps must increase strictly; pose 2 at 1\.0 s follows 1\.0 s"):
        odometry_from_poses(np.array([0.0, 1.0, 1.0]), np.zeros((3, 3)))


def test_tangent_plane_worked_example() -> None:
    # WGS84 meridian radius at 49 deg N: a (1 - e2) / (1 - e2 sin^2 49)^1.5 = 6371.86 km, so one
    # arc-second of latitude (4.8481e-6 rad) is 30.8916 m of northing
    enu = lla_to_local(np.array([[49.0 + 1 / 3600, 8.4, 110.0]]), ORIGIN)
    assert enu[0, 1] == pytest.approx(30.8916, abs=1e-4) and enu[0, 0] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(local_to_lla(enu, ORIGIN), [[49.0 + 1 / 3600, 8.4, 110.0]], atol=1e-12)


def test_bad_bags_are_data_errors(tmp_path) -> None:
    with pytest.raises(DataError, match="no such bag"):
        read_bag(tmp_path / "missing.bag")
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"#ROSBAG V2.0\nnot really")
    with pytest.raises(DataError, match=r"junk\.bag: cannot open as a ROS bag"):
        read_bag(junk)
    write_bag(tmp_path / "b", _sequence(), gps_origin_lla=ORIGIN)
    with pytest.raises(DataError, match=r"none of the requested topics is in the bag; it has: /fix "
                                        r"\(sensor_msgs/msg/NavSatFix\), /imu"):
        read_bag(tmp_path / "b", topics=BagTopics(scan="/laser", odom="/wheel", imu=None, gps=None))
    with pytest.raises(DataError, match="topic /imu carries sensor_msgs/msg/Imu, expected sensor_msgs/msg/LaserScan"):
        read_bag(tmp_path / "b", topics=BagTopics(scan="/imu"))


def test_never_writes_over_an_existing_path(tmp_path) -> None:
    (tmp_path / "b").mkdir()
    with pytest.raises(OutputError, match="exists; a bag is only written to a new path"):
        write_bag(tmp_path / "b", _sequence())
    assert list((tmp_path / "b").iterdir()) == []


# --- issue 31: impossible values, damaged bags, a database that disagrees with its metadata ---


def _bag_with(path, *, ros_version: int = 2, scan: dict | None = None, twist: tuple[float, float] = (0.5, 0.1)):
    """A bag written with rosbags itself: three odometry messages (the last two with ``twist``
    (v, omega)) and three scans whose fields ``scan`` overrides."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE if ros_version == 2 else Stores.ROS1_NOETIC)
    T = ts.types

    def header(k):
        H = T["std_msgs/msg/Header"]
        stamp = T["builtin_interfaces/msg/Time"](sec=100 + k, nanosec=0)
        return H(seq=0, stamp=stamp, frame_id="f") if "seq" in H.__dataclass_fields__ else H(stamp=stamp, frame_id="f")

    v3 = T["geometry_msgs/msg/Vector3"]
    cov = np.zeros(36)
    fields = dict(angle_min=-1.0, angle_max=1.0, angle_increment=0.5, time_increment=0.0, scan_time=0.0,
                  range_min=0.1, range_max=8.0, ranges=np.array([1, 2, 3, 4, 5], np.float32),
                  intensities=np.zeros(0, np.float32))
    fields.update(scan or {})
    rows = []
    for k in range(3):
        v, w = (0.0, 0.0) if k == 0 else twist
        pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=0.1 * k, y=0.0, z=0.0),
                                           orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
        tw = T["geometry_msgs/msg/Twist"](linear=v3(x=v, y=0.0, z=0.0), angular=v3(x=0.0, y=0.0, z=w))
        rows.append(("/odom", "nav_msgs/msg/Odometry", T["nav_msgs/msg/Odometry"](
            header=header(k), child_frame_id="base_link",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=tw, covariance=cov)), k))
        rows.append(("/scan", "sensor_msgs/msg/LaserScan", T["sensor_msgs/msg/LaserScan"](header=header(k), **fields), k))
    if ros_version == 2:
        from rosbags.rosbag2 import Writer
        writer, serialize = Writer(path, version=9), ts.serialize_cdr
    else:
        from rosbags.rosbag1 import Writer
        writer, serialize = Writer(path), ts.serialize_ros1
    with writer:
        conns = {}
        for topic, msgtype, msg, k in rows:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=ts)
            writer.write(conns[topic], (100 + k) * 10**9, serialize(msg, msgtype))
    return path


@pytest.mark.parametrize("ros_version", [2, 1])
def test_the_test_bag_reads(tmp_path, ros_version) -> None:
    seq = read_bag(_bag_with(tmp_path / ("b.bag" if ros_version == 1 else "b"), ros_version=ros_version),
                   topics=BagTopics(imu=None, gps=None))
    assert len(seq.of_type(Scan)) == 3 and [e.v_mps for e in seq.of_type(Odometry)] == [0.5, 0.5]
    np.testing.assert_array_equal(seq.of_type(Scan)[0].angles_rad, [-1.0, -0.5, 0.0, 0.5, 1.0])


@pytest.mark.parametrize("ros_version", [2, 1])
@pytest.mark.parametrize("scan, twist, expected", [
    ({}, (math.nan, 0.1), r"/odom message 1: twist\.linear\.x is nan"),
    ({}, (0.5, math.inf), r"/odom message 1: twist\.angular\.z is inf"),
    ({"angle_min": math.nan}, (0.5, 0.1), r"/scan message 0: angle_min is nan"),
    ({"angle_increment": math.nan}, (0.5, 0.1), r"/scan message 0: angle_increment is nan"),
    ({"range_max": 0.0}, (0.5, 0.1), r"/scan message 0: range_max is 0\.0; a laser's maximum range must be > 0"),
    ({"range_max": -math.inf}, (0.5, 0.1), r"/scan message 0: range_max is -inf, not a finite number"),
    ({"range_min": -1.0}, (0.5, 0.1), r"/scan message 0: range_min -1\.0 must be >= 0"),
])
def test_impossible_values_are_refused_naming_message_and_field(tmp_path, ros_version, scan, twist, expected) -> None:
    path = _bag_with(tmp_path / ("b.bag" if ros_version == 1 else "b"), ros_version=ros_version, scan=scan,
                     twist=twist)
    with pytest.raises(DataError, match=expected):
        read_bag(path, topics=BagTopics(imu=None, gps=None))


def test_a_corrupt_ros1_bag_is_a_data_error(tmp_path) -> None:
    """Zeroed bytes inside the message records (the header and index still open) stop rosbags
    mid-iteration (before: its ReaderError escaped as an internal error)."""
    good = _bag_with(tmp_path / "good.bag", ros_version=1).read_bytes()
    start = good.index(b"/scan") + 200
    bad = tmp_path / "bad.bag"
    bad.write_bytes(good[:start] + b"\x00" * 300 + good[start + 300:])
    with pytest.raises(DataError, match=r"bad\.bag: cannot read the bag's messages: ReaderError"):
        read_bag(bad, topics=BagTopics(imu=None, gps=None))
    bad.write_bytes(good[:len(good) // 2])  # cut before its index
    with pytest.raises(DataError, match=r"bad\.bag: cannot open as a ROS bag"):
        read_bag(bad, topics=BagTopics(imu=None, gps=None))


def test_a_database_that_disagrees_with_its_metadata_is_refused(tmp_path) -> None:
    """metadata.yaml declares 3 scans; the database's topic was renamed, so no message matches it
    (before: 0 scans, exit 0)."""
    import sqlite3

    path = _bag_with(tmp_path / "b")
    db = sqlite3.connect(path / "b.db3")
    db.execute("update topics set name = '/laser' where name = '/scan'")
    db.commit()
    db.close()
    with pytest.raises(DataError, match=r"topic /scan: the bag declares 3 messages but holds 0"):
        read_bag(path, topics=BagTopics(imu=None, gps=None))
