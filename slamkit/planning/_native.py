"""The compiled grid-search core (``_gridsearch.c``), loaded through :mod:`slamkit._native`
(built by setuptools when slamkit is installed; None when it was not built, and then callers
fall back to the pure-Python heapq search)."""

from __future__ import annotations

from types import ModuleType

from slamkit._native import load_extension
from slamkit._native import unavailable_reason as _reason

MODULE = "slamkit.planning._gridsearch"


def gridsearch() -> ModuleType | None:
    """The compiled module, or None (see :func:`unavailable_reason`)."""
    return load_extension(MODULE)


def unavailable_reason() -> str | None:
    return _reason(MODULE)
