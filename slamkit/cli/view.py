"""``slamkit view RUN_FOLDER | FILE.rrd [--bind ADDR] [--port N] [--native]``: look at a recording.

By default this serves Rerun's web viewer, so it works on a headless machine and over SSH: the
rerun binary of the installed wheel hosts the viewer's page on ``--port`` (default 9090), and the
recording file itself is served on the next port by a small HTTP server in this process; the
printed URL opens the viewer with ``?url=`` pointing at the file (the viewer downloads it, so a
recording of any size is read from disk, not buffered in a server). Both listen on 127.0.0.1
unless ``--bind`` says otherwise: nothing started here is reachable from another machine unless
asked (``rerun FILE`` alone listens on 0.0.0.0:9876). On a server, forward both ports::

    ssh -L 9090:localhost:9090 -L 9091:localhost:9091 server   # then open the printed URL

``--native`` opens the native viewer instead, where a display exists (``$DISPLAY`` or
``$WAYLAND_DISPLAY``); its own server is bound to ``--bind`` too.

Rerun's binary reports usage (and the serving of its web viewer) unless ``rerun analytics
disable`` was run once; ``make setup`` does that.

:func:`serve_recording` is the function behind the command (a notebook can call it); it returns a
:class:`ViewServer` to ``close()``.
"""

from __future__ import annotations

import functools
import http.server
import os
import shutil
import socket
import subprocess
import sys
import threading
import time
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path

import typer

from slamkit.cli.app import app
from slamkit.errors import ConfigError, OutputError

#: where the viewer listens unless ``--bind`` says otherwise
DEFAULT_BIND = "127.0.0.1"
DEFAULT_PORT = 9090
#: how long the rerun binary may take to start listening
START_TIMEOUT_S = 60.0


def recording_of(path: str | Path) -> Path:
    """The ``.rrd`` a path names: the file itself, or ``recording.rrd`` of a run folder."""
    path = Path(path).expanduser()
    if path.is_dir():
        rrd = path / "recording.rrd"
        if rrd.is_file():
            return rrd
        found = sorted(str(p.relative_to(path)) for p in path.rglob("*.rrd"))[:5]
        hint = f"; .rrd files below it: {', '.join(found)}" if found else (
            "; runs write one when their config has record: true (the default) and they run through "
            "`slamkit run`")
        raise ConfigError(f"{path}: no recording.rrd in this folder{hint}")
    if not path.is_file():
        raise ConfigError(f"{path}: no such recording file or run folder")
    if path.suffix != ".rrd":
        raise ConfigError(f"{path}: not a Rerun recording (.rrd)")
    return path


def rerun_binary() -> str:
    """The rerun binary of the installed wheel, else the ``rerun`` on PATH.

    The wheel's ``bin/rerun`` is a Python launcher that runs the binary as its child, so stopping
    the launcher would leave the binary (and its listening socket) behind: the binary inside the
    ``rerun_cli`` package is started directly."""
    import importlib.util

    spec = importlib.util.find_spec("rerun_cli")
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        binary = Path(location) / ("rerun.exe" if sys.platform.startswith("win") else "rerun")
        if binary.is_file() and os.access(binary, os.X_OK):
            return str(binary)
    beside = Path(sys.executable).with_name("rerun")
    if beside.exists():
        return str(beside)
    found = shutil.which("rerun")
    if found is None:
        raise ConfigError("the rerun CLI is not installed (it comes with the rerun-sdk wheel: pip install rerun-sdk)")
    return found


def _host_for_url(bind: str) -> str:
    """The host a browser uses for a server bound to ``bind``: the address itself, or for a
    wildcard bind (which is asked for to be reached from elsewhere) this machine's name -- the
    browser fetches the recording from that URL too, so ``localhost`` would point at its own
    machine."""
    if bind in ("0.0.0.0", "::", ""):
        return socket.gethostname()
    return f"[{bind}]" if ":" in bind else bind


def _check_port_free(bind: str, port: int, what: str) -> None:
    family = socket.AF_INET6 if ":" in bind else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((bind, port))
        except OSError as exc:
            raise ConfigError(f"{what}: cannot listen on {bind}:{port} ({exc.strerror}); choose another "
                              "with --port") from None


class _RecordingHandler(http.server.SimpleHTTPRequestHandler):
    """Serves the one recording file; the viewer's page is on another port, so CORS allows it."""

    def end_headers(self) -> None:
        self.send_header("Access-Control-Allow-Origin", "*")
        super().end_headers()

    def log_message(self, format: str, *args) -> None:  # noqa: A002 - the stdlib's signature
        pass  # one line per request would bury the URL


class _Server(http.server.ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self, bind: str, port: int, handler):
        self.address_family = socket.AF_INET6 if ":" in bind else socket.AF_INET
        super().__init__((bind, port), handler)


@dataclass
class ViewServer:
    """A running viewer: ``url`` to open, ``close()`` to stop it (also a context manager)."""

    url: str
    recording: Path
    bind: str
    viewer_port: int
    data_port: int | None
    process: subprocess.Popen
    _http: _Server | None = field(default=None, repr=False)
    _log: Path | None = field(default=None, repr=False)

    def close(self) -> None:
        if self.process.poll() is None:
            _stop(self.process)
        if self._http is not None:
            self._http.shutdown()
            self._http.server_close()
            self._http = None
        if self._log is not None:
            self._log.unlink(missing_ok=True)

    def __enter__(self) -> "ViewServer":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _stop(process: subprocess.Popen) -> None:
    """Stop the viewer and anything it started (it runs in its own process group)."""
    import signal

    for sig, wait_s in ((signal.SIGTERM, 10), (signal.SIGKILL, 10)):
        try:
            os.killpg(process.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass
        try:
            process.wait(timeout=wait_s)
            return
        except subprocess.TimeoutExpired:
            continue


def _wait_listening(process: subprocess.Popen, host: str, port: int, log: Path) -> None:
    deadline = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise OutputError(f"the rerun web viewer exited with code {process.returncode}: "
                              f"{log.read_text(errors='replace')[-2000:]}")
        try:
            with socket.create_connection((host, port), timeout=1.0):
                return
        except OSError:
            time.sleep(0.2)
    _stop(process)
    raise OutputError(f"the rerun web viewer did not listen on {host}:{port} within {START_TIMEOUT_S:.0f} s: "
                      f"{log.read_text(errors='replace')[-2000:]}")


def serve_recording(path: str | Path, bind: str = DEFAULT_BIND, port: int = DEFAULT_PORT,
                    log_dir: Path | None = None) -> ViewServer:
    """Serve the recording ``path`` names (a file or a run folder) in Rerun's web viewer on
    ``bind:port``, the file itself on ``bind:port + 1``; returns once both listen."""
    rrd = recording_of(path).resolve()
    if not 1 <= port <= 65534:
        raise ConfigError(f"--port must be in 1..65534 (the recording is served on port + 1), got {port}")
    _check_port_free(bind, port, "web viewer")
    _check_port_free(bind, port + 1, "recording server")
    handler = functools.partial(_RecordingHandler, directory=str(rrd.parent))
    server = _Server(bind, port + 1, handler)
    threading.Thread(target=server.serve_forever, name="slamkit-view-http", daemon=True).start()
    host = _host_for_url(bind)
    data_url = f"http://{host}:{port + 1}/{urllib.parse.quote(rrd.name)}"
    log = (log_dir or Path(os.environ.get("TMPDIR", "/tmp"))) / f"slamkit-view-{os.getpid()}-{port}.log"
    with open(log, "wb") as out:
        # a URL argument makes --web-viewer host only the viewer's page (no gRPC server); the
        # viewer in the browser downloads the file from data_url
        process = subprocess.Popen([rerun_binary(), "--web-viewer", "--bind", bind, "--web-viewer-port", str(port),
                                    "--hide-welcome-screen", data_url],
                                   stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                   start_new_session=True)
    try:
        _wait_listening(process, {"0.0.0.0": "127.0.0.1", "::": "::1"}.get(bind, bind), port, log)
    except BaseException:
        server.shutdown()
        server.server_close()
        log.unlink(missing_ok=True)
        raise
    url = f"http://{host}:{port}/?url={urllib.parse.quote(data_url, safe='')}"
    return ViewServer(url, rrd, bind, port, port + 1, process, server, log)


def open_native(path: str | Path, bind: str = DEFAULT_BIND) -> subprocess.Popen:
    """The native viewer on ``path`` (its server bound to ``bind``); needs a display."""
    rrd = recording_of(path)
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ConfigError("--native needs a display ($DISPLAY or $WAYLAND_DISPLAY is unset): on a headless "
                          "machine or a server run `slamkit view` without --native and open the printed URL "
                          "(over SSH: ssh -L 9090:localhost:9090 -L 9091:localhost:9091 HOST)")
    return subprocess.Popen([rerun_binary(), "--bind", bind, str(rrd)])


@app.command("view")
def view_command(
    path: Path = typer.Argument(..., help="a run folder (its recording.rrd) or an .rrd file"),
    bind: str = typer.Option(DEFAULT_BIND, "--bind",
                             help="address to listen on (default loopback only; 0.0.0.0 exposes the "
                                  "recording to the network)"),
    port: int = typer.Option(DEFAULT_PORT, "--port", min=1, max=65534,
                             help="web viewer port; the recording file is served on port + 1"),
    native: bool = typer.Option(False, "--native", help="open the native viewer (needs a display)"),
) -> None:
    """Open a recording in Rerun's web viewer (headless and SSH friendly) or the native viewer."""
    if native:
        raise typer.Exit(open_native(path, bind).wait())
    server = serve_recording(path, bind, port)
    typer.echo(f"Serving {server.recording} (listening on {bind}, ports {port} and {port + 1}).")
    typer.echo(f"Open: {server.url}")
    if bind in ("127.0.0.1", "::1", "localhost"):
        typer.echo(f"From another machine: ssh -L {port}:localhost:{port} -L {port + 1}:localhost:{port + 1} "
                   "<this host>, then open the URL there.")
    else:
        typer.echo(f"warning: listening on {bind}: whoever can reach this machine on ports {port} and "
                   f"{port + 1} can load the recording", err=True)
    typer.echo("Ctrl-C stops.")
    sys.stdout.flush()

    def _interrupt(*_: object) -> None:
        raise KeyboardInterrupt  # a kill (SIGTERM) stops the viewer too, not only Ctrl-C

    import signal

    signal.signal(signal.SIGTERM, _interrupt)
    try:
        while server.process.poll() is None:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
