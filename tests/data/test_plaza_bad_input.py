"""Issue 31: a corrupt or incomplete Plaza ``.mat`` is a DataError naming the file, never a
TypeError, IndexError, zlib error or a crash of scipy's MAT parser. The files are written here
with ``scipy.io.savemat`` (a small run: 3 GT rows, 2 DR rows, 2 ranges, 1 beacon)."""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from slamkit.data.formats.plaza import read_plaza_sequence
from slamkit.data.sequence import Odometry, Range
from slamkit.errors import DataError

GT = np.array([[10.0, 0.0, 0.0, 0.0], [11.0, 1.0, 0.0, 0.0], [12.0, 2.0, 0.0, 0.0]])
TL = np.array([[7.0, 5.0, 0.0]])


def files(folder: Path, compress: bool = True, **tables) -> list[Path]:
    paths = [folder / "Plaza9_.mat", folder / "Plaza9_DR.txt", folder / "Plaza9_TD.txt"]
    savemat(paths[0], {"GT": GT, "TL": TL, **tables}, do_compression=compress)
    paths[1].write_text("11.0 1.0 0.0\n12.0 1.0 0.0\n")
    paths[2].write_text("11.0 2 7 4.0\n12.0 2 7 3.0\n")
    return paths


def test_the_small_run_reads(tmp_path: Path) -> None:
    seq = read_plaza_sequence(*files(tmp_path))
    assert len(seq.of_type(Odometry)) == 2 and [r.range_m[0] for r in seq.of_type(Range)] == [4.0, 3.0]


@pytest.mark.parametrize("tables, message", [
    ({"GT": np.zeros((0, 4))}, "the GT table has 0 rows; at least 2 are needed"),
    ({"GT": GT[:1]}, "the GT table has 1 rows; at least 2 are needed"),
    ({"TL": np.zeros((0, 3))}, "the TL table has 0 rows; at least 1 are needed"),
    ({"GT": np.array([["abcd"] * 4] * 3)}, r"the GT table is not numbers \(MAT class <U4\)"),
    ({"GT": np.array([[{"a": 1.0}] * 4] * 3, dtype=object)}, "the GT table is not numbers"),
])
def test_an_empty_or_non_numeric_table_is_a_data_error(tmp_path: Path, tables, message) -> None:
    paths = files(tmp_path, **tables)
    with pytest.raises(DataError, match=message) as info:
        read_plaza_sequence(*paths)
    assert info.value.path == str(paths[0])


def _corrupt(path: Path, offset: int, new: bytes) -> None:
    data = bytearray(path.read_bytes())
    data[offset:offset + len(new)] = new
    path.write_bytes(bytes(data))


def test_a_corrupt_compressed_element_is_caught_by_its_checksum(tmp_path: Path) -> None:
    paths = files(tmp_path)
    _corrupt(paths[0], 128 + 8 + 20, b"\xf8\x2c\xd6\xca")  # inside GT's deflate stream
    with pytest.raises(DataError, match=r"Plaza9_.mat: corrupt compressed MAT element at byte 128"):
        read_plaza_sequence(*paths)


def test_a_wrong_element_type_is_a_data_error_not_a_type_error(tmp_path: Path) -> None:
    # scipy raised TypeError("Expecting miMATRIX type here, got 3")
    paths = files(tmp_path, compress=False)
    _corrupt(paths[0], 128, struct.pack("<I", 3))
    with pytest.raises(DataError, match=r"not a readable MAT v5 file: TypeError: Expecting miMATRIX type here"):
        read_plaza_sequence(*paths)


@pytest.mark.parametrize("cut", [0, 100, 131, 200])
def test_a_truncated_file_is_a_data_error(tmp_path: Path, cut: int) -> None:
    paths = files(tmp_path)
    paths[0].write_bytes(paths[0].read_bytes()[:cut])
    with pytest.raises(DataError, match="Plaza9_.mat: "):
        read_plaza_sequence(*paths)


def test_the_bytes_that_crashed_scipy_are_refused_in_a_child_process(tmp_path: Path) -> None:
    # 4 bytes at offset 264 of the gtsam wheel's Plaza1_.mat made scipy.io.loadmat die with
    # SIGSEGV (scipy 1.17.1); a child process, so that a crash fails this test, not the run
    from slamkit.data import registry

    if not registry.is_available(registry.get("plaza1")):
        pytest.skip("the gtsam wheel's Plaza files are not available")
    mat = tmp_path / "Plaza1_.mat"
    mat.write_bytes(registry.path_of("plaza1", "Plaza1_.mat").read_bytes())
    _corrupt(mat, 264, bytes([0o370, 0o044, 0o326, 0o312]))
    code = ("import sys\nfrom slamkit.data.formats.plaza import _mat_tables\nfrom slamkit.errors import DataError\n"
            "try:\n    _mat_tables(__import__('pathlib').Path(sys.argv[1]))\nexcept DataError as e:\n    print(e)\n")
    done = subprocess.run([sys.executable, "-c", code, str(mat)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-500:]
    assert done.stdout.strip() == (f"{mat}: corrupt compressed MAT element at byte 128: Error -3 while "
                                   "decompressing data: incorrect data check")


def test_a_dead_reckoning_step_that_is_no_finite_speed_names_its_line(tmp_path: Path) -> None:
    """1e308 m over 0.5 s: before, v = inf reached the Sequence (found by the fuzzer)."""
    paths = files(tmp_path)
    paths[1].write_text("10.5 1e308 0.0\n12.0 1.0 0.0\n")
    with pytest.raises(DataError, match=r"Plaza9_DR\.txt:1: dead-reckoning step \(1e\+308 m, 0\.0 rad\) over 0\.5 s "
                                        r"is not a finite speed"):
        read_plaza_sequence(*paths)


def test_an_unknown_array_class_is_a_data_error(tmp_path: Path) -> None:
    """GT's array class byte (offset 144 of an uncompressed file: 128-byte header, miMATRIX tag,
    array-flags tag) set to 117, no MATLAB class: scipy's compiled reader raised UnboundLocalError
    (found by the fuzzer)."""
    paths = files(tmp_path, compress=False)
    data = bytearray(paths[0].read_bytes())
    assert data[144] == 6  # mxDOUBLE_CLASS
    data[144] = 117
    paths[0].write_bytes(bytes(data))
    with pytest.raises(DataError, match=r"Plaza9_\.mat: not a readable MAT v5 file: UnboundLocalError"):
        read_plaza_sequence(*paths)
