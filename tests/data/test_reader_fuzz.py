"""Issue 10: every reader fuzzed with the seeded mutator of ``tests/fuzzing.py``.

Each case is a real file (a small slice of a registry dataset, or a file slamkit wrote) mutated one
to three times; the reader must either return a result with no impossible numbers or raise a
``SlamkitError`` -- never another exception, never hang. The default run tries ``FAST_CASES`` per
format (a few hundred in all); ``-m slow`` tries ``SLOW_CASES`` per format, the figure issue 10
counts.
"""

from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from fuzzing import fuzz, has_nonfinite  # noqa: E402

from slamkit.data.formats import load_pose_graph, read_ground_truth  # noqa: E402
from slamkit.data.formats.kitti import read_kitti  # noqa: E402
from slamkit.data.formats.landmark_datasets import (  # noqa: E402
    read_isam_landmark_sequence,
    read_mrclam_sequence,
    read_pyfg_landmark_sequence,
)
from slamkit.data.formats.sequence import open_sequence, save_sequence  # noqa: E402
from slamkit.data.formats.tum import read_tum  # noqa: E402
from slamkit.data.sequence import Gps, Imu, Odometry, RangeBearing, Scan, Sequence, WheelEncoders  # noqa: E402
from slamkit.data.trajectory import Trajectory  # noqa: E402
from slamkit.maps.movingai import load_map, load_scenarios  # noqa: E402
from slamkit.sim.ros_map import load_ros_map  # noqa: E402

FAST_CASES = 15
SLOW_CASES = 350
DATA = Path("/work/shared/datasets")
GTSAM_DATA = Path(__import__("gtsam").__file__).parent / "Data"


def _head(path: Path, lines: int) -> bytes:
    return b"\n".join(path.read_bytes().split(b"\n")[:lines]) + b"\n"


def _pyfg_seed() -> bytes:
    """Robot A's first 20 poses with their odometry and landmark sightings, and every landmark."""
    keep = []
    for line in (DATA / "landmark_2d/mrclam5a.pyfg").read_bytes().split(b"\n"):
        parts = line.split()
        if not parts:
            continue
        ids = [int(p[1:]) for p in parts[1:4] if p[:1] == b"A" and p[1:].isdigit()]
        if parts[0] == b"VERTEX_XY" or (ids and max(ids) < 20 and parts[0] != b"EDGE_RANGE"
                                        and all(p[:1] in b"AL" for p in parts[2:4] if p[:1].isalpha())):
            keep.append(line)
    return b"\n".join(keep) + b"\n"


def _png_seed() -> bytes:
    from PIL import Image

    grey = np.frombuffer((DATA / "maps_ros/willow-2010-02-18-0.10.pgm").read_bytes()[-566 * 608:],
                         dtype=np.uint8).reshape(608, 566)[300:324, 250:282]
    buf = io.BytesIO()
    Image.fromarray(grey).save(buf, format="PNG")
    return buf.getvalue()


def _pgm_seed() -> bytes:
    grey = np.frombuffer((DATA / "maps_ros/willow-2010-02-18-0.10.pgm").read_bytes()[-566 * 608:],
                         dtype=np.uint8).reshape(608, 566)[300:324, 250:282]
    return b"P5\n32 24\n255\n" + grey.tobytes()


def _slamseq_seed(tmp: Path) -> bytes:
    rng = np.random.default_rng(0)
    events = []
    for k in range(6):
        t = 0.1 * (k + 1)
        events += [Odometry(t, 0.1, 1.0, 0.1 * k),
                   RangeBearing(t, np.array([1, 2]), rng.uniform(1, 5, 2), rng.uniform(-1, 1, 2))]
    events += [Imu(0.3, np.array([0.0, 0.01, 0.3]), np.array([0.1, 0.0, 9.81])), WheelEncoders(0.3, 12, -4),
               Gps(0.5, np.array([1.0, 2.0]), 2.5),
               Scan(0.5, np.linspace(-1, 1, 4), np.array([1.0, np.inf, 2.0, 3.0]), 8.0)]
    events.sort(key=lambda e: e.stamp_s)
    gt = Trajectory.from_se2(np.array([0.0, 0.1, 0.5]), np.array([[0, 0, 0], [0.1, 0, 0.1], [0.4, 0.1, 0.2]]))
    seq = Sequence("fuzz", tuple(events), ground_truth=gt, world_p_landmarks={1: np.array([1.0, 2.0]),
                                                                          2: np.array([-4.0, 0.5])},
                   initial_world_xytheta_body=np.zeros(3), metadata={"sigma": [0.1, 0.2]})
    return save_sequence(tmp / "seed.slamseq", seq).read_bytes()


def _check_events(events) -> str | None:
    """Every number finite, except scan ranges (inf / NaN is the format's "no return")."""
    for e in events:
        for field in e.__dataclass_fields__:
            if field == "ranges_m":
                continue
            if has_nonfinite(getattr(e, field)):
                return f"non-finite {type(e).__name__}.{field} at stamp {e.stamp_s}"
    return None


def _read_slamseq(path: Path):
    with open_sequence(path) as reader:  # lazy: touch every column, the ground truth and landmarks
        return (list(reader), reader.ground_truth, reader.world_p_landmarks, reader.initial_world_xytheta_body,
                dict(reader.metadata))


def _check_slamseq(result) -> str | None:
    events, gt, lms, initial, _ = result
    return _check_events(events) or ("non-finite ground truth or landmark"
                                     if has_nonfinite([gt, lms, initial]) else None)


def _check_sequence(seq) -> str | None:
    return _check_events(seq.events) or ("non-finite ground truth or landmark"
                                         if has_nonfinite([seq.ground_truth, seq.world_p_landmarks]) else None)


def _with_companions(files: dict[str, bytes], case_name: str):
    def prepare(workdir: Path, case: bytes) -> Path:
        for name, data in files.items():
            (workdir / name).write_bytes(data)
        (workdir / case_name).write_bytes(case)
        return workdir / case_name
    return prepare


_MRCLAM = DATA / "landmark_2d/MRCLAM_Dataset1"
_MRCLAM_FILES = {"odo.dat": _head(_MRCLAM / "Robot1_Odometry.dat", 120),
                 "meas.dat": _head(_MRCLAM / "Robot1_Measurement.dat", 60),
                 "lm.dat": (_MRCLAM / "Landmark_Groundtruth.dat").read_bytes(),
                 "codes.dat": (_MRCLAM / "Barcodes.dat").read_bytes()}


def _mrclam(workdir: Path) -> Sequence:
    return read_mrclam_sequence(workdir / "odo.dat", workdir / "meas.dat", workdir / "lm.dat", workdir / "codes.dat")


def _ros_yaml(image: str) -> bytes:
    return (f"image: {image}\nresolution: 0.1\norigin: [-1.0, -2.0, 0.0]\nnegate: 0\n"
            "occupied_thresh: 0.65\nfree_thresh: 0.196\n").encode()


# name -> (target, seed bytes or factory(tmp), suffix, binary, check, prepare)
TARGETS = {
    "g2o_2d": (lambda p: load_pose_graph(p, format="g2o"), _head(DATA / "pose_graph_2d/intel_g2o_943.g2o", 60),
               ".g2o", False, None, None),
    "g2o_3d": (lambda p: load_pose_graph(p, format="g2o"), _head(DATA / "pose_graph_3d/tinyGrid3D.g2o", 60),
               ".g2o", False, None, None),
    "toro": (lambda p: load_pose_graph(p, format="toro"), _head(DATA / "pose_graph_2d/FR079_P_toro.graph", 60),
             ".graph", False, None, None),
    "isam": (lambda p: load_pose_graph(p, format="isam"), _head(DATA / "pose_graph_3d/sphere400.txt", 60),
             ".txt", False, None, None),
    "tum": (read_tum, _head(DATA / "reference_trajectories/V101_gt.txt", 40), ".tum", False, None, None),
    "kitti": (read_kitti, _head(DATA / "reference_trajectories/KITTI_00_gt.txt", 30), ".txt", False, None, None),
    "kitti_times": (lambda p: read_kitti(p.with_name("poses.txt"), times_path=p),
                    _head(DATA / "reference_trajectories/KITTI_00_gt_times.txt", 30), ".txt", False, None,
                    _with_companions({"poses.txt": _head(DATA / "reference_trajectories/KITTI_00_gt.txt", 30)},
                                     "times.txt")),
    "gt_id_x_y_theta": (lambda p: read_ground_truth(p, "id_x_y_theta"),
                        _head(DATA / "pose_graph_2d/ring_groundtruth_poses.txt", 40), ".txt", False, None, None),
    "gt_x_y_theta": (lambda p: read_ground_truth(p, "x_y_theta"),
                     _head(DATA / "pose_graph_2d/manhattanOlson3500_groundtruth_nodes.dat", 40), ".dat", False,
                     None, None),
    "citytrees": (read_isam_landmark_sequence, _head(DATA / "landmark_2d/cityTrees10000.txt", 60), ".txt", False,
                  _check_sequence, None),
    "victoria_park": (lambda p: read_isam_landmark_sequence(p, covariance_entries=True),
                      _head(GTSAM_DATA / "victoria_park.txt", 60), ".txt", False, _check_sequence, None),
    "mrclam5a_pyfg": (read_pyfg_landmark_sequence, _pyfg_seed(), ".pyfg", False, _check_sequence, None),
    "mrclam_raw": (lambda p: _mrclam(p.parent), _MRCLAM_FILES["meas.dat"], ".dat", False, _check_sequence,
                   _with_companions({k: v for k, v in _MRCLAM_FILES.items() if k != "meas.dat"}, "meas.dat")),
    "movingai_map": (load_map, b"type octile\nheight 6\nwidth 8\nmap\n" + b"\n".join(
        line[:8] for line in (DATA / "grid_planning/movingai/room/8room_000.map").read_bytes().split(b"\n")[4:10])
        + b"\n", ".map", False, None, None),
    "movingai_scen": (load_scenarios, _head(DATA / "grid_planning/movingai/room/8room_000.map.scen", 20),
                      ".scen", False, None, None),
    "ros_map_png": (lambda p: load_ros_map(p.with_name("map.yaml")), _png_seed(), ".png", True, None,
                    _with_companions({"map.yaml": _ros_yaml("map.png")}, "map.png")),
    "ros_map_pgm": (lambda p: load_ros_map(p.with_name("map.yaml")), _pgm_seed(), ".pgm", True, None,
                    _with_companions({"map.yaml": _ros_yaml("map.pgm")}, "map.pgm")),
    "slamseq": (_read_slamseq, _slamseq_seed, ".slamseq", True, _check_slamseq, None),
}


# --- issue 31: the readers added since issue 10 ------------------------------------------------


def _bag_sequence() -> Sequence:
    """Five odometry steps, scans of 19 beams (one no-return), three IMU and three GPS events."""
    from slamkit.data.sequence import beam_angles_rad

    events = []
    for k in range(1, 6):
        t = 100.0 + 0.1 * k
        events.append(Odometry(t, 0.1, 0.5, 0.05 * k))
        r = np.linspace(0.5, 9.0, 19).astype(np.float32)
        r[3] = np.nan
        events.append(Scan(round(t + 0.01, 3), beam_angles_rad(-np.pi / 2, np.pi / 18, 19), r, 10.0))
        if k <= 3:
            events.append(Imu(round(t + 0.02, 3), np.array([0.0, 0.0, 0.1]), np.array([0.1, 0.0, 9.81])))
            events.append(Gps(round(t + 0.05, 3), np.array([1.0 * k, -2.0, 0.5]), 0.5))
    return Sequence.from_events("bag", events)


def _fresh(tmp: Path) -> Path:
    import tempfile

    return Path(tempfile.mkdtemp(dir=tmp))


def _ros1_seed(tmp: Path) -> bytes:
    from slamkit.data.formats.rosbag import write_bag

    return write_bag(_fresh(tmp) / "seed.bag", _bag_sequence(), ros_version=1).path.read_bytes()


def _ros2_files(tmp: Path) -> dict[str, bytes]:
    """metadata.yaml and the database of a ROS 2 bag folder named ``seed2``."""
    from slamkit.data.formats.rosbag import write_bag

    folder = write_bag(_fresh(tmp) / "seed2", _bag_sequence()).path
    (db,) = folder.glob("*.db3")  # named as metadata.yaml lists it
    return {"metadata.yaml": (folder / "metadata.yaml").read_bytes(), "db": db.read_bytes(), "db_name": db.name}


def _ros2_prepare(mutated: str):
    """A ROS 2 bag folder whose ``mutated`` part ('db' or 'metadata.yaml') is the case."""
    def prepare(workdir: Path, case: bytes) -> Path:
        files = _ROS2_FILES.setdefault(str(workdir), _ros2_files(workdir) if str(workdir) not in _ROS2_FILES else {})
        folder = workdir / "seed2"
        folder.mkdir(exist_ok=True)
        (folder / "metadata.yaml").write_bytes(case if mutated == "metadata.yaml" else files["metadata.yaml"])
        (folder / files["db_name"]).write_bytes(case if mutated == "db" else files["db"])
        return folder
    return prepare


_ROS2_FILES: dict[str, dict[str, bytes]] = {}


def _check_bag(seq) -> str | None:
    # a fix without a covariance has sigma NaN: the documented "unknown", not an impossible number
    for e in seq.events:
        for field in e.__dataclass_fields__:
            if field == "ranges_m" or (isinstance(e, Gps) and field == "sigma_m"):
                continue
            if has_nonfinite(getattr(e, field)):
                return f"non-finite {type(e).__name__}.{field} at stamp {e.stamp_s}"
    return "non-finite initial pose" if has_nonfinite(seq.initial_world_xytheta_body) else None


def _read_bag(p: Path):
    from slamkit.data.formats.rosbag import read_bag

    return read_bag(p)


_CARMEN_HEAD = b"\n".join(__import__("bz2").decompress((DATA / "lidar_2d/intel.clf.bz2").read_bytes())
                          .split(b"\n")[:40]) + b"\n"


def _carmen(p: Path):
    from slamkit.data.formats.carmen import load_carmen_sequence

    return load_carmen_sequence(p)


def _compressed(suffix: str):
    """Mutate the log's text, then compress it: the parser behind the decompressor is reached."""
    import bz2
    import gzip

    compress = gzip.compress if suffix == ".gz" else bz2.compress

    def prepare(workdir: Path, case: bytes) -> Path:
        path = workdir / f"case.clf{suffix}"
        path.write_bytes(compress(case))
        return path
    return prepare


_EQVIO = _head(Path(__import__("gtsam").__file__).parent / "Data" / "eqvio_processed_30s.csv", 130)


def _eqvio(p: Path):
    from slamkit.data.formats.eqvio_csv import read_eqvio_csv

    return read_eqvio_csv(p)


_KITTI_FILES = {"imu.txt": _head(GTSAM_DATA / "KittiEquivBiasedImu.txt", 500),
                "gps.txt": _head(GTSAM_DATA / "KittiGps_converted.txt", 7),
                "meta.txt": (GTSAM_DATA / "KittiEquivBiasedImu_metadata.txt").read_bytes()}


def _kitti_imu_gps(workdir: Path):
    from slamkit.data.formats.kitti_imu_gps import read_kitti_imu_gps

    return read_kitti_imu_gps(workdir / "imu.txt", workdir / "gps.txt", workdir / "meta.txt")


def _check_inertial(seq) -> str | None:
    from slamkit.data.inertial import setup_of

    return _check_sequence(seq) or ("non-finite inertial setup (noise, start)" if has_nonfinite(setup_of(seq)) else None)


def _kitti_target(name: str):
    return (lambda p: _kitti_imu_gps(p.parent), _KITTI_FILES[name], ".txt", False, _check_inertial,
            _with_companions({k: v for k, v in _KITTI_FILES.items() if k != name}, name))


def _plaza_files() -> dict[str, bytes]:
    """A slice of Plaza 1: its first 40 s of ground truth, dead reckoning and ranges, every beacon;
    the .mat compressed as the real one is, and uncompressed (whose mutations reach the tables
    rather than zlib's checksum)."""
    from scipy.io import loadmat, savemat

    mat = loadmat(GTSAM_DATA / "Plaza1_.mat")
    t0 = float(mat["GT"][0, 0])
    mats = {}
    for name, compress in (("plaza.mat", True), ("raw.mat", False)):
        buf = io.BytesIO()
        savemat(buf, {"GT": mat["GT"][mat["GT"][:, 0] <= t0 + 40], "TL": mat["TL"]}, do_compression=compress)
        mats[name] = buf.getvalue()
    lines = {}
    for name, src in (("dr.txt", "Plaza1_DR.txt"), ("td.txt", "Plaza1_TD.txt")):
        rows = (GTSAM_DATA / src).read_bytes().split(b"\n")
        lines[name] = b"\n".join(r for r in rows if r.split() and float(r.split()[0]) <= t0 + 40) + b"\n"
    return {**mats, **lines}


_PLAZA_FILES = _plaza_files()


def _plaza_target(name: str):
    from slamkit.data.formats.plaza import read_plaza_sequence

    mat = "raw.mat" if name == "raw.mat" else "plaza.mat"
    return (lambda p: read_plaza_sequence(p.parent / mat, p.parent / "dr.txt", p.parent / "td.txt"),
            _PLAZA_FILES[name], Path(name).suffix, name.endswith(".mat"), _check_sequence,
            _with_companions({k: v for k, v in _PLAZA_FILES.items() if k != name}, name))


TARGETS.update({
    "rosbag_ros1": (_read_bag, _ros1_seed, ".bag", True, _check_bag, None),
    "rosbag_ros2_db": (_read_bag, lambda tmp: _ros2_files(tmp)["db"], ".db3", True, _check_bag, _ros2_prepare("db")),
    "rosbag_ros2_metadata": (_read_bag, lambda tmp: _ros2_files(tmp)["metadata.yaml"], ".yaml", False, _check_bag,
                             _ros2_prepare("metadata.yaml")),
    "carmen_clf": (_carmen, _CARMEN_HEAD, ".clf", False, _check_sequence, None),
    "carmen_gz": (_carmen, __import__("gzip").compress(_CARMEN_HEAD), ".clf.gz", True, _check_sequence, None),
    "carmen_gz_content": (_carmen, _CARMEN_HEAD, ".clf.gz", False, _check_sequence, _compressed(".gz")),
    "carmen_bz2": (_carmen, __import__("bz2").compress(_CARMEN_HEAD), ".clf.bz2", True, _check_sequence, None),
    "carmen_bz2_content": (_carmen, _CARMEN_HEAD, ".clf.bz2", False, _check_sequence, _compressed(".bz2")),
    "eqvio_csv": (_eqvio, _EQVIO, ".csv", False, None, None),
    "kitti_imu_gps_imu": _kitti_target("imu.txt"),
    "kitti_imu_gps_gps": _kitti_target("gps.txt"),
    "kitti_imu_gps_meta": _kitti_target("meta.txt"),
    "plaza_mat": _plaza_target("plaza.mat"),
    "plaza_mat_uncompressed": _plaza_target("raw.mat"),
    "plaza_dr": _plaza_target("dr.txt"),
    "plaza_td": _plaza_target("td.txt"),
})


def _run(name: str, cases: int, tmp_path: Path):
    target, seed, suffix, binary, check, prepare = TARGETS[name]
    if callable(seed):
        seed = seed(tmp_path)
    return fuzz(target, seed, suffix=suffix, cases=cases, seed=10, workdir=tmp_path / "work", name=name,
                binary=binary, check=check, prepare=prepare, timeout_s=10.0)


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_reader_fuzz(name: str, tmp_path: Path) -> None:
    report = _run(name, FAST_CASES, tmp_path)
    assert report.defect_count == 0, report.summary()
    assert sum(report.counts.values()) == FAST_CASES


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(TARGETS))
def test_reader_fuzz_long(name: str, tmp_path: Path) -> None:
    report = _run(name, SLOW_CASES, tmp_path)
    assert report.defect_count == 0, report.summary()


def test_seeds_are_valid_files(tmp_path: Path) -> None:
    """Every seed reads cleanly before mutation, so the fuzz starts from a real, valid file."""
    for name, (target, seed, suffix, _, check, prepare) in TARGETS.items():
        data = seed(tmp_path) if callable(seed) else seed
        work = tmp_path / name
        work.mkdir()
        path = prepare(work, data) if prepare else work / f"seed{suffix}"
        if not prepare:
            path.write_bytes(data)
        result = target(path)
        assert (check or (lambda r: "non-finite" if has_nonfinite(r) else None))(result) is None, name
