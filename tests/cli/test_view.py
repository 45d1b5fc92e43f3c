"""``slamkit view`` (issue 32 item 3): Rerun's web viewer served on loopback for a recording,
fetched over HTTP like a browser would, nothing listening beyond 127.0.0.1, stopped cleanly."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.parse
import urllib.request
from pathlib import Path

import pytest

from slamkit.cli.view import _host_for_url, open_native, recording_of, serve_recording
from slamkit.errors import ConfigError

SLAMKIT = Path(sys.executable).with_name("slamkit")


def _recording(path: Path) -> Path:
    import rerun as rr

    rec = rr.RecordingStream("slamkit_view_test")
    rec.save(str(path))
    rec.log("world/landmarks", rr.Points2D([[0.0, 0.0], [1.0, 2.0], [3.0, 1.0]]), static=True)
    for k in range(5):
        rec.set_time("stamp", duration=0.1 * k)
        rec.log("plots/ate", rr.Scalars(0.1 * k))
    rec.flush()
    rec.disconnect()
    assert path.stat().st_size > 0
    return path


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("run")
    _recording(folder / "recording.rrd")
    return folder


def _free_port_pair() -> int:
    """A port p with p and p + 1 both free on 127.0.0.1 (ask the kernel, then check the next)."""
    for _ in range(50):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        if port >= 65534:
            continue
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port + 1))
            except OSError:
                continue
        return port
    raise RuntimeError("no free port pair")


def _listening(pids: set[int]) -> list[tuple[str, int]]:
    """(address hex, port) of every TCP socket in LISTEN state owned by ``pids`` (/proc/net/tcp)."""
    inodes = set()
    for pid in pids:
        fd_dir = Path(f"/proc/{pid}/fd")
        for fd in fd_dir.iterdir() if fd_dir.exists() else ():
            try:
                target = os.readlink(fd)
            except OSError:
                continue
            if target.startswith("socket:["):
                inodes.add(target[8:-1])
    out = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            cols = line.split()
            if cols[3] == "0A" and cols[9] in inodes:
                address, port = cols[1].split(":")
                out.append((address, int(port, 16)))
    return out


def _descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (the rerun CLI is a Python launcher that starts the binary)."""
    parent = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parent[int(stat.parent.name)] = int(fields[1])
    found, frontier = set(), {pid}
    while frontier:
        frontier = {child for child, ppid in parent.items() if ppid in frontier} - found
        found |= frontier
    return found


LOOPBACK = {"0100007F", "00000000000000000000000001000000"}  # 127.0.0.1, ::1 as /proc/net writes them


def test_view_serves_the_web_viewer_and_the_recording_on_loopback_only(run_folder):
    port = _free_port_pair()
    process = subprocess.Popen([str(SLAMKIT), "view", str(run_folder), "--port", str(port)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = None
        deadline = time.monotonic() + 120
        while url is None and time.monotonic() < deadline:
            line = process.stdout.readline()
            assert line or process.poll() is None, process.stderr.read()
            if line.startswith("Open: "):
                url = line.split(" ", 1)[1].strip()
        assert url is not None and url.startswith(f"http://127.0.0.1:{port}/?url=")
        page = urllib.request.urlopen(url, timeout=30).read().decode()
        assert "<title>Rerun Viewer" in page
        wasm = urllib.request.urlopen(f"http://127.0.0.1:{port}/re_viewer_bg.wasm", timeout=30).read()
        assert wasm[:4] == b"\0asm"  # the viewer itself, from the wheel's binary (no CDN)
        data_url = urllib.parse.parse_qs(urllib.parse.urlparse(url).query)["url"][0]
        assert data_url == f"http://127.0.0.1:{port + 1}/recording.rrd"
        served = urllib.request.urlopen(data_url, timeout=30)
        assert served.headers["Access-Control-Allow-Origin"] == "*"
        assert served.read() == (run_folder / "recording.rrd").read_bytes()
        sockets = _listening({process.pid, *_descendants(process.pid)})
        assert {p for _, p in sockets} >= {port, port + 1}
        assert all(address in LOOPBACK for address, _ in sockets), sockets
    finally:
        process.send_signal(signal.SIGTERM)  # as a service manager or `kill` stops it (Ctrl-C: SIGINT, same path)
        code = process.wait(timeout=30)
    assert code == 0
    for p in (port, port + 1):  # both servers are gone
        with socket.socket() as s:
            assert s.connect_ex(("127.0.0.1", p)) != 0


def test_view_in_process_and_bad_paths(run_folder, tmp_path):
    port = _free_port_pair()
    with serve_recording(run_folder / "recording.rrd", port=port) as server:
        assert server.bind == "127.0.0.1" and server.recording == (run_folder / "recording.rrd").resolve()
        with pytest.raises(ConfigError, match=rf"web viewer: cannot listen on 127.0.0.1:{port}"):
            serve_recording(run_folder, port=port)
    assert server.process.poll() is not None
    (tmp_path / "empty_run").mkdir()
    with pytest.raises(ConfigError, match=r"no recording.rrd in this folder; runs write one"):
        recording_of(tmp_path / "empty_run")
    with pytest.raises(ConfigError, match=r"not a Rerun recording"):
        recording_of(Path(__file__))


def test_native_needs_a_display(run_folder, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(ConfigError, match=r"--native needs a display.*ssh -L 9090:localhost:9090"):
        open_native(run_folder)


def test_the_url_names_a_host_the_browser_can_reach():
    # loopback and explicit addresses as given; a wildcard bind (asked for so that other machines
    # connect) is named by this machine's name, since the browser fetches the recording from it
    assert _host_for_url("127.0.0.1") == "127.0.0.1" and _host_for_url("::1") == "[::1]"
    assert _host_for_url("0.0.0.0") == socket.gethostname()
