"""TUM and KITTI trajectory files: worked examples, round trips (hypothesis), bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from slamkit.data.formats.kitti import read_kitti, read_kitti_calib, write_kitti
from slamkit.data.formats.tum import read_tum, write_tum
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.geometry import so3


def test_read_tum_worked_example(tmp_path: Path):
    f = tmp_path / "est.txt"
    f.write_text("# timestamp tx ty tz qx qy qz qw\n"
                 "1305031102.175304 1.0 2.0 3.0 0 0 0.7071067811865476 0.7071067811865476\n"
                 "\n"
                 "1305031102.211214,1.5,2.0,3.0,0,0,0,1\n")
    traj = read_tum(f)
    assert len(traj) == 2
    np.testing.assert_allclose(traj.stamps_s, [1305031102.175304, 1305031102.211214])
    np.testing.assert_allclose(traj.world_t_body[0], [1, 2, 3])
    # scalar-last in the file, wxyz in memory: a 90 degree yaw
    np.testing.assert_allclose(traj.world_q_body_wxyz[0], [np.sqrt(0.5), 0, 0, np.sqrt(0.5)])
    np.testing.assert_allclose(traj.xytheta()[0], [1, 2, np.pi / 2])


def test_read_kitti_worked_example(tmp_path: Path):
    f = tmp_path / "00.txt"
    f.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n"
                 "0 -1 0 5.5 1 0 0 -2 0 0 1 0.25\n")
    traj = read_kitti(f)
    np.testing.assert_array_equal(traj.stamps_s, [0.0, 1.0])
    np.testing.assert_allclose(traj.world_t_body[1], [5.5, -2, 0.25])
    np.testing.assert_allclose(traj.xytheta()[1], [5.5, -2, np.pi / 2])
    times = tmp_path / "times.txt"
    times.write_text("0.0\n0.103\n")
    np.testing.assert_allclose(read_kitti(f, times_path=times).stamps_s, [0.0, 0.103])


@st.composite
def trajectories(draw):
    n = draw(st.integers(1, 12))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    stamps = np.cumsum(rng.uniform(0.0, 2.0, n)) + draw(st.floats(0, 2e9))
    t = rng.normal(scale=draw(st.sampled_from([1e-6, 1.0, 1e4])), size=(n, 3))
    q = rng.normal(size=(n, 4))
    return Trajectory(stamps, t, q)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(trajectories())
def test_tum_round_trip(tmp_path: Path, traj: Trajectory):
    path = write_tum(tmp_path / "sub" / "t.txt", traj, header="written by a test\nsecond line")
    back = read_tum(path)
    np.testing.assert_array_equal(back.stamps_s, traj.stamps_s)
    np.testing.assert_array_equal(back.world_t_body, traj.world_t_body)
    np.testing.assert_allclose(back.world_q_body_wxyz, traj.world_q_body_wxyz, atol=1e-15)
    assert not list(path.parent.glob("*.tmp"))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(trajectories())
def test_kitti_round_trip(tmp_path: Path, traj: Trajectory):
    path = write_kitti(tmp_path / "k.txt", traj)
    back = read_kitti(path)
    np.testing.assert_array_equal(back.stamps_s, np.arange(len(traj)))
    np.testing.assert_array_equal(back.world_t_body, traj.world_t_body)
    np.testing.assert_allclose(back.matrices(), traj.matrices(), atol=1e-14)
    # same rotation (q and -q are equal rotations)
    np.testing.assert_allclose(so3.canonical_quat_wxyz(back.world_q_body_wxyz),
                               so3.canonical_quat_wxyz(traj.world_q_body_wxyz), atol=1e-14)


def test_write_is_atomic_and_replaces(tmp_path: Path):
    traj = Trajectory([0.0], [[1.0, 2.0, 3.0]], [[1.0, 0, 0, 0]])
    f = tmp_path / "t.txt"
    f.write_text("old content\n")
    write_tum(f, traj)
    assert f.read_text() == "0.0 1.0 2.0 3.0 0.0 0.0 0.0 1.0\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.txt"]


@pytest.mark.parametrize("reader, text, line, fragment", [
    (read_tum, "# c\n0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n", 3, "8 numbers, got 7"),
    (read_tum, "0 0 0 0 0 0 0 1\n\n1 0 x 0 0 0 0 1\n", 3, "field 3 is 'x'"),
    (read_tum, "0 0 0 0 0 0 0 1\n1 0 nan 0 0 0 0 1\n", 2, "NaN"),
    (read_tum, "0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 0\n", 2, "zero quaternion"),
    (read_tum, "2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", 2, "earlier"),
    (read_kitti, "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n", 2, "12 numbers, got 11"),
    (read_kitti, "1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 1 0 0 0 0 1 0\n", 2, "not a rotation"),
    (read_kitti, "1 0 0 0 0 1 0 0 0 0 1 inf\n", 1, "NaN or infinity"),
])
def test_malformed_line_names_file_and_line(tmp_path: Path, reader, text, line, fragment):
    f = tmp_path / "bad.txt"
    f.write_text(text)
    with pytest.raises(DataError) as info:
        reader(f)
    assert info.value.line == line
    assert info.value.path == str(f)
    assert fragment in str(info.value)
    assert f"{f}:{line}:" in str(info.value)


@pytest.mark.parametrize("reader", [read_tum, read_kitti])
def test_empty_or_missing_file(tmp_path: Path, reader):
    f = tmp_path / "empty.txt"
    f.write_text("# only a comment\n\n")
    with pytest.raises(DataError, match="no .* poses"):
        reader(f)
    with pytest.raises(DataError, match="no such file"):
        reader(tmp_path / "missing.txt")



@pytest.mark.parametrize("token", ["1_000", "\u0663", "\uff11"])
def test_non_ascii_decimal_tokens_are_not_numbers(tmp_path, token):
    # issue 10: float() accepts these; the shared token rule (slamkit._text) does not
    path = tmp_path / "t.tum"
    path.write_text(f"0 0 0 0 0 0 0 1\n1 {token} 0 0 0 0 0 1\n", encoding="utf-8")
    with pytest.raises(DataError) as info:
        read_tum(path)
    assert str(info.value) == f"{path}:2: field 2 is {token!r}, expected a number"


@pytest.mark.parametrize("brk", ["\x0c", "\x85", "\x1c", "\x1d", "\x1e", "\u2028", "\r"])
def test_only_newline_ends_a_line(tmp_path, brk):
    # issue 10: str.splitlines() also broke lines at these, so the error named line 3, not 2
    path = tmp_path / "k.txt"
    row = "1 0 0 0 0 1 0 0 0 0 1 0"
    path.write_text(f"{row}\n{row}{brk} 5\n{row}\n", encoding="utf-8", newline="")
    with pytest.raises(DataError) as info:
        read_kitti(path)
    assert str(info.value) == f"{path}:2: KITTI line needs 12 numbers, got 13"


P0 = "P0: 718.856 0 607.1928 0 0 718.856 185.2157 0 0 0 1 0\n"


def test_kitti_calib_worked_example_and_unnamed_lines(tmp_path: Path):
    path = tmp_path / "calib.txt"
    path.write_text(P0 + "1 0 0 -386.1448 0 1 0 0 0 0 1 0\n")
    calib = read_kitti_calib(path)
    assert list(calib) == ["P0", "P1"] and calib["P0"][0, 0] == 718.856 and calib["P1"][0, 3] == -386.1448


@pytest.mark.parametrize("data, line, fragment", [
    # issue 31: a non-UTF-8 calib.txt raised UnicodeDecodeError (exit 1 from the VO pipeline)
    (P0.encode() + b"P1: 7\xff8 0 0 0 0 1 0 0 0 0 1 0\n", 2, "not a text file (invalid start byte at byte 59)"),
    (b"\xfe" + P0.encode(), 1, "not a text file"),
    ((P0 + "P1: 1 0 0 0 0 1 0 0 0 0 1\n").encode(), 2, "a projection matrix needs 12 finite numbers, got 11"),
    ((P0 + "P1: 1 0 0 nan 0 1 0 0 0 0 1 0\n").encode(), 2, "a projection matrix needs 12 finite numbers"),
])
def test_kitti_calib_bad_bytes_name_file_and_line(tmp_path: Path, data, line, fragment):
    path = tmp_path / "calib.txt"
    path.write_bytes(data)
    with pytest.raises(DataError) as info:
        read_kitti_calib(path)
    assert info.value.path == str(path) and info.value.line == line and fragment in str(info.value)


def test_kitti_calib_missing_or_a_folder_is_a_data_error(tmp_path: Path):
    with pytest.raises(DataError, match="calib.txt: no such file"):
        read_kitti_calib(tmp_path / "calib.txt")
    with pytest.raises(DataError, match="is a directory, not a file"):
        read_kitti_calib(tmp_path)
