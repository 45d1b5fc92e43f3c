"""Opening Rerun recordings: the one place that decides where a recording goes.

Every pipeline writes through a ``RecordingStream`` returned here (never the global one), so
several recordings can be produced in one process and tests stay isolated. Files are written
under a temporary name and renamed on ``close`` so a half-written ``.rrd`` never looks complete.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

from slamkit.errors import OutputError
from slamkit.paths import check_output_file, temporary_sibling

#: where a spawned viewer listens unless asked otherwise: this machine only (rerun's own
#: ``spawn`` serves on every interface)
VIEWER_BIND = "127.0.0.1"
VIEWER_PORT = 9876
#: how long to wait for a spawned viewer to accept connections
VIEWER_START_TIMEOUT_S = 10.0


def is_rrd_file(path: Path) -> bool:
    """True for a Rerun recording (an ``.rrd`` stream starts with the bytes ``RRF``)."""
    with open(path, "rb") as handle:
        return handle.read(3) == b"RRF"


def _viewer_executable() -> str | None:
    beside = Path(sys.executable).with_name("rerun")
    return str(beside) if beside.exists() else shutil.which("rerun")


def viewer_url(bind: str = VIEWER_BIND, port: int = VIEWER_PORT) -> str:
    """Start (or reuse) a Rerun viewer listening on ``bind:port`` -- loopback by default -- and
    return the gRPC url to send to. No display, no viewer executable, or a viewer that does not
    come up is an OutputError with the reason, never a hang or a traceback."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise OutputError("--spawn needs a display (neither DISPLAY nor WAYLAND_DISPLAY is set); "
                          "leave --spawn out (the run folder keeps its recording.rrd) and look at it with "
                          "`slamkit view RUN_FOLDER`, Rerun's web viewer served on 127.0.0.1 (over SSH too)")
    exe = _viewer_executable()
    if exe is None:
        raise OutputError("--spawn needs the rerun viewer, which is not installed (pip install rerun-sdk)")
    if not _port_open(bind, port):
        subprocess.Popen([exe, "--bind", bind, "--port", str(port)], stdin=subprocess.DEVNULL,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        deadline = time.monotonic() + VIEWER_START_TIMEOUT_S
        while not _port_open(bind, port):
            if time.monotonic() > deadline:
                raise OutputError(f"the rerun viewer did not start listening on {bind}:{port} within "
                                  f"{VIEWER_START_TIMEOUT_S:.0f} s")
            time.sleep(0.1)
    host = f"[{bind}]" if ":" in bind else bind
    return f"rerun+http://{host}:{port}/proxy"


def _port_open(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=0.2):
            return True
    except OSError:
        return False


class Recording:
    """A recording stream bound to a file (``path``) and/or a spawned viewer (``spawn``)."""

    def __init__(self, application_id: str, path: str | Path | None = None, spawn: bool = False,
                 blueprint: rrb.Blueprint | None = None):
        self.stream = rr.RecordingStream(application_id)
        self.path = None if path is None else Path(path)
        self._tmp_path: Path | None = None
        sinks: list = []
        if spawn:
            sinks.append(rr.GrpcSink(viewer_url()))  # first: fail before any file is created
        if self.path is not None:
            self.path = check_output_file(self.path, is_rrd_file, "recording")
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._tmp_path = temporary_sibling(self.path)
            sinks.append(rr.FileSink(str(self._tmp_path)))
        if sinks:
            self.stream.set_sinks(*sinks, default_blueprint=blueprint)
        if blueprint is not None and not sinks:
            self.stream.send_blueprint(blueprint)

    def close(self) -> Path | None:
        """Flush, finish the file and move it to its final name; returns the final path."""
        self.stream.flush()
        self.stream.disconnect()
        if self._tmp_path is not None and self.path is not None:
            os.replace(self._tmp_path, self.path)
            self._tmp_path = None
        return self.path

    def abort(self) -> None:
        """Stop recording and remove the unfinished file (a failed run leaves no recording)."""
        self.stream.disconnect()
        if self._tmp_path is not None and self._tmp_path.exists():
            self._tmp_path.unlink()
        self._tmp_path = None

    def __enter__(self) -> "Recording":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def open_recording(application_id: str, path: str | Path | None = None, spawn: bool = False,
                   blueprint: rrb.Blueprint | None = None) -> Recording:
    return Recording(application_id, path=path, spawn=spawn, blueprint=blueprint)


class OutputRecorder:
    """Base of the recorders that draw a pipeline from its finished output only (no live steps):
    ``RecorderClass(path, spawn=False)``; a subclass sets ``payload_type`` and implements
    ``on_output``."""

    payload_type: object = None
    wants_steps = False  # everything it draws is in the pipeline's output
    step_every = 1

    def __init__(self, path, spawn: bool = False):
        self.path, self.spawn = path, spawn

    def on_step(self, snapshot) -> None:
        pass

    def on_output(self, output) -> None:
        raise NotImplementedError

    def close(self) -> None:
        pass
