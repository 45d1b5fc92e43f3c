"""Our g2o / TORO / iSAM readers against gtsam's own parsers on the shared benchmark files:
same vertex ids, initial poses, edge endpoints, measurements and information (1e-12 relative)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

gtsam = pytest.importorskip("gtsam")

from slamkit.data.formats import load_pose_graph, read_g2o, read_isam, read_toro  # noqa: E402

GTSAM_DATA = Path(gtsam.__file__).parent / "Data"
# gtsam's Pose3 tangent is (rotation, translation); PoseGraph keeps g2o's (translation, rotation)
SWAP = np.zeros((6, 6))
SWAP[:3, 3:] = SWAP[3:, :3] = np.eye(3)

FAST_2D = ["pose_graph_2d/intel.g2o", "pose_graph_2d/CSAIL.g2o", "pose_graph_2d/input_MITb_g2o.g2o",
           "pose_graph_2d/ring.g2o", "pose_graph_2d_kitti/kitti_00.g2o"]
SLOW_2D = ["pose_graph_2d/input_INTEL_g2o.g2o", "pose_graph_2d/intel_g2o_943.g2o",
           "pose_graph_2d/manhattan.g2o", "pose_graph_2d/input_M3500_g2o.g2o",
           "pose_graph_2d/input_M3500b_g2o.g2o", "pose_graph_2d/manhattanOlson3500.g2o",
           "pose_graph_2d/city10000.g2o", "pose_graph_2d/ais2klinik.g2o", "pose_graph_2d/ringCity.g2o",
           *[f"pose_graph_2d_kitti/kitti_0{k}.g2o" for k in (2, 5, 6, 7, 8, 9)]]
FAST_3D = ["pose_graph_3d/tinyGrid3D.g2o", "pose_graph_3d/smallGrid3D.g2o", "pose_graph_3d/parking-garage.g2o"]
SLOW_3D = ["pose_graph_3d/sphere2500.g2o", "pose_graph_3d/torus3D.g2o",
           "pose_graph_3d/sphere_bignoise_vertex3.g2o", "pose_graph_3d/cubicle.g2o"]


def _close(a, b, rtol=1e-12):
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = np.maximum(1.0, np.maximum(np.abs(a), np.abs(b)))
    return bool(np.all(np.abs(a - b) <= rtol * scale))


def _pose3_row(p) -> np.ndarray:
    q = p.rotation().toQuaternion()
    return np.r_[p.translation(), q.w(), q.x(), q.y(), q.z()]


def _same_quat_sign(ours: np.ndarray, theirs: np.ndarray) -> np.ndarray:
    flip = np.sign(np.sum(ours[..., 3:] * theirs[..., 3:], axis=-1))
    out = theirs.copy()
    out[..., 3:] *= flip[..., None]
    return out


def compare_2d(graph, factors, values):
    assert factors.size() == graph.num_edges
    assert list(values.keys()) == graph.vertex_ids.tolist()
    poses = np.array([[p.x(), p.y(), p.theta()] for p in (values.atPose2(k) for k in values.keys())])
    if graph.has_initial:
        assert _close(graph.poses, poses)
    else:
        # chained poses accumulate rounding along thousands of compositions (gtsam's compiled
        # arithmetic may fuse multiply-adds): agree to 1e-12 of the trajectory's extent
        extent = max(1.0, float(np.abs(poses).max()))
        assert np.abs(graph.poses - poses).max() <= 1e-12 * extent
    meas, info = [], []
    for k in range(factors.size()):
        f = factors.at(k)
        assert tuple(f.keys()) == (graph.edge_from[k], graph.edge_to[k])
        m = f.measured()
        meas.append([m.x(), m.y(), m.theta()])
        info.append(f.noiseModel().information())
    assert _close(graph.measurements, meas)
    info = np.array(info)
    # gtsam stores information as R^T R; compare relative to each matrix's own scale
    scale = np.abs(info).max(axis=(1, 2), keepdims=True)
    assert np.all(np.abs(graph.information - info) <= 1e-12 * np.maximum(scale, 1.0))


@pytest.mark.parametrize("rel", FAST_2D + [pytest.param(r, marks=pytest.mark.slow) for r in SLOW_2D])
def test_g2o_2d_matches_gtsam(shared_datasets, rel):
    path = shared_datasets / rel
    graph = read_g2o(path)
    factors, values = gtsam.readG2o(str(path), False)
    compare_2d(graph, factors, values)
    no_vertices = "VERTEX_SE2" not in path.read_text()
    assert graph.has_initial is (not no_vertices)


@pytest.mark.parametrize("rel", FAST_3D + [pytest.param(r, marks=pytest.mark.slow) for r in SLOW_3D])
def test_g2o_3d_matches_gtsam(shared_datasets, rel):
    path = shared_datasets / rel
    graph = read_g2o(path)
    factors, values = gtsam.readG2o(str(path), True)
    assert factors.size() == graph.num_edges
    assert list(values.keys()) == graph.vertex_ids.tolist()
    poses = np.array([_pose3_row(values.atPose3(k)) for k in values.keys()])
    assert _close(graph.poses, _same_quat_sign(graph.poses, poses), 1e-12)
    non_pd = np.linalg.eigvalsh(graph.information)[:, 0] <= 0
    for k in range(factors.size()):
        f = factors.at(k)
        assert tuple(f.keys()) == (graph.edge_from[k], graph.edge_to[k])
        ours = graph.measurements[k]
        assert _close(ours, _same_quat_sign(ours, _pose3_row(f.measured())), 1e-12)
        if non_pd[k]:
            # gtsam factors a non-PD information with an unchecked Cholesky; passing ours through the
            # same constructor must give the identical square root (that is what 'keep' promises)
            mine = gtsam.noiseModel.Gaussian.Information(SWAP @ graph.information[k] @ SWAP)
            assert np.array_equal(mine.R(), f.noiseModel().R())
        else:
            theirs = SWAP @ f.noiseModel().information() @ SWAP
            assert np.all(np.abs(graph.information[k] - theirs) <= 1e-12 * max(1.0, np.abs(theirs).max()))


def test_cubicle_non_pd_count_is_noted(shared_datasets):
    graph = read_g2o(shared_datasets / "pose_graph_3d/cubicle.g2o")
    assert int((np.linalg.eigvalsh(graph.information)[:, 0] <= 0).sum()) == 5021
    assert any(n.startswith("non_pd_information: 5021 of 16869") for n in graph.notes)
    repaired = read_g2o(shared_datasets / "pose_graph_3d/cubicle.g2o", policy="repair")
    assert np.linalg.eigvalsh(repaired.information)[:, 0].min() > 0


@pytest.mark.parametrize("rel", ["pose_graph_2d/CSAIL_P_toro.graph", "pose_graph_2d/FR079_P_toro.graph",
                                 "pose_graph_2d/FRH_P_toro.graph"])
def test_toro_matches_gtsam(shared_datasets, rel):
    path = shared_datasets / rel
    graph = read_toro(path)
    factors, values = gtsam.load2D(str(path), None, 0, False, True, gtsam.NoiseFormat.NoiseFormatTORO)
    compare_2d(graph, factors, values)


@pytest.mark.parametrize("name", ["w100.graph", pytest.param("w10000.graph", marks=pytest.mark.slow)])
def test_toro_wheel_files_match_gtsam_and_equiv_is_ignored(name):
    path = GTSAM_DATA / name
    graph = read_toro(path)
    factors, values = gtsam.load2D(str(path), None, 0, False, True, gtsam.NoiseFormat.NoiseFormatTORO)
    compare_2d(graph, factors, values)
    n_equiv = sum(1 for line in path.read_text().splitlines() if line.startswith("EQUIV"))
    assert f"ignored {n_equiv} EQUIV lines" in graph.notes
    assert load_pose_graph(path).num_edges == graph.num_edges


def test_csail_g2o_and_toro_share_measurements(shared_datasets):
    """Same CSAIL measurements in two formats (the MANIFEST says the dx, dy, dtheta are identical)."""
    g2o = read_g2o(shared_datasets / "pose_graph_2d/CSAIL.g2o")
    toro = read_toro(shared_datasets / "pose_graph_2d/CSAIL_P_toro.graph")
    a = {(int(i), int(j)): m for i, j, m in zip(g2o.edge_from, g2o.edge_to, g2o.measurements)}
    b = {(int(i), int(j)): m for i, j, m in zip(toro.edge_from, toro.edge_to, toro.measurements)}
    assert set(a) == set(b) and len(a) == 1171  # 1,172 edges, one duplicated pair
    assert max(np.abs(a[k] - b[k]).max() for k in a) < 1e-6


def test_isam_sphere2500_matches_g2o_version(shared_datasets):
    """iSAM's sphere2500.txt and SE-Sync's sphere2500.g2o hold the same measurements: checks our
    roll-pitch-yaw -> quaternion conversion (to the g2o file's 6 printed digits) and R^T R."""
    isam = read_isam(GTSAM_DATA / "sphere2500.txt")
    g2o = read_g2o(shared_datasets / "pose_graph_3d/sphere2500.g2o")
    ia = np.lexsort((isam.edge_to, isam.edge_from))
    ib = np.lexsort((g2o.edge_to, g2o.edge_from))
    assert np.array_equal(isam.edge_from[ia], g2o.edge_from[ib])
    assert np.array_equal(isam.edge_to[ia], g2o.edge_to[ib])
    mine, theirs = isam.measurements[ia], g2o.measurements[ib]
    assert np.abs(mine - _same_quat_sign(mine, theirs)).max() < 1e-6
    # sqrt-information diag(10, 10, 10, 100, 100, 25) -> information diag(100, ..., 625)
    assert np.allclose(isam.information[0], np.diag([100, 100, 100, 1e4, 1e4, 625]))
    # gtsam.load3D parses the same rotation from x y z roll pitch yaw
    factors, _ = gtsam.load3D(str(GTSAM_DATA / "sphere2500.txt"))
    for k in range(5):
        ours = isam.measurements[k]
        assert _close(ours, _same_quat_sign(ours, _pose3_row(factors.at(k).measured())), 1e-12)


def test_toro_3d_vertices_match_gtsam_load3d():
    """VERTEX3 x y z roll pitch yaw -> quaternion agrees with gtsam.load3D's reading."""
    path = GTSAM_DATA / "sphere_smallnoise.graph"
    graph = read_toro(path)
    _, values = gtsam.load3D(str(path))
    assert list(values.keys()) == graph.vertex_ids.tolist()
    poses = np.array([_pose3_row(values.atPose3(k)) for k in values.keys()])
    assert _close(graph.poses, _same_quat_sign(graph.poses, poses), 1e-12)
    assert "8647 EDGE3 lines carry no information: identity used" in graph.notes
