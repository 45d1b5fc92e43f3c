"""The compiled text scanner (``slamkit/data/formats/_textscan.c``) against the Python/numpy path
it replaces: identical arrays (bit for bit) on every shared pose-graph file, identical DataError
messages on malformed input, and identical numbers for any decimal spelling (property test).

Each comparison reads the same file twice, once with ``SLAMKIT_NO_NATIVE=1``."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit import _native
from slamkit.data.formats import load_pose_graph, read_g2o, read_isam_with_landmarks, read_toro
from slamkit.data.formats._records import (
    TEXTSCAN_MODULE,
    read_records,
    smallest_eigenvalue_positive,
    textscan,
    vertex_rows,
)
from slamkit.errors import DataError

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "datasets"
GTSAM_DATA = Path(sys.prefix) / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" \
    / "site-packages" / "gtsam" / "Data"
FIELDS = ("vertex_ids", "poses", "edge_from", "edge_to", "measurements", "information")


def _pose_graph_files() -> list[Path]:
    files: list[Path] = []
    for folder in ("pose_graph_2d", "pose_graph_2d_kitti", "pose_graph_3d", "landmark_2d", "landmark_3d"):
        if (SHARED / folder).is_dir():
            files += sorted(p for p in (SHARED / folder).iterdir()
                            if p.suffix in (".g2o", ".graph", ".txt") and "groundtruth" not in p.name)
    if GTSAM_DATA.is_dir():
        files += sorted(p for p in GTSAM_DATA.iterdir() if p.suffix in (".g2o", ".graph", ".txt"))
    return files


needs_native = pytest.mark.skipif(textscan() is None,
                                  reason=f"no compiled scanner: {_native.unavailable_reason(TEXTSCAN_MODULE)}")


def _outcome(monkeypatch, native: bool, reader, path):
    """The reader's result, or the (type, message, line) of the DataError it raised."""
    if native:
        monkeypatch.delenv("SLAMKIT_NO_NATIVE", raising=False)
        assert textscan() is not None
    else:
        monkeypatch.setenv("SLAMKIT_NO_NATIVE", "1")
        assert textscan() is None
    try:
        return reader(path)
    except DataError as exc:
        return {"error": type(exc).__name__, "message": str(exc), "line": exc.line}
    finally:
        monkeypatch.delenv("SLAMKIT_NO_NATIVE", raising=False)


def _assert_same(a, b) -> None:
    if isinstance(a, dict) or isinstance(b, dict):  # a DataError on either side
        assert a == b
        return
    if isinstance(a, tuple):  # read_isam_with_landmarks' (graph, landmarks)
        (a, marks_a), (b, marks_b) = a, b
        assert (marks_a is None) == (marks_b is None)
        if marks_a is not None:
            for field in ("pose_id", "landmark_id", "body_p_landmark", "information"):
                assert getattr(marks_a, field).tobytes() == getattr(marks_b, field).tobytes()
    for field in FIELDS:
        x, y = getattr(a, field), getattr(b, field)
        assert x.dtype == y.dtype and x.shape == y.shape, field
        assert x.tobytes() == y.tobytes(), field  # bit for bit, NaN-safe, -0.0-aware
    assert (a.dim, a.has_initial, a.notes, a.name) == (b.dim, b.has_initial, b.notes, b.name)


def _params(files: list[Path]) -> list:
    """Files over 1.5 MB (except the benchmark's w10000.graph) only run with ``-m slow``."""
    return [pytest.param(p, id=f"{p.parent.name}/{p.name}",
                         marks=[pytest.mark.slow] if p.stat().st_size > 1_500_000
                         and p.name != "w10000.graph" else [])
            for p in files]


@needs_native
@pytest.mark.parametrize("path", _params(_pose_graph_files()))
def test_every_shared_pose_graph_loads_identically_with_and_without_native(monkeypatch, path):
    fast = _outcome(monkeypatch, True, load_pose_graph, path)
    slow = _outcome(monkeypatch, False, load_pose_graph, path)
    _assert_same(fast, slow)


INFO6 = "1 0 0 1 0 1"
GOOD_V = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n"
MALFORMED_G2O = [
    GOOD_V + f"EDGE_SE2 0 1 1 0 0 {INFO6} 7\n",             # one field too many
    GOOD_V + "EDGE_SE2 0 1 1 0 0 1 0 0 1 0\n",              # one too few
    GOOD_V + f"EDGE_SE2 0 1 1 x 0 {INFO6}\n",
    GOOD_V + f"EDGE_SE2 0 1 1 1_0 0 {INFO6}\n",             # float() takes it, numpy does not
    GOOD_V + f"EDGE_SE2 0 1 0x10 0 0 {INFO6}\n",            # strtod takes hex, numpy does not
    GOOD_V + f"EDGE_SE2 0 1 1e 0 0 {INFO6}\n",
    GOOD_V + f"EDGE_SE2 0 1 . 0 0 {INFO6}\n",
    GOOD_V + f"EDGE_SE2 0 1 nan(1) 0 0 {INFO6}\n",
    GOOD_V + f"EDGE_SE2 0 1 1 0 0 {INFO6} # trailing comment\n",
    GOOD_V + f"EDGE_SE2 0 1 -nan 0 0 {INFO6}\n",
    GOOD_V + f"EDGE_SE2 0 1 Infinity 0 0 {INFO6}\n",
    GOOD_V + f"EDGE_SE2 0 1 1e400 0 0 {INFO6}\n",           # overflows to inf in both parsers
    GOOD_V + f"EDGE_SE2 0.5 1 1 0 0 {INFO6}\n",
    GOOD_V + f"EDGE_SE2 0 1e20 1 0 0 {INFO6}\n",            # integral but beyond 2^53
    GOOD_V + "EDGE_SE2\n",
    GOOD_V + f"EDGE_SE2 0 7 1 0 0 {INFO6}\n",
    "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 0 1 0 0\n",
    "VERTEX_SE2 0 0 0\r\nVERTEX_SE2 1 0 0 0\r\n",            # CRLF, bad line 1
    "VERTEX_SE2 0 0 0 0\rVERTEX_SE2 1 0 0 0\rVERTEX_SE2 1 0 0 0\r",  # old-Mac line ends
    "VERTEX_SE2 0 0 0 0\x0cVERTEX_SE2 0 0 0 0\n",           # form feed: a line break for Python
    "VERTEX_SE2 0 0 0 0\x1fVERTEX_SE2 1 0 0 0\n",
    "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0 é\n",           # non-ASCII: the Python path decides
    "VERTEX_SE2 0 0 0 0\n\n   \n\t# c\nVERTEX_SE2\t1 0 x 0\n",
    "0 1 2 3\n",
    "",
    "# only a comment\n",
    "VERTEX_SE2 0 0 0 0\nVERTEX_SE3:QUAT 1 0 0 0 0 0 0 1\n",
    "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 0\n",
]
MALFORMED_OTHER = [
    (read_toro, "VERTEX2 0 0 0 0\nVERTEX2 1 0 0 0\nEDGE2 0 1 0 0 0 1 0 1 1 0\n"),
    (read_toro, "VERTEX2 0 0 0 0\nEDGE2 0 3 0 0 0 1 0 1 1 0 0\n"),
    (read_toro, "VERTEX3 0 0 0 0 0 0 0\nVERTEX3 1 0 0 0 0 0 0\nEDGE3 0 1 0 0 0 0 0 0 1 2\n"),
    (read_toro, "VERTEX2 0 0 0 0\nVERTEX3 0 0 0 0 0 0 0\n"),
    (read_isam_with_landmarks, "EDGE2 0 1 0 0 0 1 0 0 1 0 1\nODOMETRY 1 2 0 0 0 1 0 0 1 0 nan\n"),
    (read_isam_with_landmarks, "EDGE2 0 1 0 0 0 1 0 0 1 0 1\nLANDMARK 5 1 0 0 1 0 1\n"),
    (read_isam_with_landmarks, "EDGE2 0 1 0 0 0 1 0 0 1 0 1\nLANDMARK 1 1 0 0 1 0\n"),
]


@needs_native
@pytest.mark.parametrize("reader, text", [(read_g2o, t) for t in MALFORMED_G2O] + MALFORMED_OTHER)
def test_malformed_input_gives_the_same_error_either_way(tmp_path, monkeypatch, reader, text):
    path = tmp_path / "g.txt"
    path.write_bytes(text.encode("utf-8"))
    fast = _outcome(monkeypatch, True, reader, path)
    slow = _outcome(monkeypatch, False, reader, path)
    _assert_same(fast, slow)


VALID = [
    # tabs, leading blanks, comments, blank lines, CRLF, trailing blanks, ignored tags
    "# header\n\n  VERTEX_SE2 0 0 0 0\t\r\nVERTEX_SE2\t1\t1.5e+00\t-0.\t+.25  \r\nFIX 0\n"
    f"\tEDGE_SE2 0 1 1 0 0 {INFO6}\n#EDGE_SE2 9 9\nEQUIV 0 1\n",
    # no vertices: chained initial poses; no newline at the end
    f"EDGE_SE2 0 1 1 0 0.5 {INFO6}\nEDGE_SE2 1 2 1 0 4 {INFO6}",
    # numbers at the edges of the exact fast path (15/16/17/20 significant digits, 1e+-22/23)
    "VERTEX_SE2 0 0.123456789012345 1.2345678901234567 123456789012345678901\n"
    "VERTEX_SE2 1 1e22 1e23 1e-22\nVERTEX_SE2 2 1e-23 4.9e-324 2.2250738585072011e-308\n"
    "VERTEX_SE2 3 0.000000000000000000000000123 9007199254740993 -0.0\n",
]


@needs_native
@pytest.mark.parametrize("text", VALID)
def test_valid_edge_cases_read_identically(tmp_path, monkeypatch, text):
    path = tmp_path / "g.g2o"
    path.write_bytes(text.encode())
    fast = _outcome(monkeypatch, True, read_g2o, path)
    slow = _outcome(monkeypatch, False, read_g2o, path)
    assert not isinstance(fast, dict), fast
    _assert_same(fast, slow)


@pytest.mark.parametrize("no_native", ["", "1"])
def test_crlf_and_comment_line_numbers_worked_example(tmp_path, monkeypatch, no_native):
    # line 1 comment, 2 blank, 3 vertex, 4 vertex, 5 bad edge: the error names line 5 either way
    monkeypatch.setenv("SLAMKIT_NO_NATIVE", no_native)
    path = tmp_path / "g.g2o"
    path.write_bytes(b"# c\r\n\r\nVERTEX_SE2 0 0 0 0\r\nVERTEX_SE2 1 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0\n")
    with pytest.raises(DataError, match="EDGE_SE2 needs 11 fields after the tag, got 8") as info:
        read_g2o(path)
    assert info.value.line == 5
    blocks = read_records(path)
    assert {t: b.lines.tolist() for t, b in blocks.items()} == {"VERTEX_SE2": [3, 4], "EDGE_SE2": [5]}


@pytest.mark.parametrize("no_native", ["", "1"])
@pytest.mark.parametrize("brk", [b"\r", b"\x0c", b"\x0b", b"\x1c", b"\x1e", "\u0085".encode(), "\u2028".encode()])
def test_only_newline_ends_a_line(tmp_path, monkeypatch, no_native, brk):
    # issue 10: a lone CR, form feed, NEL, U+2028 ... stay inside their line (whitespace), so the
    # line numbers are what `sed -n Np` shows; both paths agree
    monkeypatch.setenv("SLAMKIT_NO_NATIVE", no_native)
    path = tmp_path / "g.g2o"
    path.write_bytes(b"VERTEX_SE2 0 0 0 0" + brk + b"\nVERTEX_SE2 1 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0\n")
    with pytest.raises(DataError) as info:
        read_g2o(path)
    assert str(info.value) == f"{path}:3: EDGE_SE2 needs 11 fields after the tag, got 8"
    path.write_bytes(b"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0" + brk + b"0 0\nEDGE_SE2 0 1 1 0 0 1 0 0\n")
    with pytest.raises(DataError) as info:
        read_g2o(path)
    assert str(info.value) == f"{path}:3: EDGE_SE2 needs 11 fields after the tag, got 8"


@pytest.mark.parametrize("no_native", ["", "1"])
@pytest.mark.parametrize("token", ["1_000", "\u0663", "\uff11"])
def test_non_ascii_digits_are_not_numbers(tmp_path, monkeypatch, no_native, token):
    monkeypatch.setenv("SLAMKIT_NO_NATIVE", no_native)
    path = tmp_path / "g.g2o"
    path.write_text(f"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 {token} 0 0\n", encoding="utf-8")
    with pytest.raises(DataError) as info:
        read_g2o(path)
    assert str(info.value) == f"{path}:2: VERTEX_SE2 field 2 is {token!r}, expected a number"


FORMATS = ["{!r}", "{:.6g}", "{:e}", "{:+.3f}", "{:.17g}", "{:.20e}", "{:.25f}", "{:.0f}.", "{:E}"]


@needs_native
@settings(max_examples=60, deadline=None)
@given(values=st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=3,
                       max_size=3),
       formats=st.lists(st.sampled_from(FORMATS), min_size=3, max_size=3))
def test_any_decimal_spelling_converts_to_the_same_bits(tmp_path_factory, values, formats):
    tokens = [fmt.format(v) for fmt, v in zip(formats, values)]
    data = f"VERTEX_SE2 0 {' '.join(tokens)}\n".encode()
    scanned = textscan().scan(data, "VERTEX_SE2", 4)
    assert scanned is not None
    ours = np.frombuffer(scanned[0], dtype=float)[1:]
    expected = np.array([float(t) for t in tokens])  # correctly rounded, like numpy's parser
    assert ours.tobytes() == expected.tobytes()
    assert np.frombuffer(scanned[1], dtype=np.int64).tolist() == [1]


@needs_native
def test_scanner_hands_unusual_lines_back_to_python():
    scanner = textscan()
    assert scanner.tags("A 1\nB 2\r\nA 3\n\n# x\n".encode()) is not None
    assert {k: np.frombuffer(v, np.int64).tolist() for k, v in scanner.tags(b"A 1\nB 2\r\nA 3\n# x\n").items()} \
        == {"A": [1, 3], "B": [2]}
    assert scanner.tags(b"A 1\x0b2\n") is None
    assert scanner.tags("A é\n".encode()) is None
    assert scanner.scan(b"A 1 2\nA 1 x\n", "A", 2) is None
    assert scanner.scan(b"A 1 2\nA 1\n", "A", 2) is None
    values, lines = scanner.scan(b"B x\nA 1 2\n  A\t3 -4e-1\n", "A", 2)
    assert np.frombuffer(values).tolist() == [1.0, 2.0, 3.0, -0.4]
    assert np.frombuffer(lines, np.int64).tolist() == [2, 3]


def test_every_kernel_is_built_at_install_and_nothing_is_compiled_at_run_time(tmp_path, monkeypatch):
    # setup.py compiles the four kernels when slamkit is installed (make setup does); the loader
    # only imports them: a shared object in the old user cache is never picked up
    monkeypatch.delenv("SLAMKIT_NO_NATIVE", raising=False)
    assert _native.status() == {name: "compiled" for name in _native.KERNELS}
    monkeypatch.setenv("SLAMKIT_CACHE", str(tmp_path))
    (tmp_path / "_answer_0123456789abcdef.so").write_bytes(b"\x7fELF not really")
    assert _native.load_extension("slamkit_test_pkg._answer") is None
    assert _native.unavailable_reason("slamkit_test_pkg._answer").startswith("not built: install slamkit")
    assert not hasattr(_native, "cache_dir") and not hasattr(_native, "_compile_and_load")
    monkeypatch.setenv("SLAMKIT_NO_NATIVE", "1")
    assert _native.load_extension(TEXTSCAN_MODULE) is None
    assert _native.unavailable_reason(TEXTSCAN_MODULE) == "disabled by SLAMKIT_NO_NATIVE"


# --- assemble's fast paths: Gershgorin pre-check and contiguous-id lookup ---------------------


@settings(max_examples=60, deadline=None)
@given(n=st.sampled_from([3, 6]), seed=st.integers(0, 2**32 - 1),
       log_scale=st.floats(-300, 300), shift=st.floats(-2.0, 2.0))
def test_positive_definite_precheck_agrees_with_eigvalsh(n, seed, log_scale, shift):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(40, n, n))
    sym = a @ np.swapaxes(a, 1, 2) / n + shift * np.eye(n)  # eigenvalues straddle 0 for shift < 0
    sym[::3] = np.diag(rng.uniform(0.5, 2.0, n)) + 0.1 * (a[::3] + np.swapaxes(a[::3], 1, 2))
    sym[1::5, -1, -1] = 0.0
    sym[2::7] = np.eye(n)
    sym *= 10.0 ** log_scale
    sym[0, 0, 1] += 1.0  # an asymmetric entry above the diagonal: both read the lower triangle
    expected = np.linalg.eigvalsh(sym)[:, 0] > 0.0
    assert np.array_equal(smallest_eigenvalue_positive(sym), expected)


@pytest.mark.parametrize("matrix, positive", [
    (np.eye(3), True), (np.diag([1.0, 1.0, 0.0]), False), ([[1.0, 2.0], [2.0, 1.0]], False),
    ([[2.0, 1.0], [1.0, 2.0]], True), ([[1.0, 5.0], [0.0, 1.0]], True),  # upper triangle unread
])
def test_positive_definite_precheck_on_one_matrix_for_every_edge(matrix, positive):
    batch = np.tile(np.asarray(matrix, dtype=float), (1000, 1, 1))
    assert smallest_eigenvalue_positive(batch).tolist() == [positive] * 1000
    assert (np.linalg.eigvalsh(batch)[:, 0] > 0).tolist() == [positive] * 1000


def test_vertex_rows_worked_examples():
    ends = np.array([5, 7, 3, 8])
    (rows,) = vertex_rows(np.array([5, 6, 7]), ends)  # contiguous: subtraction, then clipped
    assert rows.tolist() == [0, 2, 0, 2]
    (rows,) = vertex_rows(np.array([3, 5, 7]), ends)  # gaps: binary search
    assert rows.tolist() == [1, 2, 0, 2]
    assert vertex_rows(np.array([5, 3, 7]), ends) is None


@pytest.mark.parametrize("ids, missing", [("0 1 2", 7), ("5 6 7", 3), ("0 2 4", 1), ("0 2 4", 5)])
def test_edge_to_an_undeclared_vertex_is_found_with_or_without_gaps(tmp_path, ids, missing):
    text = "".join(f"VERTEX_SE2 {i} 0 0 0\n" for i in ids.split())
    first = ids.split()[0]
    text += f"EDGE_SE2 {first} {first} 1 0 0 {INFO6}\nEDGE_SE2 {first} {missing} 1 0 0 {INFO6}\n"
    path = tmp_path / "g.g2o"
    path.write_text(text)
    with pytest.raises(DataError, match=f"edge refers to vertex {missing},") as info:
        read_g2o(path)
    assert info.value.line == 5
