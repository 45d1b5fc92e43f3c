"""The registry table is a data file (TOML, issue 30): shipped as package data, read with the
standard library, every licence key resolved."""

from __future__ import annotations

import fnmatch
import tomllib
from pathlib import Path

import pytest

from slamkit.data import registry_table
from slamkit.errors import DataError

ROOT = Path(__file__).resolve().parents[2]


def test_the_table_is_package_data():
    """A fresh install must carry the file: pyproject's package-data globs match it (measured: with
    the line removed, ``setup.py build_py`` leaves it out and the import fails)."""
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["slamkit"]
    rel = f"data/{registry_table.TABLE_FILE}"
    assert (ROOT / "slamkit" / rel).is_file()
    assert any(fnmatch.fnmatch(rel, g) for g in globs), globs


def test_every_file_has_a_checksum_and_every_entry_a_licence():
    assert len(registry_table.SHARED_FILES) == 79 and len(registry_table.WHEEL_FILES) == 36
    for size, sha, *_ in [*registry_table.SHARED_FILES.values(), *registry_table.WHEEL_FILES.values()]:
        assert size > 0 and len(sha) == 64 and int(sha, 16) >= 0
    texts = set(registry_table.LICENCES.values())
    for name, entry in registry_table.ENTRIES.items():
        assert any(entry["licence"].startswith(t) for t in texts), name
    # a note is appended to its licence: the g2o file with Vertigo's ground truth
    assert registry_table.ENTRIES["manhattan-olson"]["licence"] == (
        f"{registry_table.LICENCES['g2o']} Ground truth: {registry_table.LICENCES['vertigo']}")


def test_an_unknown_licence_key_names_the_dataset():
    spec = {"kind": "trajectory", "format": "tum", "files": ["x.txt"], "title": "x", "licence": "nope"}
    with pytest.raises(DataError, match="'mine'.*'nope'"):
        registry_table._entry("mine", spec)
