"""build_graph, initial_values and the pose-layout conversions."""

from __future__ import annotations

import math

import gtsam
import numpy as np
import pytest
from gtsam.symbol_shorthand import X
from hypothesis import given, settings, strategies as st

from backend_reference import load
from slamkit.backend._convert import (poses_from_values, quat_wxyz_to_rotation,
                                      rotation_to_quat_wxyz, values_from_poses)
from slamkit.backend.graph import build_graph
from slamkit.backend.initialisation import initial_values
from slamkit.backend.solvers import OptimizeConfig, optimize
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import BackendError, ConfigError


def chain_2d(edges, meas, ids=(0, 1, 2), poses=None, info=None):
    n = len(ids)
    return PoseGraph(dim=2, vertex_ids=np.array(ids), poses=np.zeros((n, 3)) if poses is None else poses,
                     edge_from=np.array([e[0] for e in edges]), edge_to=np.array([e[1] for e in edges]),
                     measurements=np.array(meas, dtype=float),
                     information=np.tile(np.eye(3) if info is None else info, (len(edges), 1, 1)))


def test_build_graph_factors_keys_and_noise_2d():
    info = np.array([[10.0, 1.0, 0.5], [1.0, 20.0, 0.2], [0.5, 0.2, 30.0]])
    g = chain_2d([(4, 7), (7, 9)], [[1, 0, 0], [1, 0, 0.1]], ids=(4, 7, 9), info=info)
    fg, key_of = build_graph(g, prior_sigma=0.01)
    assert fg.size() == 3 and key_of == {4: X(4), 7: X(7), 9: X(9)}
    assert list(fg.at(0).keys()) == [X(4), X(7)] and list(fg.at(1).keys()) == [X(7), X(9)]
    R = fg.at(1).noiseModel().R()
    np.testing.assert_allclose(R.T @ R, info, rtol=1e-12)
    np.testing.assert_allclose(fg.at(1).measured().theta(), 0.1)
    prior_R = fg.at(2).noiseModel().R()
    np.testing.assert_allclose(prior_R, 100.0 * np.eye(3))  # 1 / prior_sigma


def test_build_graph_permutes_3d_information_to_rotation_first():
    info_g2o = np.diag([1.0, 2.0, 3.0, 40.0, 50.0, 60.0])
    info_g2o[0, 3] = info_g2o[3, 0] = 0.5  # x - rx coupling
    ident = [0, 0, 0, 1, 0, 0, 0.0]
    g = PoseGraph(dim=3, vertex_ids=np.array([0, 1]), poses=np.array([ident, ident]),
                  edge_from=np.array([0]), edge_to=np.array([1]),
                  measurements=np.array([[1, 2, 3, 1, 0, 0, 0.0]]), information=info_g2o[None])
    fg, _ = build_graph(g)
    R = fg.at(0).noiseModel().R()
    gtsam_info = R.T @ R
    np.testing.assert_allclose(np.diag(gtsam_info), [40, 50, 60, 1, 2, 3])
    assert gtsam_info[3, 0] == pytest.approx(0.5)
    np.testing.assert_allclose(fg.at(0).measured().translation(), [1, 2, 3])


@pytest.mark.parametrize("kind,cls", [("huber", gtsam.noiseModel.mEstimator.Huber),
                                      ("cauchy", gtsam.noiseModel.mEstimator.Cauchy)])
def test_build_graph_wraps_edges_in_robust_kernels(kind, cls):
    g = chain_2d([(0, 1), (1, 2)], [[1, 0, 0], [1, 0, 0]])
    fg, _ = build_graph(g, robust_kind=kind, robust_k=2.0)
    model = fg.at(0).noiseModel()
    assert isinstance(model, gtsam.noiseModel.Robust)
    assert isinstance(model.robust(), cls)
    # the gauge prior stays Gaussian
    assert not isinstance(fg.at(2).noiseModel(), gtsam.noiseModel.Robust)


def test_build_graph_rejects_bad_input():
    with pytest.raises(ConfigError):
        build_graph(chain_2d([(0, 1)], [[1, 0, 0]]), robust_kind="tukey")
    with pytest.raises(BackendError, match="unknown vertex ids \\[5\\]"):
        build_graph(chain_2d([(0, 5)], [[1, 0, 0]]))
    with pytest.raises(BackendError, match="NaN"):
        build_graph(chain_2d([(0, 1)], [[np.nan, 0, 0]]))
    with pytest.raises(BackendError, match="ids"):
        build_graph(chain_2d([(0, 1)], [[1, 0, 0]], ids=(0, 1, 1)))


def test_odometry_init_worked_example():
    """Edges 0->1 measure (1, 0, 90deg); the second edge is stored backwards (2->1 measuring the
    inverse of (1, 0, 90deg) = (0, 1, -90deg)), so chaining must invert it: X1 = (1, 0, 90deg),
    X2 = X1 (+) (1, 0, 90deg) = (1, 1, 180deg)."""
    g = chain_2d([(0, 1), (2, 1)], [[1, 0, math.pi / 2], [0, 1, -math.pi / 2]])
    init = initial_values(g, "odometry")
    assert init.method == "odometry"
    np.testing.assert_allclose(init.poses[1], [1, 0, math.pi / 2], atol=1e-12)
    np.testing.assert_allclose(init.poses[2][:2], [1, 1], atol=1e-12)
    assert abs(abs(init.poses[2][2]) - math.pi) < 1e-12


def test_odometry_init_bridges_a_missing_link_through_a_loop_closure():
    # no 1-2 edge: vertex 2 is reached via the 0-2 closure measuring (5, 0, 0)
    g = chain_2d([(0, 1), (0, 2)], [[1, 0, 0], [5, 0, 0]])
    np.testing.assert_allclose(initial_values(g, "odometry").poses[2], [5, 0, 0], atol=1e-12)


def test_disconnected_graph_is_a_backend_error():
    g = chain_2d([(0, 1)], [[1, 0, 0]], ids=(0, 1, 2))
    with pytest.raises(BackendError, match="disconnected"):
        initial_values(g, "odometry")


def test_init_methods_check_dimension():
    g2 = chain_2d([(0, 1), (1, 2)], [[1, 0, 0], [1, 0, 0]])
    with pytest.raises(ConfigError, match="3D"):
        initial_values(g2, "chordal")
    ident = [0, 0, 0, 1, 0, 0, 0.0]
    g3 = PoseGraph(dim=3, vertex_ids=np.array([0, 1]), poses=np.array([ident, ident]),
                   edge_from=np.array([0]), edge_to=np.array([1]), measurements=np.array([ident]),
                   information=np.eye(6)[None])
    with pytest.raises(ConfigError, match="2D"):
        initial_values(g3, "lago")
    with pytest.raises(ConfigError):
        initial_values(g3, "magic")


def test_lago_on_intel(shared_datasets):
    """LAGO (on marginal-sigma diagonal noise) starts intel at error 23.108 instead of the file's
    276.998; LM then needs 3 iterations to 22.5021 either way."""
    graph = load("pose_graph_2d/intel.g2o")
    result = optimize(graph, OptimizeConfig(init="lago"))
    assert result.init == "lago"
    assert result.initial_error == pytest.approx(23.1082, rel=1e-4)
    assert result.final_error == pytest.approx(22.5021, rel=1e-5)
    np.testing.assert_allclose(result.initial_poses[0], graph.poses[0], atol=1e-9)


def test_chordal_init_is_anchored_at_the_first_file_pose(shared_datasets):
    """tinyGrid3D moved rigidly by 10 m and 0.5 rad of yaw: chordal init must put pose 0 where the
    file does (InitializePose3 alone puts it at the origin) and reach the same error 9.31391."""
    graph = load("pose_graph_3d/tinyGrid3D.g2o")
    yaw = 0.5
    Rz = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]])
    R = quat_wxyz_to_rotation(graph.poses[:, 3:])
    moved = np.column_stack([graph.poses[:, :3] @ Rz.T + [10, 0, 0], rotation_to_quat_wxyz(Rz @ R)])
    shifted = PoseGraph(dim=3, vertex_ids=graph.vertex_ids, poses=moved, edge_from=graph.edge_from,
                        edge_to=graph.edge_to, measurements=graph.measurements,
                        information=graph.information)
    init = initial_values(shifted, "chordal")
    np.testing.assert_allclose(init.poses[0], moved[0], atol=1e-9)
    assert optimize(shifted, OptimizeConfig(init="chordal")).final_error == pytest.approx(9.31391, rel=1e-5)


@pytest.mark.slow
def test_chordal_on_cubicle_falls_back_to_odometry(shared_datasets):
    init = initial_values(load("pose_graph_3d/cubicle.g2o"), "chordal")
    assert init.method == "odometry"
    assert "fell back to odometry" in init.warnings[0]


def test_poses_from_values_follows_vertex_id_order_not_key_order():
    ids = np.array([5, 2, 9])
    poses = np.array([[5.0, 0, 0.5], [2.0, 0, 0.2], [9.0, 0, 0.9]])
    np.testing.assert_allclose(poses_from_values(2, ids, values_from_poses(2, ids, poses)), poses)


quats = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
    lambda q: np.linalg.norm(q) > 1e-3)


@settings(max_examples=200, deadline=None)
@given(quats)
def test_quaternion_round_trip(q):
    q = np.array(q) / np.linalg.norm(q)
    back = rotation_to_quat_wxyz(quat_wxyz_to_rotation(q[None]))[0]
    assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-9
    assert back[0] >= 0


@pytest.mark.parametrize("angle", [math.pi, math.pi - 1e-9, 1e-12, 0.0])
def test_quaternion_round_trip_near_identity_and_half_turn(angle):
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    q = np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])
    back = rotation_to_quat_wxyz(quat_wxyz_to_rotation(q[None]))[0]
    assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-9
    # agrees with GTSAM's own rotation matrix
    R = gtsam.Rot3.Quaternion(*q).matrix()
    np.testing.assert_allclose(quat_wxyz_to_rotation(q[None])[0], R, atol=1e-12)
