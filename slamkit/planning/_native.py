"""Loads the compiled grid-search core (``_gridsearch.c``), or reports that it is unavailable.

Order of attempts:

1. ``slamkit.planning._gridsearch`` built by setuptools (``ext_modules``) next to this file;
2. a copy compiled on first use with the system C compiler into a per-user cache
   (``$SLAMKIT_CACHE`` or ``~/.cache/slamkit``), keyed by the source hash and Python ABI, so a
   source checkout without a build step still gets the fast path;
3. ``None``: callers fall back to the pure-Python heapq search (same results, ~50-100x slower).

Set ``SLAMKIT_NO_NATIVE=1`` to force the fallback (tests use it to check both paths agree).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import subprocess
import sysconfig
import tempfile
from pathlib import Path
from types import ModuleType

_SOURCE = Path(__file__).with_name("_gridsearch.c")
_cached: ModuleType | None = None
_tried = False
#: why the compiled core is missing (for ``slamkit bench`` and error messages)
unavailable_reason: str | None = None


def _load_from(path: Path) -> ModuleType:
    spec = importlib.util.spec_from_file_location("slamkit.planning._gridsearch", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _compile() -> ModuleType:
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise RuntimeError("no C compiler found")
    source = _SOURCE.read_bytes()
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    key = hashlib.sha256(source + suffix.encode()).hexdigest()[:16]
    cache = Path(os.environ.get("SLAMKIT_CACHE", Path.home() / ".cache" / "slamkit"))
    target = cache / f"_gridsearch_{key}{suffix}"
    if not target.exists():
        cache.mkdir(parents=True, exist_ok=True)
        include = sysconfig.get_paths()["include"]
        # compile to a temporary name and rename, so concurrent test workers never load a
        # half-written library
        fd, tmp = tempfile.mkstemp(suffix=suffix, dir=cache)
        os.close(fd)
        cmd = [cc, "-O3", "-shared", "-fPIC", f"-I{include}", str(_SOURCE), "-o", tmp, "-lm"]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        if done.returncode != 0:
            os.unlink(tmp)
            raise RuntimeError(f"compiling {_SOURCE.name} failed: {done.stderr.strip()[:500]}")
        os.replace(tmp, target)
    return _load_from(target)


def gridsearch() -> ModuleType | None:
    """The compiled module, or None (see ``unavailable_reason``)."""
    global _cached, _tried, unavailable_reason
    if os.environ.get("SLAMKIT_NO_NATIVE"):
        unavailable_reason = "disabled by SLAMKIT_NO_NATIVE"
        return None
    if _tried:
        return _cached
    _tried = True
    try:
        from slamkit.planning import _gridsearch  # type: ignore[attr-defined]

        _cached = _gridsearch
        return _cached
    except ImportError:
        pass
    try:
        _cached = _compile()
    except Exception as exc:  # any failure means: use the Python fallback
        unavailable_reason = str(exc)
        _cached = None
    return _cached
