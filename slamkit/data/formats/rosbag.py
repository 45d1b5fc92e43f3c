"""ROS 1 and ROS 2 bags <-> slamkit Sequences, through the pure-Python ``rosbags`` library (no
ROS installation needed).

Reading (:func:`read_bag`, ROS 1 ``.bag`` files and ROS 2 bag folders alike) takes the topics
named in :class:`BagTopics` (``None`` skips one):

* ``sensor_msgs/LaserScan`` -> :class:`~slamkit.data.sequence.Scan`: beam k at
  angle_min + k angle_increment; a reading outside [range_min, range_max] or not finite is "no
  return" (NaN, REP 117); ``max_range_m`` = range_max.
* ``nav_msgs/Odometry`` -> :class:`~slamkit.data.sequence.Odometry` (v, omega over the time since
  the previous message); the first message's pose is the Sequence's
  ``initial_world_xytheta_body``. ``odometry_source``: ``"twist"`` takes the message's body-frame twist
  (linear.x, angular.z); ``"pose"`` converts consecutive poses with
  :func:`slamkit.data.odometry.odometry_from_poses`; ``"auto"`` (default) uses the twist unless
  every twist in the topic is zero (many drivers fill only the pose).
* ``tf2_msgs/TFMessage``: with ``tf_odometry=(parent, child)`` (e.g. ``("odom", "base_link")``)
  and no odometry topic, the parent->child transforms are the odometry poses.
* ``sensor_msgs/Imu`` -> :class:`~slamkit.data.sequence.Imu` (angular velocity, linear
  acceleration; orientation is not used).
* ``sensor_msgs/NavSatFix`` -> :class:`~slamkit.data.sequence.Gps`: positions in a local
  east-north frame about the first fix (or ``metadata['gps_origin_lla']``), by the tangent-plane
  approximation with the WGS84 radii of curvature at the origin (error < 1 mm within 1 km);
  ``sigma_m`` = the root of the mean horizontal variance (NaN when the covariance is unknown);
  fixes with status NO_FIX are skipped and counted.

Stamps are the messages' header stamps (the bag's receive time when a header stamp is zero).

A bag reads into a valid Sequence or is refused with a DataError naming the topic, message index
and field: non-finite numbers, a scan's range_max <= 0 or range_min outside [0, range_max), a
damaged bag (rosbags' errors while iterating), and a bag whose storage holds other message counts
than its index or ``metadata.yaml`` declares.

:func:`read_laser_bag` (what ``load_recording`` and a lidar_slam log ``path:`` use) picks the
topics itself: the bag's only LaserScan and Odometry topics unless named, with the laser's
mounting from ``/tf_static``. :func:`bag_info` (``slamkit data info BAG``) lists every topic with
its type, message count and rate.

Writing (:func:`write_bag`, ROS 2 sqlite3 by default, ``ros_version=1`` for a ``.bag``) is the
inverse for Scan, Odometry (a first message at the start pose, then the exact-arc integrated pose
and the twist of every event), Imu and Gps events; RangeBearing and WheelEncoders have no
standard ROS message and are counted as skipped. A bag written from a Sequence whose scans are
evenly spaced, whose ranges are float32 and whose odometry ``dt_s`` equals its stamp spacing
reads back into an identical Sequence (tested on the Intel log). The output path must not exist.
"""

from __future__ import annotations

import math
import os
import shutil
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from slamkit.data.odometry import odometry_from_poses
from slamkit.data.sequence import beam_angles_rad, Gps, Imu, Odometry, RangeBearing, Scan, Sequence, WheelEncoders
from slamkit.errors import DataError, OutputError
from slamkit.geometry import se2
from slamkit.models.diff_drive import motion
from slamkit.paths import check_no_file_above, temporary_sibling

#: WGS84 semi-major axis (m) and first eccentricity squared
WGS84_A_M = 6378137.0
WGS84_E2 = 6.69437999014e-3

MSG_SCAN = "sensor_msgs/msg/LaserScan"
MSG_ODOM = "nav_msgs/msg/Odometry"
MSG_IMU = "sensor_msgs/msg/Imu"
MSG_FIX = "sensor_msgs/msg/NavSatFix"
MSG_TF = "tf2_msgs/msg/TFMessage"


@dataclass(frozen=True)
class BagTopics:
    """Topic of each message kind (``None``: not read / not written)."""

    scan: str | None = "/scan"
    odom: str | None = "/odom"
    imu: str | None = "/imu"
    gps: str | None = "/fix"
    tf: str | None = "/tf"


@dataclass(frozen=True)
class BagWriteSummary:
    path: Path
    messages: dict[str, int]
    skipped_events: dict[str, int]


def _typestore(ros_version: int = 2):
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE if ros_version == 2 else Stores.ROS1_NOETIC)


# --- local tangent plane ---------------------------------------------------------------------


def _radii_m(lat0_rad: float) -> tuple[float, float]:
    """Meridian (north) and prime-vertical (east) radii of curvature of WGS84 at lat0."""
    s2 = math.sin(lat0_rad) ** 2
    w = math.sqrt(1.0 - WGS84_E2 * s2)
    return WGS84_A_M * (1.0 - WGS84_E2) / w**3, WGS84_A_M / w


def lla_to_local(lla_deg_m: np.ndarray, origin_lla: tuple[float, float, float]) -> np.ndarray:
    """(N, 3) latitude (deg), longitude (deg), altitude (m) -> (N, 3) east, north, up (m)."""
    lla = np.asarray(lla_deg_m, dtype=float).reshape(-1, 3)
    lat0 = math.radians(origin_lla[0])
    r_n, r_e = _radii_m(lat0)
    north = np.radians(lla[:, 0] - origin_lla[0]) * r_n
    east = np.radians(lla[:, 1] - origin_lla[1]) * r_e * math.cos(lat0)
    return np.column_stack([east, north, lla[:, 2] - origin_lla[2]])


def local_to_lla(enu_m: np.ndarray, origin_lla: tuple[float, float, float]) -> np.ndarray:
    """The inverse of :func:`lla_to_local`."""
    enu = np.asarray(enu_m, dtype=float).reshape(-1, 3)
    lat0 = math.radians(origin_lla[0])
    r_n, r_e = _radii_m(lat0)
    lat = origin_lla[0] + np.degrees(enu[:, 1] / r_n)
    lon = origin_lla[1] + np.degrees(enu[:, 0] / (r_e * math.cos(lat0)))
    return np.column_stack([lat, lon, enu[:, 2] + origin_lla[2]])


# --- reading ---------------------------------------------------------------------------------


def _stamp_s(msg: Any, bag_time_ns: int) -> float:
    st = msg.header.stamp
    if st.sec == 0 and st.nanosec == 0:
        return bag_time_ns // 1_000_000_000 + (bag_time_ns % 1_000_000_000) * 1e-9
    return st.sec + st.nanosec * 1e-9


def _messages(reader, connections, path: Path):
    """``reader.messages(connections)`` with every failure of a damaged bag (rosbags' own errors,
    struct and Unicode errors from a cut record) a DataError naming the bag; at the end, each
    connection must have delivered the messages its index (ROS 1) or ``metadata.yaml`` (ROS 2)
    declares: a database that disagrees with its metadata otherwise reads as a short or empty
    bag without a word."""
    seen: dict[int, int] = {c.id: 0 for c in connections}
    it = iter(reader.messages(connections=connections))
    while True:
        try:
            item = next(it)
        except StopIteration:
            break
        except Exception as exc:
            raise DataError(f"cannot read the bag's messages: {type(exc).__name__}: {exc}", path) from None
        seen[item[0].id] = seen.get(item[0].id, 0) + 1
        yield item
    for c in connections:
        declared = getattr(c, "msgcount", None)
        if declared is not None and declared != seen.get(c.id, 0):
            raise DataError(f"topic {c.topic}: the bag declares {declared} messages but holds {seen.get(c.id, 0)} "
                            "(its storage and its index or metadata.yaml disagree)", path)


def _decoded(reader, connections, path: Path):
    """(connection, receive time ns, message) of :func:`_messages`, a message that does not
    decode a DataError naming its topic and receive time."""
    for conn, t_ns, raw in _messages(reader, connections, path):
        try:
            msg = reader.deserialize(raw, conn.msgtype)
        except Exception as exc:
            raise DataError(f"message on {conn.topic} at {t_ns} ns cannot be decoded: {type(exc).__name__}: {exc}",
                            path) from None
        yield conn, t_ns, msg


def _finite(**values: float) -> str | None:
    for field, v in values.items():
        if not math.isfinite(v):
            return f"{field} is {v!r}, not a finite number"
    return None


def _message_problem(kind: str, m: Any) -> str | None:
    """What makes message ``m`` of ``kind`` physically impossible (names the field), or None.
    A reader returns a valid Sequence or refuses: NaN angles, a non-positive or non-finite
    range_max or a NaN twist would otherwise reach every estimator."""
    if kind == "scan":
        problem = _finite(angle_min=m.angle_min, angle_increment=m.angle_increment, range_min=m.range_min,
                          range_max=m.range_max)
        if problem:
            return problem
        if m.range_max <= 0:
            return f"range_max is {m.range_max!r}; a laser's maximum range must be > 0"
        if not 0 <= m.range_min < m.range_max:
            return f"range_min {m.range_min!r} must be >= 0 and below range_max {m.range_max!r}"
        if len(m.ranges) > 1 and m.angle_increment == 0:
            return f"angle_increment is 0 for {len(m.ranges)} beams"
        return None
    if kind == "odom":
        p, q, tw = m.pose.pose.position, m.pose.pose.orientation, m.twist.twist
        return _finite(**{"pose.position.x": p.x, "pose.position.y": p.y, "pose.orientation.x": q.x,
                          "pose.orientation.y": q.y, "pose.orientation.z": q.z, "pose.orientation.w": q.w,
                          "twist.linear.x": tw.linear.x, "twist.angular.z": tw.angular.z})
    if kind == "imu":
        av, la = m.angular_velocity, m.linear_acceleration
        return _finite(**{f"angular_velocity.{a}": getattr(av, a) for a in "xyz"},
                       **{f"linear_acceleration.{a}": getattr(la, a) for a in "xyz"})
    if kind == "gps":
        if m.status.status < 0:  # NO_FIX: skipped, whatever it holds
            return None
        problem = _finite(latitude=m.latitude, longitude=m.longitude, altitude=m.altitude)
        if problem:
            return problem
        if not (-90 <= m.latitude <= 90 and -180 <= m.longitude <= 360):
            return f"latitude {m.latitude!r} / longitude {m.longitude!r} out of range"
        if m.position_covariance_type > 0:
            var = np.asarray(m.position_covariance, dtype=float).reshape(3, 3)[[0, 1], [0, 1]]
            if not (np.isfinite(var).all() and (var >= 0).all() and var.sum() > 0):
                return f"position_covariance variances {var.tolist()} must be finite, >= 0 and not both 0"
        return None
    if kind == "tf":
        for tr in m.transforms:
            tt, q = tr.transform.translation, tr.transform.rotation
            problem = _finite(**{"transform.translation.x": tt.x, "transform.translation.y": tt.y,
                                 "transform.rotation.z": q.z, "transform.rotation.w": q.w})
            if problem:
                return problem
    return None


def _yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def read_bag(path: str | Path, topics: BagTopics = BagTopics(), name: str | None = None,
             odometry_source: Literal["auto", "twist", "pose"] = "auto",
             tf_odometry: tuple[str, str] | None = None,
             gps_origin_lla: tuple[float, float, float] | None = None) -> Sequence:
    """A Sequence from the bag at ``path`` (see the module docstring)."""
    from rosbags.highlevel import AnyReader

    path = Path(path)
    if not path.exists():
        raise DataError("no such bag", path)
    if odometry_source not in ("auto", "twist", "pose"):
        raise DataError(f"odometry_source must be auto, twist or pose, got {odometry_source!r}", path)
    wanted = {"scan": (topics.scan, MSG_SCAN), "odom": (topics.odom, MSG_ODOM),
              "imu": (topics.imu, MSG_IMU), "gps": (topics.gps, MSG_FIX)}
    if tf_odometry is not None:
        wanted["tf"] = (topics.tf, MSG_TF)
    try:
        reader = AnyReader([path], default_typestore=_typestore())
        reader.open()
    except Exception as exc:  # rosbags raises its own errors for damaged or foreign files
        raise DataError(f"cannot open as a ROS bag: {type(exc).__name__}: {exc}", path) from None
    try:
        present = {c.topic: c.msgtype for c in reader.connections}
        conns: dict[str, list] = {}
        for kind, (topic, msgtype) in wanted.items():
            if topic is None or topic not in present:
                continue
            if present[topic] != msgtype:
                raise DataError(f"topic {topic} carries {present[topic]}, expected {msgtype} for {kind}", path)
            conns[kind] = [c for c in reader.connections if c.topic == topic]
        if not conns:
            listing = ", ".join(f"{t} ({m})" for t, m in sorted(present.items())) or "none"
            raise DataError(f"none of the requested topics is in the bag; it has: {listing}", path)
        rows: dict[str, list] = {k: [] for k in conns}
        by_id = {c.id: kind for kind, cs in conns.items() for c in cs}
        for conn, t_ns, msg in _decoded(reader, [c for cs in conns.values() for c in cs], path):
            rows[by_id[conn.id]].append((t_ns, msg))
    finally:
        reader.close()
    for kind, (topic, _) in wanted.items():
        for k, (_, m) in enumerate(rows.get(kind, [])):
            problem = _message_problem(kind, m)
            if problem:
                raise DataError(f"{topic} message {k}: {problem}", path)

    # odometry first: at a shared stamp the motion up to t comes before the measurement at t
    # (the order every slamkit reader and the simulator use; from_events keeps it, sorting stably)
    odometry = _odometry_events(rows, odometry_source, tf_odometry, path)
    events: list = list(odometry)
    skipped: dict[str, int] = {}
    for t_ns, m in rows.get("scan", []):
        angles = beam_angles_rad(m.angle_min, m.angle_increment, len(m.ranges))
        r = np.asarray(m.ranges)
        valid = np.isfinite(r) & (r >= m.range_min) & (r <= m.range_max)
        # range_max travels as float32: its shortest decimal is the value the sensor reported
        events.append(Scan(_stamp_s(m, t_ns), angles, np.where(valid, r, np.nan).astype(r.dtype),
                           float(str(np.float32(m.range_max)))))
    for t_ns, m in rows.get("imu", []):
        av, la = m.angular_velocity, m.linear_acceleration
        events.append(Imu(_stamp_s(m, t_ns), np.array([av.x, av.y, av.z]), np.array([la.x, la.y, la.z])))
    fixes = [(t_ns, m) for t_ns, m in rows.get("gps", []) if m.status.status >= 0]
    if len(fixes) < len(rows.get("gps", [])):
        skipped["gps_no_fix"] = len(rows["gps"]) - len(fixes)
    origin = gps_origin_lla
    if fixes:
        if origin is None:
            m0 = fixes[0][1]
            origin = (float(m0.latitude), float(m0.longitude), float(m0.altitude))
        enu = lla_to_local(np.array([[m.latitude, m.longitude, m.altitude] for _, m in fixes]), origin)
        for (t_ns, m), p in zip(fixes, enu):
            cov = np.asarray(m.position_covariance, dtype=float).reshape(3, 3)
            sigma = (math.sqrt(0.5 * (cov[0, 0] + cov[1, 1]))
                     if m.position_covariance_type > 0 else float("nan"))
            events.append(Gps(_stamp_s(m, t_ns), p, sigma))
    metadata: dict[str, Any] = {"source": str(path),
                                "odometry_source": _odometry_source_used(rows, odometry_source, tf_odometry)}
    if origin is not None:
        metadata["gps_origin_lla"] = list(origin)
    if skipped:
        metadata["skipped"] = skipped
    stamps = np.array([e.stamp_s for e in events])
    if not np.isfinite(stamps).all():
        raise DataError("a message has a non-finite stamp", path)
    # the robot starts where the first odometry message puts it (write_bag's first message is
    # the start pose), as a CARMEN log's first ODOM line does
    initial = None
    if rows.get("odom"):
        p0 = rows["odom"][0][1].pose.pose
        initial = np.array([p0.position.x, p0.position.y, _yaw(p0.orientation)])
    return Sequence.from_events(name or path.stem, events, metadata=metadata, initial_world_xytheta_body=initial)


def _twists_all_zero(rows: dict[str, list]) -> bool:
    return all(m.twist.twist.linear.x == 0.0 and m.twist.twist.angular.z == 0.0 for _, m in rows["odom"])


def _odometry_source_used(rows, odometry_source, tf_odometry) -> str | None:
    if rows.get("odom"):
        if odometry_source == "auto":
            return "pose" if _twists_all_zero(rows) else "twist"
        return odometry_source
    if tf_odometry is not None and rows.get("tf"):
        return "tf"
    return None


def _odometry_events(rows: dict[str, list], odometry_source: str, tf_odometry, path: Path) -> list[Odometry]:
    source = _odometry_source_used(rows, odometry_source, tf_odometry)
    if source is None:
        return []
    if source == "tf":
        parent, child = tf_odometry
        stamps, poses = [], []
        for t_ns, m in rows["tf"]:
            for tr in m.transforms:
                if tr.header.frame_id.lstrip("/") == parent and tr.child_frame_id.lstrip("/") == child:
                    tt = tr.transform.translation
                    stamps.append(_stamp_s(tr, t_ns))
                    poses.append((tt.x, tt.y, _yaw(tr.transform.rotation)))
        if len(stamps) < 2:
            raise DataError(f"fewer than two {parent} -> {child} transforms on the tf topic", path)
        return odometry_from_poses(np.array(stamps), np.array(poses), f"{path}: tf {parent}->{child}")
    msgs = rows["odom"]
    stamps = np.array([_stamp_s(m, t_ns) for t_ns, m in msgs])
    if source == "pose":
        poses = np.array([(m.pose.pose.position.x, m.pose.pose.position.y, _yaw(m.pose.pose.orientation))
                          for _, m in msgs])
        return odometry_from_poses(stamps, poses, f"{path}: odometry")
    dt = np.diff(stamps)
    if not (dt > 0).all():
        k = int(np.flatnonzero(~(dt > 0))[0]) + 1
        raise DataError(f"odometry stamps must increase strictly; message {k} at {stamps[k]!r} s follows "
                        f"{stamps[k - 1]!r} s", path)
    return [Odometry(float(stamps[k]), float(dt[k - 1]), float(msgs[k][1].twist.twist.linear.x),
                     float(msgs[k][1].twist.twist.angular.z)) for k in range(1, len(msgs))]


# --- what a bag holds; a laser log from a bag -------------------------------------------------


@dataclass(frozen=True)
class BagTopicInfo:
    """One topic of a bag: its message type, how many messages and their mean rate (messages
    per second over the span of the topic's receive times; NaN with fewer than two)."""

    topic: str
    msgtype: str
    count: int
    rate_hz: float
    first_s: float
    last_s: float


def is_bag(path: str | Path) -> bool:
    """A ROS 2 bag folder (one holding ``metadata.yaml``) or a ROS 1 bag file (``#ROSBAG`` magic)."""
    path = Path(path)
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    if path.is_file():
        with open(path, "rb") as f:
            return f.read(7) == b"#ROSBAG"
    return False


def _open(path: Path):
    from rosbags.highlevel import AnyReader

    if not path.exists():
        raise DataError("no such bag", path)
    if path.is_file() and path.suffix != ".bag" and is_bag(path):
        raise DataError("a ROS 1 bag (it starts with #ROSBAG) is read only under a .bag name (rosbags "
                        "chooses the format by the suffix); rename it", path)
    try:
        reader = AnyReader([path], default_typestore=_typestore())
        reader.open()
    except Exception as exc:  # rosbags raises its own errors for damaged or foreign files
        raise DataError(f"cannot open as a ROS bag: {type(exc).__name__}: {exc}", path) from None
    return reader


def bag_topics(path: str | Path) -> list[BagTopicInfo]:
    """Every topic of the bag at ``path`` (sorted by name) with type, count and rate."""
    path = Path(path)
    reader = _open(path)
    try:
        times: dict[str, list[int]] = {}
        types: dict[str, str] = {}
        for c in reader.connections:
            times.setdefault(c.topic, [])
            types[c.topic] = c.msgtype
        for conn, t_ns, _ in _messages(reader, list(reader.connections), path):
            times[conn.topic].append(t_ns)
    finally:
        reader.close()
    out = []
    for topic in sorted(times):
        t = np.sort(np.array(times[topic], dtype=np.int64))
        span_s = (t[-1] - t[0]) * 1e-9 if len(t) else 0.0
        rate = (len(t) - 1) / span_s if len(t) > 1 and span_s > 0 else float("nan")
        out.append(BagTopicInfo(topic, types[topic], len(t), float(rate),
                                float(t[0]) * 1e-9 if len(t) else float("nan"),
                                float(t[-1]) * 1e-9 if len(t) else float("nan")))
    return out


def bag_info(path: str | Path) -> dict[str, Any]:
    """What ``slamkit data info BAG`` prints: the bag's kind, duration and every topic."""
    path = Path(path)
    topics = bag_topics(path)
    firsts = [t.first_s for t in topics if t.count]
    lasts = [t.last_s for t in topics if t.count]
    return {"path": str(path), "kind": "ros1" if path.is_file() else "ros2",
            "storage": _storage_of(path), "messages": sum(t.count for t in topics),
            "duration_s": float(max(lasts) - min(firsts)) if firsts else 0.0,
            "topics": [{"topic": t.topic, "type": t.msgtype, "count": t.count, "rate_hz": float(t.rate_hz)}
                       for t in topics]}


def _storage_of(path: Path) -> str:
    if path.is_file():
        return "rosbag1"
    if any(path.glob("*.mcap")):
        return "mcap"
    return "sqlite3"


def _unique_topic(present: dict[str, str], msgtype: str, chosen: str | None, what: str, key: str,
                  required: bool, path: Path) -> str | None:
    listing = ", ".join(f"{t} ({m})" for t, m in sorted(present.items())) or "none"
    if chosen is not None:
        if chosen not in present:
            raise DataError(f"{key} {chosen!r} is not in the bag; it has: {listing}", path)
        if present[chosen] != msgtype:
            raise DataError(f"{key} {chosen!r} carries {present[chosen]}, not {msgtype}", path)
        return chosen
    found = sorted(t for t, m in present.items() if m == msgtype)
    if len(found) == 1:
        return found[0]
    if not found and not required:
        return None
    how = (f"no {what} topic of type {msgtype}" if not found
           else f"{len(found)} {what} topics of type {msgtype} ({', '.join(found)}); set {key} to choose one")
    raise DataError(f"{how}. The bag's topics: {listing}", path)


def _static_mount(reader, tf_conns, base_frame: str, laser_frame: str, path: Path) -> tuple[float, float, float] | None:
    """base_frame -> laser_frame (x, y, yaw) composed along the static tf tree, or None."""
    parent_of: dict[str, tuple[str, tuple[float, float, float]]] = {}
    for k, (conn, _, msg) in enumerate(_decoded(reader, tf_conns, path)):
        problem = _message_problem("tf", msg)
        if problem:
            raise DataError(f"{conn.topic} message {k}: {problem}", path)
        for tr in msg.transforms:
            tt = tr.transform.translation
            parent_of[tr.child_frame_id.lstrip("/")] = (tr.header.frame_id.lstrip("/"),
                                                        (tt.x, tt.y, _yaw(tr.transform.rotation)))
    # walk from the laser frame up to the base frame: base_T_laser = base_T_a a_T_b ... x_T_laser
    chain, frame, seen = [], laser_frame.lstrip("/"), set()
    while frame != base_frame.lstrip("/"):
        if frame not in parent_of or frame in seen:
            return None
        seen.add(frame)
        parent, pose = parent_of[frame]
        chain.append(pose)
        frame = parent
    base_T_laser = np.zeros(3)
    for pose in reversed(chain):
        base_T_laser = se2.compose(base_T_laser, np.asarray(pose, float))
    return tuple(float(v) for v in base_T_laser)


def read_laser_bag(path: str | Path, scan_topic: str | None = None, odom_topic: str | None = None,
                   name: str | None = None) -> Sequence:
    """A laser log (scans, and odometry when the bag has it) from a ROS bag.

    The ``sensor_msgs/LaserScan`` and ``nav_msgs/Odometry`` topics are the bag's only ones of
    those types unless ``scan_topic`` / ``odom_topic`` name them; with several (or no scan
    topic) a DataError lists the bag's topics and types. The laser's mounting on the robot,
    ``metadata['body_xytheta_lidar']``, comes from the static transforms (``/tf_static``) from
    the odometry's ``child_frame_id`` (``base_link`` without odometry) to the scans' frame, when
    the bag has them."""
    path = Path(path)
    reader = _open(path)
    try:
        present = {c.topic: c.msgtype for c in reader.connections}
        scan = _unique_topic(present, MSG_SCAN, scan_topic, "scan", "scan_topic", True, path)
        odom = _unique_topic(present, MSG_ODOM, odom_topic, "odometry", "odom_topic", False, path)
        mount = None
        tf_conns = [c for c in reader.connections if c.topic == "/tf_static" and c.msgtype == MSG_TF]
        if tf_conns:
            first = {}
            for topic in (scan, odom):
                if topic is None:
                    continue
                # the first message only (leaving the generator early skips the count check,
                # which read_bag makes when it reads them all)
                for _, _, msg in _decoded(reader, [c for c in reader.connections if c.topic == topic], path):
                    first[topic] = msg
                    break
            laser_frame = first[scan].header.frame_id if scan in first else ""
            base_frame = (first[odom].child_frame_id if odom in first and first[odom].child_frame_id
                          else "base_link")
            if laser_frame:
                mount = _static_mount(reader, tf_conns, base_frame, laser_frame, path)
    finally:
        reader.close()
    seq = read_bag(path, BagTopics(scan=scan, odom=odom, imu=None, gps=None, tf=None), name=name)
    metadata = {**seq.metadata, "scan_topic": scan, "odom_topic": odom}
    if mount is not None:
        metadata["body_xytheta_lidar"] = list(mount)
    # the stamp order (a bag stores its messages by time)
    metadata.setdefault("event_order", "stamp")
    return replace(seq, metadata=metadata)


# --- writing ---------------------------------------------------------------------------------


def _time(ts, stamp_s: float):
    sec = math.floor(stamp_s)
    nsec = int(round((stamp_s - sec) * 1e9))
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    # builtin_interfaces/Time holds the seconds in an int32 (rosbags writes ROS 1 time the same
    # way): a stamp from 2^31 s on (2038-01-19) made struct.pack fail deep in the serializer
    if not -2**31 <= sec < 2**31:
        raise DataError(f"a stamp of {stamp_s!r} s does not fit a ROS time, whose seconds are a signed "
                        "32-bit integer (-2147483648 .. 2147483647 s, up to 2038-01-19)")
    return ts.types["builtin_interfaces/msg/Time"](sec=int(sec), nanosec=nsec), int(sec) * 1_000_000_000 + nsec


def _header(ts, stamp_s: float, frame: str):
    t, ns = _time(ts, stamp_s)
    H = ts.types["std_msgs/msg/Header"]
    if "seq" in H.__dataclass_fields__:  # ROS 1 headers carry a sequence number
        return H(seq=0, stamp=t, frame_id=frame), ns
    return H(stamp=t, frame_id=frame), ns


def _quat_yaw(ts, yaw: float):
    return ts.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(0.5 * yaw), w=math.cos(0.5 * yaw))


def check_bag_path(path: str | Path, ros_version: int, overwrite: bool = False) -> None:
    """An OutputError unless :func:`write_bag` may write a ROS ``ros_version`` bag at ``path``
    (the CLI asks before it loads the recording): a new path, or with ``overwrite`` a bag of the
    same ROS version."""
    path = Path(path)
    check_no_file_above(path, "choose another output path")
    if path.exists() or path.is_symlink():
        if not overwrite:
            raise OutputError(f"{path} exists; a bag is only written to a new path (pass --overwrite to replace "
                              "an earlier bag)")
        if path.is_symlink() or not is_bag(path) or path.is_dir() != (ros_version == 2):
            raise OutputError(f"{path} exists and is not a ROS {ros_version} bag; --overwrite replaces only a bag "
                              "of the same kind: choose another output path")


def write_bag(path: str | Path, sequence: Sequence, topics: BagTopics = BagTopics(),
              ros_version: Literal[1, 2] = 2, gps_origin_lla: tuple[float, float, float] = (0.0, 0.0, 0.0),
              storage: Literal["sqlite3", "mcap"] = "sqlite3", overwrite: bool = False) -> BagWriteSummary:
    """Write ``sequence`` as a ROS bag (see the module docstring); returns what was written.
    ``storage`` is the ROS 2 storage plugin (``sqlite3``: NAME/NAME.db3, ``mcap``: NAME/NAME.mcap).
    An existing path is replaced only with ``overwrite`` and only when it is a bag of the same ROS
    version (a ``.bag`` file by a ``.bag`` file, a ROS 2 bag folder by a folder); the new bag is
    complete before it takes the old one's place."""
    path = Path(path)
    check_bag_path(path, ros_version, overwrite)
    path.parent.mkdir(parents=True, exist_ok=True)
    if ros_version not in (1, 2):
        raise DataError(f"ros_version must be 1 or 2, got {ros_version!r}")
    if storage not in ("sqlite3", "mcap"):
        raise DataError(f"storage must be sqlite3 or mcap, got {storage!r}")
    ts = _typestore(ros_version)
    T = ts.types
    by_kind: dict[type, list] = {}
    for e in sequence:
        by_kind.setdefault(type(e), []).append(e)
    skipped = {k.__name__: len(v) for k, v in by_kind.items() if k in (RangeBearing, WheelEncoders)}
    out: list[tuple[int, str, str, Any]] = []  # (time ns, topic, msgtype, message)
    zeros9 = np.zeros(9)
    for e in by_kind.get(Scan, []) if topics.scan else []:
        a = np.asarray(e.angles_rad, dtype=float)
        inc = (a[-1] - a[0]) / (len(a) - 1) if len(a) > 1 else 0.0
        if len(a) > 2 and np.abs(np.diff(a) - inc).max() > 1e-6:
            raise DataError(f"{sequence.name}: scan at {e.stamp_s} s has unevenly spaced beams; "
                            "sensor_msgs/LaserScan needs a constant angle increment")
        r = np.asarray(e.ranges_m).astype(np.float32)
        header, ns = _header(ts, e.stamp_s, "laser")
        msg = T[MSG_SCAN](header=header, angle_min=float(a[0]), angle_max=float(a[-1]), angle_increment=float(inc),
                          time_increment=0.0, scan_time=0.0, range_min=0.0, range_max=float(e.max_range_m),
                          ranges=np.where(np.isnan(r), np.float32(np.inf), r), intensities=np.zeros(0, np.float32))
        out.append((ns, topics.scan, MSG_SCAN, msg))
    odo = by_kind.get(Odometry, []) if topics.odom else []
    if odo:
        pose = (np.zeros(3) if sequence.initial_world_xytheta_body is None
                else np.asarray(sequence.initial_world_xytheta_body, dtype=float).reshape(3))
        cov36 = np.zeros(36)

        def odom_msg(stamp_s, p, v, w):
            header, ns = _header(ts, stamp_s, "odom")
            pose_msg = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=float(p[0]), y=float(p[1]), z=0.0),
                                                   orientation=_quat_yaw(ts, float(p[2])))
            twist = T["geometry_msgs/msg/Twist"](linear=T["geometry_msgs/msg/Vector3"](x=float(v), y=0.0, z=0.0),
                                                 angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=float(w)))
            return ns, T[MSG_ODOM](header=header, child_frame_id="base_link",
                                   pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose_msg, covariance=cov36),
                                   twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov36))

        ns, m = odom_msg(odo[0].stamp_s - odo[0].dt_s, pose, 0.0, 0.0)
        out.append((ns, topics.odom, MSG_ODOM, m))
        for e in odo:
            pose = motion(pose, np.array([e.v_mps, e.omega_radps]), e.dt_s)
            ns, m = odom_msg(e.stamp_s, pose, e.v_mps, e.omega_radps)
            out.append((ns, topics.odom, MSG_ODOM, m))
    for e in by_kind.get(Imu, []) if topics.imu else []:
        header, ns = _header(ts, e.stamp_s, "imu")
        g, acc = np.asarray(e.gyro_radps, float), np.asarray(e.accel_mps2, float)
        cov = zeros9.copy()
        cov[0] = -1.0  # REP 145: no orientation estimate
        out.append((ns, topics.imu, MSG_IMU, T[MSG_IMU](
            header=header, orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=cov,
            angular_velocity=T["geometry_msgs/msg/Vector3"](x=g[0], y=g[1], z=g[2]), angular_velocity_covariance=zeros9,
            linear_acceleration=T["geometry_msgs/msg/Vector3"](x=acc[0], y=acc[1], z=acc[2]),
            linear_acceleration_covariance=zeros9)))
    fixes = by_kind.get(Gps, []) if topics.gps else []
    if fixes:
        enu = np.array([np.r_[np.asarray(e.world_p_body, float).reshape(-1)[:2],
                              np.asarray(e.world_p_body, float).reshape(-1)[2] if np.size(e.world_p_body) > 2 else 0.0]
                        for e in fixes])
        lla = local_to_lla(enu, gps_origin_lla)
        for e, (lat, lon, alt) in zip(fixes, lla):
            header, ns = _header(ts, e.stamp_s, "gps")
            known = math.isfinite(e.sigma_m)
            cov = np.diag([e.sigma_m**2, e.sigma_m**2, e.sigma_m**2]).reshape(9) if known else zeros9
            out.append((ns, topics.gps, MSG_FIX, T[MSG_FIX](
                header=header, status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
                latitude=float(lat), longitude=float(lon), altitude=float(alt), position_covariance=cov,
                position_covariance_type=2 if known else 0)))
    out.sort(key=lambda row: row[0])
    # assembled under a hidden temporary folder and renamed into place when complete; a ROS 2
    # bag is written as <tmp>/<name> because rosbags names the database (and metadata.yaml lists
    # it) after the bag folder: NAME/NAME.db3 (or .mcap), an ordinary name, not the temporary one
    tmp = temporary_sibling(path)
    try:
        if ros_version == 2:
            tmp.mkdir()
            counts = _write_messages(tmp / path.name, out, ts, ros_version, storage)
            _put_in_place(tmp / path.name, path)
            tmp.rmdir()
        else:
            counts = _write_messages(tmp, out, ts, ros_version)
            _put_in_place(tmp, path)
    except BaseException:
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            tmp.unlink(missing_ok=True)
        raise
    return BagWriteSummary(path, counts, skipped)


def _put_in_place(new: Path, path: Path) -> None:
    """Rename the complete bag ``new`` to ``path``; an earlier bag there (checked by the caller)
    is moved aside first and removed after, so ``path`` never holds half a bag."""
    if not path.exists():
        new.rename(path)
        return
    if new.is_file():
        os.replace(new, path)  # atomic for a file
        return
    old = temporary_sibling(path)
    path.rename(old)
    new.rename(path)
    shutil.rmtree(old, ignore_errors=True)


def _write_messages(path: Path, rows: list, ts, ros_version: int, storage: str = "sqlite3") -> dict[str, int]:
    counts: dict[str, int] = {}
    if ros_version == 2:
        from rosbags.rosbag2 import StoragePlugin, Writer

        writer = Writer(path, version=9,
                        storage_plugin=StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3)
        serialize = ts.serialize_cdr
    elif ros_version == 1:
        from rosbags.rosbag1 import Writer

        writer = Writer(path)
        serialize = ts.serialize_ros1
    else:
        raise DataError(f"ros_version must be 1 or 2, got {ros_version!r}")
    with writer:
        conns = {}
        for ns, topic, msgtype, msg in rows:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=ts)
            writer.write(conns[topic], ns, serialize(msg, msgtype))
            counts[topic] = counts.get(topic, 0) + 1
    return counts


__all__ = ["BagTopicInfo", "BagTopics", "BagWriteSummary", "bag_info", "bag_topics", "check_bag_path", "is_bag",
           "read_bag",
           "read_laser_bag", "write_bag", "lla_to_local", "local_to_lla"]
