"""Opening Rerun recordings: the one place that decides where a recording goes.

Every pipeline writes through a ``RecordingStream`` returned here (never the global one), so
several recordings can be produced in one process and tests stay isolated. Files are written
under a temporary name and renamed on ``close`` so a half-written ``.rrd`` never looks complete.
"""

from __future__ import annotations

import os
from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb


class Recording:
    """A recording stream bound to a file (``path``) and/or a spawned viewer (``spawn``)."""

    def __init__(self, application_id: str, path: str | Path | None = None, spawn: bool = False,
                 blueprint: rrb.Blueprint | None = None):
        self.stream = rr.RecordingStream(application_id)
        self.path = None if path is None else Path(path)
        self._tmp_path: Path | None = None
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._tmp_path = self.path.with_name(self.path.name + ".partial")
            self.stream.save(self._tmp_path, default_blueprint=blueprint)
        if spawn:
            self.stream.spawn(connect=self.path is None)
        if blueprint is not None and self.path is None:
            self.stream.send_blueprint(blueprint)

    def close(self) -> Path | None:
        """Flush, finish the file and move it to its final name; returns the final path."""
        self.stream.flush()
        self.stream.disconnect()
        if self._tmp_path is not None and self.path is not None:
            os.replace(self._tmp_path, self.path)
            self._tmp_path = None
        return self.path

    def __enter__(self) -> "Recording":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.stream.disconnect()
            if self._tmp_path is not None and self._tmp_path.exists():
                self._tmp_path.unlink()


def open_recording(application_id: str, path: str | Path | None = None, spawn: bool = False,
                   blueprint: rrb.Blueprint | None = None) -> Recording:
    return Recording(application_id, path=path, spawn=spawn, blueprint=blueprint)
