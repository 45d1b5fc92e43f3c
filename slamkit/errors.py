"""Typed exceptions: every failure on bad input is a ``SlamkitError`` whose message names the
file, line or field at fault."""

from __future__ import annotations

from pathlib import Path


class SlamkitError(Exception):
    """Base of every error slamkit raises on purpose."""


class DataError(SlamkitError):
    """A data file or in-memory dataset is malformed or inconsistent.

    ``path`` and ``line`` (one-based) locate the fault when it comes from a file."""

    def __init__(self, message: str, path: str | Path | None = None, line: int | None = None):
        self.path = None if path is None else str(path)
        self.line = line
        where = ""
        if self.path is not None:
            where = f"{self.path}:{line}: " if line is not None else f"{self.path}: "
        super().__init__(f"{where}{message}")


class DatasetNotFoundError(DataError):
    """A registry name is unknown, or known but not available in any search location."""


class ChecksumError(DataError):
    """A downloaded or local file does not match the sha256 the registry records."""


class ConfigError(SlamkitError):
    """A pipeline or algorithm config has an unknown key or an invalid value."""


class OutputError(SlamkitError):
    """An output path cannot be written safely (a folder slamkit did not write, a regular file,
    another run writing to the same folder)."""


class NoResultError(SlamkitError):
    """A valid request has no answer: no path exists, a solve failed, a result is not finite.
    The CLI exits with code 3 (bad input is 2)."""


class BackendError(SlamkitError):
    """The factor-graph back-end could not build or solve a problem."""


class EstimationError(SlamkitError):
    """A filter or smoother was used wrongly (for example step before reset)."""


class PlanningError(SlamkitError):
    """A planning problem is malformed (start or goal outside the map, wrong dimensions)."""


class ControlError(SlamkitError):
    """A controller was configured or called with inconsistent inputs."""
