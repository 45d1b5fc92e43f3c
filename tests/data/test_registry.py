"""The dataset registry: coverage of MANIFEST.md and the gtsam wheel, checksums of local files,
recorded counts and reference values, lookup order, ground truth."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from slamkit.data import registry, registry_table
from slamkit.data.formats import read_isam
from slamkit.data.formats.ground_truth import read_ground_truth, read_id_x_y_theta, read_x_y_theta
from slamkit.errors import DataError, DatasetNotFoundError


@pytest.fixture
def isolated(monkeypatch, tmp_path):
    """No shared datasets, no wheel, empty cache: only what a test puts in SLAMKIT_DATA/cache."""
    monkeypatch.delenv("SLAMKIT_DATA", raising=False)
    monkeypatch.setenv("SLAMKIT_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(registry, "shared_datasets_dir", lambda: tmp_path / "no-shared")
    monkeypatch.setattr(registry, "gtsam_data_dir", lambda: None)
    return tmp_path


# --- coverage ---------------------------------------------------------------------------------


def test_every_manifest_file_is_registered_with_its_checksum(shared_datasets):
    manifest = (shared_datasets / "MANIFEST.md").read_text()
    index = re.findall(r"^\| `([^`]+)` \| ([\d,]+) \| `([0-9a-f]{64})` \|", manifest, re.M)
    assert len(index) == 79  # 62 files plus the raw recordings of 2026-11-23
    used = {f.path for e in registry.REGISTRY.values() for f in e.files}
    for rel, size, sha in index:
        assert rel in used, f"{rel} is in MANIFEST.md but in no registry entry"
        f = next(f for e in registry.REGISTRY.values() for f in e.files if f.path == rel)
        assert (f.sha256, f.size_bytes) == (sha, int(size.replace(",", "")))


def test_every_wheel_file_is_used_and_every_entry_file_is_known():
    used = {f.wheel_name for e in registry.REGISTRY.values() for f in e.files if f.wheel_name}
    assert used == set(registry_table.WHEEL_FILES)
    for e in registry.REGISTRY.values():
        for f in e.files:
            assert f.path in registry_table.SHARED_FILES or f.wheel_name in registry_table.WHEEL_FILES


def test_names_are_lowercase_and_the_documented_ones_exist():
    assert all(n == n.lower() and " " not in n for n in registry.names())
    for name in ["intel", "city10000", "torus3d", "parking-garage", "kitti_00", "w10000", "sphere400",
                 "sphere2500", "cubicle", "csail-toro", "manhattan", "citytrees10000", "mrclam5a",
                 "torus2000points", "arena", "maze512-32-9", "w100", "w20000", "pose2example",
                 "pose3example", "sphere-smallnoise", "victoria-park", "klaus3", "example-graph"]:
        assert name in registry.REGISTRY, name
    kinds = {e.kind for e in registry.REGISTRY.values()}
    assert {"pose_graph_2d", "pose_graph_3d", "landmark_2d", "landmark_3d", "grid_map"} <= kinds


def test_one_naming_rule_case_and_dash_or_underscore_alike():
    # the registry keeps each source's spelling; typed names ignore case and '_' vs '-' (issue 32)
    assert registry.get("intel_log").name == "intel-log"
    assert registry.get("Kitti-00").name == "kitti_00"
    assert registry.get("PARKING_GARAGE").name == "parking-garage"
    keys = [registry.name_key(n) for n in registry.names()]
    assert len(set(keys)) == len(keys)  # the rule maps no two datasets onto one name
    with pytest.raises(DatasetNotFoundError, match=r"did you mean intel-log"):
        registry.get("intel_lgo")


def test_every_local_file_matches_its_sha256(shared_datasets):
    checked = 0
    for name in registry.names():
        for path, ok in registry.verify(name).items():
            assert ok is not False, f"{name}: {path} does not match its recorded sha256"
            checked += ok is True
    assert checked >= 62


# --- reference values -------------------------------------------------------------------------


def test_published_and_local_reference_values_are_flagged():
    torus = registry.get("torus3d")
    fstar = torus.reference("sesync_fstar")
    assert fstar.value == 24230.0 and fstar.published and fstar.objective == "sesync_F"
    local = torus.reference("gtsam_local_check")
    assert not local.published and local.value == 12117.6 and local.details["init"] == "chordal"
    assert registry.get("parking-garage").reference("sesync_fstar").value == 1.263
    assert registry.get("intel-carlone").reference("chi2_optimum").value == 215.8405
    # every MANIFEST local check is attached to exactly one entry
    attached = [e.primary.name for e in registry.REGISTRY.values() if e.reference("gtsam_local_check")]
    assert sorted(attached) == sorted(registry_table.GTSAM_LOCAL_CHECKS)
    assert {e.name for e in registry.REGISTRY.values() if e.reference("sesync_fstar")} == {
        "intel", "csail", "manhattan", "city10000", "ais2klinik", "sphere2500", "torus3d",
        "parking-garage", "cubicle"}


# --- every pose graph loads with its recorded counts ---------------------------------------------

POSE_GRAPHS = [n for n in registry.names() if registry.get(n).kind in registry.POSE_GRAPH_KINDS]
BIG = {"w10000", "w20000", "ais2klinik", "city10000", "cubicle", "torus3d", "sphere-bignoise",
       "sphere-smallnoise", "parking-garage", "sphere2500", "sphere2500-isam"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in BIG else n
                                  for n in POSE_GRAPHS])
def test_pose_graph_loads_with_recorded_counts(name):
    entry = registry.get(name)
    if not registry.is_available(entry):
        pytest.skip(f"{name} not available locally")
    graph, got = registry.load_pose_graph_source(name)
    assert got is entry and graph.name == name
    assert graph.dim == (2 if entry.kind == "pose_graph_2d" else 3)
    assert (graph.num_poses, graph.num_edges) == (entry.counts["poses"], entry.counts["edges"])
    check = entry.reference("gtsam_local_check")
    if check is not None:
        assert (check.details["poses"], check.details["edges"]) == (graph.num_poses, graph.num_edges)


def test_non_pose_graph_datasets_are_refused_by_the_pose_graph_loader():
    with pytest.raises(DataError, match="grid_map dataset, not a pose graph"):
        registry.load_pose_graph_source("arena")


# --- lookup --------------------------------------------------------------------------------


def test_resolve_names_paths_and_typos(tmp_path, shared_datasets):
    assert registry.resolve("Torus3D").name == "torus3d"
    assert registry.resolve("torus3D.g2o").name == "torus3d"  # a primary file name also works
    file = tmp_path / "mine.g2o"
    file.write_text("VERTEX_SE2 0 0 0 0\n")
    assert registry.resolve(str(file)) == file
    graph, entry = registry.load_pose_graph_source(str(file))
    assert entry is None and graph.num_poses == 1
    with pytest.raises(DatasetNotFoundError, match="did you mean torus3d"):
        registry.resolve("torus3")


def test_slamkit_data_overrides_everything(monkeypatch, tmp_path, shared_datasets):
    root = tmp_path / "mydata"
    (root / "pose_graph_2d").mkdir(parents=True)
    (root / "pose_graph_2d" / "intel.g2o").write_text(
        "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n")
    (root / "gtsam_data").mkdir()
    shutil.copy(shared_datasets / "pose_graph_2d" / "ring.g2o", root / "gtsam_data" / "w100.graph")
    monkeypatch.setenv("SLAMKIT_DATA", str(root))
    assert registry.search_roots()[0] == ("SLAMKIT_DATA", root)
    assert registry.path_of("intel") == root / "pose_graph_2d" / "intel.g2o"
    graph, _ = registry.load_pose_graph_source("intel")
    assert (graph.num_poses, graph.num_edges) == (2, 1)
    assert registry.locate(registry.get("w100").primary)[0] == "SLAMKIT_DATA"
    # files the override folder lacks still come from the next roots
    assert registry.locate(registry.get("torus3d").primary)[0] == "shared"
    assert not registry.verify("intel")["pose_graph_2d/intel.g2o"]  # the override is not the real file


def test_default_roots_are_shared_then_wheel_then_cache(monkeypatch):
    monkeypatch.delenv("SLAMKIT_DATA", raising=False)
    labels = [label for label, _ in registry.search_roots()]
    assert labels[0] == "shared" and labels[-1] == "cache"
    assert registry.shared_datasets_dir() == Path(registry.__file__).resolve().parents[3] / "shared" / "datasets"
    wheel = registry.gtsam_data_dir()
    if wheel is not None:
        assert labels == ["shared", "gtsam_wheel", "cache"] and (wheel / "w10000.graph").is_file()


def test_missing_dataset_error_lists_every_location(isolated):
    with pytest.raises(DatasetNotFoundError) as info:
        registry.path_of("w10000")
    message = str(info.value)
    assert str(isolated / "no-shared" / "gtsam_data" / "w10000.graph") in message
    assert str(isolated / "cache" / "gtsam_data" / "w10000.graph") in message
    assert "slamkit data fetch w10000" in message
    assert registry.available() == []
    with pytest.raises(DatasetNotFoundError, match="has no file"):
        registry.path_of("ring", "nope.txt")


def test_cache_is_the_last_root(isolated, shared_datasets):
    target = isolated / "cache" / "pose_graph_2d" / "ring.g2o"
    target.parent.mkdir(parents=True)
    shutil.copy(shared_datasets / "pose_graph_2d" / "ring.g2o", target)
    assert registry.path_of("ring") == target
    assert not registry.is_available(registry.get("ring"))  # ground-truth file still missing
    assert registry.verify("ring") == {"pose_graph_2d/ring.g2o": True,
                                       "pose_graph_2d/ring_groundtruth_poses.txt": None}


# --- ground truth -------------------------------------------------------------------------------


def test_ground_truth_files(shared_datasets):
    ring = registry.ground_truth("ring")
    assert len(ring) == 434 and ring.planar
    np.testing.assert_array_equal(ring.xytheta()[:3], [[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    assert registry.ground_truth("intel") is None
    assert len(registry.ground_truth("manhattan-olson")) == 3500


def test_city10000_ground_truth_agrees_with_its_odometry(shared_datasets):
    """ISAM2_GT_city10000.txt vs city10000.g2o: odometry residuals are at the noise level
    (information diag(2500, 2500, 10000) -> sigma 0.02 m, 0.01 rad)."""
    gt = registry.ground_truth("city10000")
    if gt is None or len(gt) != 10000:
        pytest.skip("gtsam wheel not installed")
    graph, _ = registry.load_pose_graph_source("city10000")
    p = gt.xytheta()
    odo = graph.is_odometry()
    i, j = graph.edge_from[odo], graph.edge_to[odo]
    d = p[j, :2] - p[i, :2]
    c, s = np.cos(p[i, 2]), np.sin(p[i, 2])
    rel = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
    err = rel - graph.measurements[odo, :2]
    assert np.sqrt(np.mean(err**2)) < 0.05


@pytest.mark.parametrize("name, tol", [("sphere2500", 1e-3), ("citytrees10000", 1e-3)])
def test_noise_free_ground_truth_closes_every_loop(name, tol):
    """Composing the noise-free edges must also satisfy every loop closure of the same file:
    proves the Euler -> quaternion convention and the composition order (a wrong convention is
    off by metres; printed 6-digit precision accumulates to ~2e-4 m over sphere2500)."""
    entry = registry.get(name)
    if not registry.is_available(entry):
        pytest.skip(f"{name} not available")
    gt = registry.ground_truth(name)
    graph = read_isam(registry.path_of(name, entry.ground_truth_file))
    T = gt.matrices()
    closures = ~graph.is_odometry()
    assert closures.sum() > 0 or name == "citytrees10000"
    from scipy.spatial.transform import Rotation

    index = {int(v): k for k, v in enumerate(gt.stamps_s)}
    worst = 0.0
    for a, b, m in zip(graph.edge_from, graph.edge_to, graph.measurements):
        rel = np.linalg.inv(T[index[int(a)]]) @ T[index[int(b)]]
        if graph.dim == 3:
            meas = np.eye(4)
            meas[:3, :3] = Rotation.from_quat(m[[4, 5, 6, 3]]).as_matrix()
            meas[:3, 3] = m[:3]
        else:
            meas = np.eye(4)
            meas[:2, :2] = [[np.cos(m[2]), -np.sin(m[2])], [np.sin(m[2]), np.cos(m[2])]]
            meas[:2, 3] = m[:2]
        worst = max(worst, np.abs(rel - meas).max())
    assert worst < tol


@pytest.mark.parametrize("text, line, message", [
    ("0 0 0 0\n1 1 0\n", 2, "expected 4 numbers"),
    ("0 0 0 0\n1 x 0 0\n", 2, "field 2 is 'x'"),
    ("0 0 0 0\n0 1 0 0\n", 2, "appears twice"),
    ("0 0 0 0\n1 nan 0 0\n", 2, "NaN"),
])
def test_ground_truth_bad_input(tmp_path, text, line, message):
    path = tmp_path / "gt.txt"
    path.write_text(text)
    with pytest.raises(DataError, match=message) as info:
        read_id_x_y_theta(path)
    assert info.value.line == line


def test_ground_truth_empty_and_unknown_format(tmp_path):
    path = tmp_path / "gt.txt"
    path.write_text("\n")
    with pytest.raises(DataError, match="empty"):
        read_x_y_theta(path)
    with pytest.raises(DataError, match="unknown ground-truth format"):
        read_ground_truth(path, "tum")


def test_registry_and_readers_do_not_import_gtsam():
    """slamkit.data finds the wheel's Data folder with importlib.util.find_spec, never by import."""
    import subprocess
    import sys

    code = ("import sys; from slamkit.data import registry; registry.available(); "
            "registry.load_pose_graph_source('w100'); print('gtsam' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"
