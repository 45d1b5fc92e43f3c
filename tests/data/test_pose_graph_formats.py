"""g2o / TORO / iSAM readers: worked examples, every documented bad-input outcome, and a
write -> read round trip (hypothesis)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.data.formats import (
    connected_components,
    detect_pose_graph_format,
    load_pose_graph,
    read_g2o,
    read_isam,
    read_isam_with_landmarks,
    read_toro,
    write_g2o,
)
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import DataError

INFO6 = "1 0 0 1 0 1"
INFO21 = " ".join("1" if c == r else "0" for r in range(6) for c in range(r, 6))


def write(tmp_path: Path, text: str, name: str = "g.g2o") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --- worked examples -----------------------------------------------------------------------


def test_g2o_2d_worked_example(tmp_path):
    path = write(tmp_path, "# comment\n"
                 "VERTEX_SE2 1 1.0 2.0 0.5\n"
                 "VERTEX_SE2 0 0 0 0\n"
                 "\n"
                 "EDGE_SE2 0 1 1.0 2.0 0.5 10 1 2 20 3 30\n"
                 "FIX 0\n")
    g = read_g2o(path)
    assert g.dim == 2 and g.has_initial
    assert g.vertex_ids.tolist() == [0, 1]  # sorted by id
    assert g.poses[1].tolist() == [1.0, 2.0, 0.5]
    assert g.measurements[0].tolist() == [1.0, 2.0, 0.5]
    assert g.information[0].tolist() == [[10, 1, 2], [1, 20, 3], [2, 3, 30]]
    assert "ignored 1 FIX lines" in g.notes


def test_g2o_3d_worked_example_quaternion_is_stored_wxyz(tmp_path):
    s = math.sqrt(0.5)
    info = " ".join(str(v) for v in range(1, 22))
    path = write(tmp_path, f"VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 2 3 0 0 {s} {s}\n"
                 f"EDGE_SE3:QUAT 0 1 1 2 3 0 0 {s} {s} {info}\n")
    g = read_g2o(path)
    assert g.dim == 3
    np.testing.assert_allclose(g.poses[1], [1, 2, 3, s, 0, 0, s], rtol=0, atol=1e-15)
    assert g.information[0][0].tolist() == [1, 2, 3, 4, 5, 6]
    assert g.information[0][1].tolist() == [2, 7, 8, 9, 10, 11]
    assert g.information[0][5].tolist() == [6, 11, 15, 18, 20, 21]


def test_vertexless_g2o_chains_edges_in_file_order(tmp_path):
    path = write(tmp_path, f"EDGE_SE2 0 1 1 0 {math.pi / 2} {INFO6}\nEDGE_SE2 1 2 1 0 0 {INFO6}\n"
                 f"EDGE_SE2 2 0 0 0 0 {INFO6}\n")
    g = read_g2o(path)
    assert not g.has_initial
    np.testing.assert_allclose(g.poses, [[0, 0, 0], [1, 0, math.pi / 2], [1, 1, math.pi / 2]], atol=1e-15)


def test_g2o_angles_outside_pi_are_wrapped_like_gtsam(tmp_path):
    g = read_g2o(write(tmp_path, f"VERTEX_SE2 0 0 0 5.0\nVERTEX_SE2 1 0 0 0\nEDGE_SE2 0 1 0 0 -4 {INFO6}\n"))
    assert g.poses[0, 2] == pytest.approx(5.0 - 2 * math.pi, abs=1e-15)
    assert g.measurements[0, 2] == pytest.approx(2 * math.pi - 4.0, abs=1e-15)


def test_toro_information_order_is_xx_xy_yy_tt_xt_yt(tmp_path):
    g = read_toro(write(tmp_path, "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nEDGE2 0 1 1 0 0 1 2 3 4 5 6\n",
                        "g.graph"))
    assert g.information[0].tolist() == [[1, 2, 5], [2, 3, 6], [5, 6, 4]]


def test_isam_2d_information_is_r_transpose_r(tmp_path):
    g = read_isam(write(tmp_path, "EDGE2 0 1 1 0 0 2 1 0 3 0 4\n", "g.txt"))
    # R = [[2,1,0],[0,3,0],[0,0,4]] -> R^T R
    assert g.information[0].tolist() == [[4, 2, 0], [2, 10, 0], [0, 0, 16]]
    assert g.poses.tolist() == [[0, 0, 0], [1, 0, 0]]


def test_isam_3d_euler_to_quaternion_and_landmarks(tmp_path):
    sqrt_info = " ".join("2" if c == r else "0" for r in range(6) for c in range(r, 6))
    text = (f"EDGE3 0 1 1 2 3 0 0 {math.pi / 2} {sqrt_info}\n"
            f"EDGE3 1 2 0 0 0 {math.pi / 2} 0 0\n"  # no information -> identity
            "POINT3 1 7 1 2 3 10 0 0 10 0 10\n")
    g, lm = read_isam_with_landmarks(write(tmp_path, text, "g.txt"))
    c = math.sqrt(0.5)
    np.testing.assert_allclose(g.measurements[0], [1, 2, 3, c, 0, 0, c], atol=1e-15)
    np.testing.assert_allclose(g.measurements[1], [0, 0, 0, c, c, 0, 0], atol=1e-15)  # roll pi/2
    np.testing.assert_allclose(g.information[0], 4 * np.eye(6))
    np.testing.assert_allclose(g.information[1], np.eye(6))
    assert "1 EDGE3 lines carry no information: identity used" in g.notes
    assert lm.dim == 3 and len(lm) == 1 and lm.landmark_id.tolist() == [7]
    np.testing.assert_allclose(lm.information[0], 100 * np.eye(3))
    assert "ignored 1 POINT3 lines" in read_isam(write(tmp_path, text, "g.txt")).notes


def test_isam_landmarks_on_city_trees(shared_datasets):
    g, lm = read_isam_with_landmarks(shared_datasets / "landmark_2d/cityTrees10000.txt")
    # counts from the MANIFEST / iSAM data README
    assert (g.num_poses, g.num_edges, len(lm), lm.num_landmarks) == (10000, 9999, 4443, 100)
    np.testing.assert_allclose(g.information[0], np.diag([2500.0, 2500.0, 10000.0]))


def test_format_detection(tmp_path):
    assert detect_pose_graph_format(write(tmp_path, f"EDGE_SE2 0 1 0 0 0 {INFO6}\n", "a.txt")) == "g2o"
    assert detect_pose_graph_format(write(tmp_path, "EDGE2 0 1 0 0 0 1 0 1 1 0 0\n", "a.graph")) == "toro"
    assert detect_pose_graph_format(write(tmp_path, "EDGE2 0 1 0 0 0 1 0 0 1 0 1\n", "a.txt")) == "isam"
    assert detect_pose_graph_format(write(tmp_path, "VERTEX2 0 0 0 0\n", "b.txt")) == "toro"
    g = load_pose_graph(write(tmp_path, "EDGE2 0 1 0 0 0 2 0 0 2 0 2\n", "c.txt"))
    assert g.information[0, 0, 0] == 4.0  # read as iSAM (square root)
    with pytest.raises(DataError, match="cannot tell"):
        detect_pose_graph_format(write(tmp_path, "HELLO 1 2\n", "d.dat"))
    # TORO tags in a .g2o file: g2o's information order (gtsam's w100_30.g2o)
    g2o_ordered = write(tmp_path, "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nEDGE2 0 1 1 0 0 1 2 3 4 5 6\n", "e.g2o")
    assert detect_pose_graph_format(g2o_ordered) == "toro_g2o_order"
    assert load_pose_graph(g2o_ordered).information[0].tolist() == [[1, 2, 3], [2, 4, 5], [3, 5, 6]]


# --- bad input: each documented outcome ----------------------------------------------------


@pytest.mark.parametrize("text, line, message", [
    (f"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0\nEDGE_SE2 0 1 0 0 0 {INFO6}\n", 2, "needs 4 fields"),
    (f"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0\nEDGE_SE2 0 1 0 x 0 {INFO6}\n", 3, "field 4 is 'x'"),
    (f"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1.5 0 0 0\nEDGE_SE2 0 1 0 0 0 {INFO6}\n", 2, "integer id"),
    (f"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0\n\nEDGE_SE2 0 1 0 nan 0 {INFO6}\n", 4, "NaN or infinity"),
    (f"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0\nEDGE_SE2 0 1 0 0 0 1 0 0 inf 0 1\n", 3, "NaN or infinity"),
    (f"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0\nEDGE_SE2 0 1 0 0 0 {INFO6}\nEDGE_SE2 1 7 0 0 0 {INFO6}\n",
     4, "vertex 7"),
    (f"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 0 1 0 0\nEDGE_SE2 0 0 0 0 0 {INFO6}\n", 2, "declared twice"),
    (f"VERTEX_SE2 0 0 0 0\nVERTEX_SE3:QUAT 1 0 0 0 0 0 0 1\n", 2, "mixes 2D"),
    ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 0\n", 1, "zero quaternion"),
    ("0 1 2 3\n", 1, "starts with the number"),
])
def test_malformed_g2o_names_file_and_line(tmp_path, text, line, message):
    path = write(tmp_path, text)
    with pytest.raises(DataError, match=message) as info:
        read_g2o(path)
    assert info.value.line == line and info.value.path == str(path)
    assert str(info.value).startswith(f"{path}:{line}: ")


@pytest.mark.parametrize("reader, text, line", [
    (read_toro, "VERTEX2 0 0 0 0\nVERTEX2 1 0 0 0\nEDGE2 0 1 0 0 0 1 0 1 1 0\n", 3),
    (read_toro, "VERTEX2 0 0 0 0\nEDGE2 0 3 0 0 0 1 0 1 1 0 0\n", 2),
    (read_isam, "EDGE2 0 1 0 0 0 1 0 0 1 0 1\nEDGE2 1 2 0 0 0 1 0 0 1 0 nan\n", 2),
    (read_isam, "EDGE3 0 1 0 0 0 0 0 0 1 2 3\n", 1),
    (read_isam_with_landmarks, "EDGE2 0 1 0 0 0 1 0 0 1 0 1\nLANDMARK 5 1 0 0 1 0 1\n", 2),
])
def test_malformed_toro_and_isam_name_the_line(tmp_path, reader, text, line):
    with pytest.raises(DataError) as info:
        reader(write(tmp_path, text, "g.txt"))
    assert info.value.line == line


@pytest.mark.parametrize("reader, name, text, line", [
    # issue 31: one such EDGE2 line made `slamkit optimize` fail with numpy's LinAlgError
    (read_isam, "g.isam", "EDGE2 0 1 1e300 0 0 1 0 0 1 0 1\n", 1),
    # |t|^2 = 1e310 overflows; 1e154 (below) does not
    (read_isam, "g.isam", "EDGE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE2 1 2 1e155 0 0 1 0 0 1 0 1\n", 2),
    # t^T I t = 1e100^2 * (1e100)^2 (iSAM stores the square root of the information) overflows
    (read_isam, "g.isam", "EDGE2 0 1 1e100 0 0 1e100 0 0 1 0 1\n", 1),
    (read_g2o, "g.g2o", f"EDGE_SE2 0 1 1e300 0 0 {INFO6}\n", 1),
    (read_g2o, "g.g2o", f"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1e300 0 0 {INFO6}\n", 3),
    (read_g2o, "g.g2o", f"EDGE_SE3:QUAT 0 1 0 0 1e200 0 0 0 1 {INFO21}\n", 1),
    (read_toro, "g.graph", "EDGE2 0 1 1e300 0 0 1 0 1 1 0 0\n", 1),
])
def test_a_translation_whose_squared_error_overflows_is_refused_at_its_line(tmp_path, reader, name, text, line):
    with pytest.raises(DataError, match=r"edge translation \(.*\) is too large: its squared error overflows") as info:
        reader(write(tmp_path, text, name))
    assert info.value.line == line and info.value.path == str(tmp_path / name)


def test_the_largest_translation_whose_square_is_finite_is_read(tmp_path):
    graph = read_isam(write(tmp_path, "EDGE2 0 1 1e154 0 0 1 0 0 1 0 1\n", "g.isam"))
    assert graph.measurements[0, 0] == 1e154 and graph.information[0, 0, 0] == 1.0


def test_optimize_refuses_an_overflowing_isam_edge_in_one_line_exit_2(tmp_path):
    from typer.testing import CliRunner

    from slamkit.cli import app

    path = write(tmp_path, "EDGE2 0 1 1e300 0 0 1 0 0 1 0 1\n", "one.isam")
    result = CliRunner().invoke(app, ["optimize", str(path)])
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines() == [
        f"error: {path}:1: edge translation (1e+300, 0) is too large: its squared error overflows to infinity"]


@pytest.mark.parametrize("text", ["", "# only a comment\n\n", "FIX 0\n"])
def test_empty_graph_is_an_error(tmp_path, text):
    with pytest.raises(DataError, match="empty graph"):
        read_g2o(write(tmp_path, text))


def test_missing_file_is_a_data_error(tmp_path):
    with pytest.raises(DataError, match="no such file"):
        read_g2o(tmp_path / "nope.g2o")


def test_binary_file_is_a_data_error(tmp_path):
    path = tmp_path / "blob.g2o"
    path.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(DataError, match="not a text file"):
        read_g2o(path)
    with pytest.raises(DataError, match="not a text file"):
        load_pose_graph(path)  # .g2o suffix: detection falls back to g2o, which refuses it
    with pytest.raises(DataError, match="cannot tell"):
        load_pose_graph(path.rename(tmp_path / "blob.bin"))


def test_vertices_without_edges_are_a_valid_graph(tmp_path):
    g = read_g2o(write(tmp_path, "VERTEX_SE2 0 0 0 0\n"))
    assert g.num_poses == 1 and g.num_edges == 0


NON_PD = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE2 0 1 1 0 0 1 2 0 1 0 1\n"


def test_non_pd_information_policy_keep_repair_reject(tmp_path):
    path = write(tmp_path, NON_PD)
    kept = read_g2o(path)
    assert kept.information[1].tolist() == [[1, 2, 0], [2, 1, 0], [0, 0, 1]]  # eigenvalues -1, 1, 3
    assert "non_pd_information: 1 of 2 edges kept as given (first at line 4)" in kept.notes
    repaired = read_g2o(path, policy="repair")
    vals = np.linalg.eigvalsh(repaired.information[1])
    np.testing.assert_allclose(vals, [3e-9, 1, 3], rtol=1e-6)  # -1 clipped to 1e-9 * 3
    assert repaired.information[0].tolist() == np.eye(3).tolist()  # PD edges untouched
    assert any(n.startswith("non_pd_information: 1 of 2 edges repaired") for n in repaired.notes)
    with pytest.raises(DataError, match="not positive definite") as info:
        read_g2o(path, policy="reject")
    assert info.value.line == 4
    with pytest.raises(DataError, match="unknown information policy"):
        read_g2o(path, policy="ignore")


def test_disconnected_graph_is_noted_and_components_are_labelled(tmp_path):
    text = "".join(f"VERTEX_SE2 {i} 0 0 0\n" for i in range(5))
    text += f"EDGE_SE2 0 1 1 0 0 {INFO6}\nEDGE_SE2 3 2 1 0 0 {INFO6}\n"
    g = read_g2o(write(tmp_path, text))
    assert "disconnected: 3 connected components" in g.notes
    count, labels = connected_components(g)
    assert count == 3
    assert labels[0] == labels[1] and labels[2] == labels[3]
    assert len({labels[0], labels[2], labels[4]}) == 3


def test_connected_benchmark_has_one_component(shared_datasets):
    g = read_g2o(shared_datasets / "pose_graph_2d/intel.g2o")
    assert connected_components(g)[0] == 1
    assert not any(n.startswith("disconnected") for n in g.notes)


# --- writer --------------------------------------------------------------------------------


def _random_graph(dim: int, n: int, seed: int) -> PoseGraph:
    rng = np.random.default_rng(seed)
    ids = np.sort(rng.choice(10 * n, size=n, replace=False))
    edge_from = rng.choice(ids, size=2 * n)
    edge_to = rng.choice(ids, size=2 * n)
    k = 3 if dim == 2 else 6

    def poses(m):
        if dim == 2:
            return np.column_stack([rng.normal(size=(m, 2)) * 100, rng.uniform(-np.pi, np.pi, m)])
        q = rng.normal(size=(m, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        return np.column_stack([rng.normal(size=(m, 3)) * 100, q])

    a = rng.normal(size=(2 * n, k, k))
    info = np.einsum("mij,mkj->mik", a, a) + np.eye(k)
    return PoseGraph(dim=dim, vertex_ids=ids, poses=poses(n), edge_from=edge_from, edge_to=edge_to,
                     measurements=poses(2 * n), information=info)


@settings(max_examples=25, deadline=None)
@given(dim=st.sampled_from([2, 3]), n=st.integers(1, 30), seed=st.integers(0, 2**31))
def test_write_then_read_round_trips(tmp_path_factory, dim, n, seed):
    graph = _random_graph(dim, n, seed)
    path = write_g2o(tmp_path_factory.mktemp("rt") / "out.g2o", graph)
    back = read_g2o(path)
    assert np.array_equal(back.vertex_ids, graph.vertex_ids)
    assert np.array_equal(back.edge_from, graph.edge_from) and np.array_equal(back.edge_to, graph.edge_to)
    # floats are written with repr precision: exact, except quaternions re-normalised on read
    np.testing.assert_allclose(back.poses, graph.poses, rtol=0, atol=1e-15 if dim == 3 else 0)
    np.testing.assert_allclose(back.measurements, graph.measurements, rtol=0,
                               atol=1e-15 if dim == 3 else 0)
    np.testing.assert_allclose(back.information, graph.information, rtol=1e-15, atol=0)


def test_write_is_atomic_and_replaces(tmp_path):
    g = _random_graph(2, 4, 0)
    target = tmp_path / "sub" / "g.g2o"
    write_g2o(target, g)
    write_g2o(target, _random_graph(2, 5, 1))
    assert read_g2o(target).num_poses == 5
    assert sorted(p.name for p in target.parent.iterdir()) == ["g.g2o"]  # no temporary left behind


# --- parser properties ---------------------------------------------------------------------

FLOAT_FORMATS = ["{!r}", "{:.6g}", "{:e}", "{:+.3f}", "{:.17g}", "{:.0f}."]


@settings(max_examples=40, deadline=None)
@given(values=st.lists(st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12),
                       min_size=9, max_size=9),
       formats=st.lists(st.sampled_from(FLOAT_FORMATS), min_size=9, max_size=9))
def test_numbers_parse_exactly_like_python_float(tmp_path_factory, values, formats):
    tokens = [fmt.format(v) for fmt, v in zip(formats, values)]
    path = tmp_path_factory.mktemp("num") / "g.g2o"
    path.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0\nEDGE_SE2 0 1 " + "\t ".join(tokens) + "\n")
    g = read_g2o(path, policy="keep")
    expected = [float(t) for t in tokens]
    assert g.measurements[0, :2].tolist() == expected[:2]
    # angles are wrapped only when outside (-pi, pi]
    theta = expected[2]
    if -math.pi < theta <= math.pi:
        assert g.measurements[0, 2] == theta
    upper = g.information[0][np.triu_indices(3)]
    assert upper.tolist() == expected[3:]


@settings(max_examples=40, deadline=None)
@given(n=st.integers(3, 40), data=st.data())
def test_a_corrupted_token_is_reported_at_its_line(tmp_path_factory, n, data):
    lines = [f"VERTEX_SE2 {i} {i}.5 0 0.1" for i in range(n)]
    lines += [f"EDGE_SE2 {i} {i + 1} 1 0 0 {INFO6}" for i in range(n - 1)]
    k = data.draw(st.integers(0, len(lines) - 1), label="line")
    tokens = lines[k].split()
    col = data.draw(st.integers(2, len(tokens) - 1), label="field")
    garbage = data.draw(st.sampled_from(["x", "1.2.3", "--1", "nan", "inf", "0x10", "", "1 2"]))
    tokens[col] = garbage
    lines[k] = " ".join(tokens)
    path = tmp_path_factory.mktemp("bad") / "g.g2o"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError) as info:
        read_g2o(path)
    assert info.value.line == k + 1
