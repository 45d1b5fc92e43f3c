"""The compiled grid-search core (``_gridsearch.c``), loaded through :mod:`slamkit._native`
(a setuptools-built module if present, else compiled on first use into the user cache, else
None so callers fall back to the pure-Python heapq search)."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

from slamkit._native import load_extension
from slamkit._native import unavailable_reason as _reason

MODULE = "slamkit.planning._gridsearch"
SOURCE = Path(__file__).with_name("_gridsearch.c")


def gridsearch() -> ModuleType | None:
    """The compiled module, or None (see :func:`unavailable_reason`)."""
    return load_extension(MODULE, SOURCE)


def unavailable_reason() -> str | None:
    return _reason(MODULE)
