"""Compile-on-first-use loader for slamkit's small C extensions (usable from every layer).

A package keeps a plain CPython-API C file next to its Python module (e.g.
``slamkit/data/formats/_textscan.c``) and calls::

    from slamkit._native import load_extension
    mod = load_extension("slamkit.data.formats._textscan", Path(__file__).with_name("_textscan.c"))

Order of attempts:

1. the module itself, if setuptools built it (``ext_modules``) and it is importable;
2. a copy compiled with the system C compiler (``$CC``, ``cc`` or ``gcc``;
   ``-O3 -shared -fPIC -I<python include>``) into a per-user cache (``$SLAMKIT_CACHE`` or
   ``~/.cache/slamkit``), named by the source's SHA-256 and the interpreter's ``EXT_SUFFIX``, so an
   edited source or another Python gets its own build and a source checkout without a build step
   still gets the fast path. The compiler writes a temporary file in the cache folder which is then
   ``os.replace``-d into place: concurrent processes (pytest-xdist workers) never load a
   half-written library, and the loser of a race just overwrites an identical file;
3. ``None``: callers use their pure-Python fallback; :func:`unavailable_reason` says why.

``SLAMKIT_NO_NATIVE=1`` forces ``None`` (tests use it to check that both paths agree). It is read
on every call, so a test can flip it with ``monkeypatch.setenv``.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.machinery
import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import threading
from pathlib import Path
from types import ModuleType

_lock = threading.Lock()
#: module name -> compiled module (or None after a failed attempt); one attempt per process
_loaded: dict[str, ModuleType | None] = {}
_reasons: dict[str, str] = {}
COMPILE_TIMEOUT_S = 120.0


def native_disabled() -> bool:
    """True when ``SLAMKIT_NO_NATIVE`` is set to anything but '', '0' or 'false'."""
    return os.environ.get("SLAMKIT_NO_NATIVE", "").strip().lower() not in ("", "0", "false")


def cache_dir() -> Path:
    return Path(os.environ.get("SLAMKIT_CACHE") or Path.home() / ".cache" / "slamkit")


def load_extension(module_name: str, source: Path) -> ModuleType | None:
    """The C extension ``module_name`` (dotted, e.g. ``slamkit.data.formats._textscan``) built
    from ``source``, or None when it cannot be had (see :func:`unavailable_reason`)."""
    if native_disabled():
        _reasons[module_name] = "disabled by SLAMKIT_NO_NATIVE"
        return None
    if module_name in _loaded:
        return _loaded[module_name]
    with _lock:
        if module_name not in _loaded:
            module = None
            try:
                module = _import_built(module_name)
            except Exception:  # a broken build-step copy: compile our own instead
                module = None
            if module is None:
                try:
                    module = _compile_and_load(module_name, Path(source))
                except Exception as exc:  # any failure means: use the Python fallback
                    _reasons[module_name] = f"{type(exc).__name__}: {exc}"
            _loaded[module_name] = module
    return _loaded[module_name]


def unavailable_reason(module_name: str) -> str | None:
    """Why :func:`load_extension` returned None for ``module_name`` (None if it was loaded or
    never asked for)."""
    if native_disabled():
        return "disabled by SLAMKIT_NO_NATIVE"
    if _loaded.get(module_name) is not None:
        return None
    return _reasons.get(module_name)


def _import_built(module_name: str) -> ModuleType | None:
    """The extension as installed by a build step, if there is one (a stale cache copy of the
    same name is never picked up here: cache files carry a hash in their name)."""
    try:
        spec = importlib.util.find_spec(module_name)
    except (ImportError, ValueError):
        return None
    if spec is None or not isinstance(spec.loader, importlib.machinery.ExtensionFileLoader):
        return None
    return importlib.import_module(module_name)


def _compiler() -> str:
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if not cc:
        raise RuntimeError("no C compiler found (set CC, or install cc/gcc)")
    return cc


def _compile_and_load(module_name: str, source: Path) -> ModuleType:
    code = source.read_bytes()
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    key = hashlib.sha256(code + suffix.encode() + sys.version.encode()).hexdigest()[:16]
    short = module_name.rsplit(".", 1)[-1]
    cache = cache_dir()
    target = cache / f"{short}_{key}{suffix}"
    if not target.exists():
        cc = _compiler()
        cache.mkdir(parents=True, exist_ok=True)
        include = sysconfig.get_paths()["include"]
        fd, tmp = tempfile.mkstemp(prefix=f".{short}_", suffix=suffix, dir=cache)
        os.close(fd)
        try:
            cmd = [cc, "-O3", "-shared", "-fPIC", f"-I{include}", str(source), "-o", tmp, "-lm"]
            done = subprocess.run(cmd, capture_output=True, text=True, timeout=COMPILE_TIMEOUT_S)
            if done.returncode != 0:
                raise RuntimeError(f"compiling {source.name} failed: {done.stderr.strip()[:500]}")
            os.replace(tmp, target)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    # the init function is PyInit_<short>, so the spec's name must end in <short>
    spec = importlib.util.spec_from_file_location(module_name, target)
    if spec is None or spec.loader is None:
        raise RuntimeError(f"cannot load {target}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
