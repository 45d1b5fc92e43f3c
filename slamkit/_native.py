"""The compiled C kernels, imported once per process (usable from every layer).

slamkit's hot loops (the pose-graph text scanner, the ray caster, the grid search core and the
particle-filter kernels) are plain CPython extension modules built by setuptools when the
package is installed (``setup.py`` lists them). Nothing is compiled or loaded from a cache at
run time: a module is imported from the installed package or not at all, and then callers use
their pure-Python/numpy fallback, which the tests check agrees with the kernel.

``SLAMKIT_NO_NATIVE=1`` forces the fallbacks (read on every call, so a test can flip it with
``monkeypatch.setenv``). :func:`status` says which kernels this installation has
(``slamkit doctor`` prints it).
"""

from __future__ import annotations

import importlib
import importlib.machinery
import importlib.util
import os
import threading
from types import ModuleType

#: every kernel slamkit ships (module name -> what it speeds up)
KERNELS: dict[str, str] = {
    "slamkit.data.formats._textscan": "pose-graph text scanner (g2o, TORO, iSAM readers)",
    "slamkit.maps._raycast": "Amanatides-Woo ray casting",
    "slamkit.planning._gridsearch": "grid A*/Dijkstra search core",
    "slamkit.estimation._pfkernel": "particle-filter likelihood, motion and resampling",
    "slamkit.estimation._eskfkernel": "error-state EKF IMU step (inertial navigation)",
    "slamkit.frontend._bnbkernel": "branch-and-bound descent of the global scan matcher (loop closure)",
    "slamkit.frontend._icpkernel": "k-d tree, normals and point-to-line ICP loop of the scan matcher",
}

_lock = threading.Lock()
#: module name -> imported module (or None after a failed import); one attempt per process
_loaded: dict[str, ModuleType | None] = {}
_reasons: dict[str, str] = {}


def native_disabled() -> bool:
    """True when ``SLAMKIT_NO_NATIVE`` is set to anything but '', '0' or 'false'."""
    return os.environ.get("SLAMKIT_NO_NATIVE", "").strip().lower() not in ("", "0", "false")


def load_extension(module_name: str) -> ModuleType | None:
    """The installed C extension ``module_name`` (dotted, e.g. ``slamkit.maps._raycast``), or
    None when it is disabled or was not built (see :func:`unavailable_reason`)."""
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
                if module is None:
                    _reasons[module_name] = ("not built: install slamkit with a C compiler present "
                                             "(pip install -e . compiles it); the numpy fallback runs")
            except Exception as exc:  # a broken build: the fallback runs, and says why
                _reasons[module_name] = f"import failed: {type(exc).__name__}: {exc}"
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


def status() -> dict[str, str]:
    """Kernel name -> 'compiled' or the reason the fallback runs, for every kernel slamkit ships."""
    out = {}
    for name in KERNELS:
        out[name] = "compiled" if load_extension(name) is not None else (unavailable_reason(name) or "unknown")
    return out


def _import_built(module_name: str) -> ModuleType | None:
    """The extension as installed by the build step, or None if there is none."""
    try:
        spec = importlib.util.find_spec(module_name)
    except (ImportError, ValueError):
        return None
    if spec is None or not isinstance(spec.loader, importlib.machinery.ExtensionFileLoader):
        return None
    return importlib.import_module(module_name)
