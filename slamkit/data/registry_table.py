"""The dataset registry's data, read from ``registry_table.toml`` beside this module.

The table is a data file (TOML, read with the standard library's :mod:`tomllib`), shipped inside
the package as package data (``[tool.setuptools.package-data]`` in pyproject.toml), so
``slamkit.data`` needs no YAML import and an installed slamkit finds it. Its comments say what
every field means. This module only turns it into the tables :mod:`slamkit.data.registry` builds
its entries from; read the registry, never this module, for anything else.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from typing import Any

from slamkit.errors import DataError

TABLE_FILE = "registry_table.toml"


def _load() -> dict[str, Any]:
    source = resources.files("slamkit.data").joinpath(TABLE_FILE)
    try:
        with source.open("rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise DataError(f"the dataset registry table is not valid TOML: {exc}", str(source)) from None


_TABLE = _load()

#: licence texts by key (an entry's ``licence`` names one)
LICENCES: dict[str, str] = dict(_TABLE["licences"])

#: every file of ../shared/datasets (MANIFEST.md file index): relative path ->
#: (bytes, sha256, source repository, path in it, commit, git blob)
SHARED_FILES: dict[str, tuple[int, str, str, str, str, str]] = {
    path: (f["bytes"], f["sha256"], f["repo"], f["path"], f["commit"], f["blob"])
    for path, f in _TABLE["shared_files"].items()}

#: files of the gtsam 4.3.0 wheel's Data folder we register: name -> (bytes, sha256 of the wheel's
#: copy, a borglab/gtsam commit whose examples/Data holds a file of that name, or None)
WHEEL_FILES: dict[str, tuple[int, str, str | None]] = {
    name: (f["bytes"], f["sha256"], f.get("commit")) for name, f in _TABLE["wheel_files"].items()}

#: MANIFEST 'gtsam local check' lines (NOT published values): file name ->
#: (edges, poses, init, optimizer, gtsam error at optimum, chi2 as printed, iterations, seconds,
#: SE-Sync F at that optimum or None)
GTSAM_LOCAL_CHECKS: dict[str, tuple[int, int, str, str, float, float, int, float, float | None]] = {
    name: (c["edges"], c["poses"], c["init"], c["optimizer"], c["error"], c["chi2"], c["iterations"],
           c["seconds"], c.get("sesync_F"))
    for name, c in _TABLE["gtsam_local_checks"].items()}


def _entry(name: str, spec: dict[str, Any]) -> dict[str, Any]:
    """One dataset as :mod:`slamkit.data.registry` reads it: the licence key resolved to its text
    (with ``licence_note`` appended), references and ground truth as tuples."""
    out = {k: spec[k] for k in ("kind", "format", "files", "title")}
    try:
        licence = LICENCES[spec["licence"]]
    except KeyError:
        raise DataError(f"dataset {name!r}: licence {spec.get('licence')!r} is not a key of [licences] "
                        f"({', '.join(LICENCES)})", TABLE_FILE) from None
    out["licence"] = f"{licence} {spec['licence_note']}" if "licence_note" in spec else licence
    if "counts" in spec:
        out["counts"] = dict(spec["counts"])
    if "refs" in spec:
        out["refs"] = [(r["kind"], r.get("value"), r["objective"], r["published"], r["source"]) for r in spec["refs"]]
    if "ground_truth" in spec:
        out["ground_truth"] = (spec["ground_truth"]["file"], spec["ground_truth"]["format"])
    if "notes" in spec:
        out["notes"] = spec["notes"]
    return out


#: name -> dict(kind, format, files, title, licence, counts, refs, ground_truth (file, format), notes)
ENTRIES: dict[str, dict] = {name: _entry(name, spec) for name, spec in _TABLE["entries"].items()}
