"""``registry.fetch`` against a real HTTP server on 127.0.0.1: verified download into the cache,
corrupted and missing files rejected with nothing left behind."""

from __future__ import annotations

import functools
import http.server
import shutil
import threading
from pathlib import Path

import pytest

from slamkit.data import registry
from slamkit.errors import ChecksumError, DataError


class Server:
    def __init__(self, folder: Path):
        self.folder = folder
        self.hits: list[str] = []
        hits = self.hits

        class Handler(http.server.SimpleHTTPRequestHandler):
            def log_message(self, *args):  # keep test output clean
                pass

            def do_GET(self):
                hits.append(self.path)
                super().do_GET()

        handler = functools.partial(Handler, directory=str(folder))
        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/"
        self.thread = threading.Thread(target=self.httpd.serve_forever, kwargs={"poll_interval": 0.05},
                                       daemon=True)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join(timeout=5)


@pytest.fixture
def served(tmp_path, shared_datasets):
    """A served folder with a good and a corrupted copy of ring.g2o and ring's ground truth."""
    folder = tmp_path / "www"
    folder.mkdir()
    good = shared_datasets / "pose_graph_2d" / "ring.g2o"
    shutil.copy(good, folder / "ring.g2o")
    shutil.copy(shared_datasets / "pose_graph_2d" / "ring_groundtruth_poses.txt", folder / "ring_groundtruth_poses.txt")
    data = bytearray(good.read_bytes())
    data[100] = ord("7") if data[100] != ord("7") else ord("8")  # one digit changed
    (folder / "corrupt").mkdir()
    (folder / "corrupt" / "ring.g2o").write_bytes(bytes(data))
    (folder / "corrupt" / "ring_groundtruth_poses.txt").write_bytes(
        (folder / "ring_groundtruth_poses.txt").read_bytes())
    with Server(folder) as server:
        yield server


def _all_paths(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*")) if root.exists() else []


def test_fetch_downloads_verifies_and_is_found_in_the_cache(served, tmp_path, monkeypatch, shared_datasets):
    cache = tmp_path / "cache"
    path = registry.fetch("ring", url_override=served.url, cache_dir=cache)
    assert path == cache / "pose_graph_2d" / "ring.g2o"
    assert path.read_bytes() == (shared_datasets / "pose_graph_2d" / "ring.g2o").read_bytes()
    assert _all_paths(cache) == ["pose_graph_2d", "pose_graph_2d/ring.g2o",
                                 "pose_graph_2d/ring_groundtruth_poses.txt"]
    assert sorted(served.hits) == ["/ring.g2o", "/ring_groundtruth_poses.txt"]
    # a second fetch finds verified files and downloads nothing
    registry.fetch("ring", url_override=served.url, cache_dir=cache)
    assert len(served.hits) == 2
    # the cache is the last lookup root: with the others gone, the fetched files are found there
    monkeypatch.setenv("SLAMKIT_CACHE", str(cache))
    monkeypatch.delenv("SLAMKIT_DATA", raising=False)
    monkeypatch.setattr(registry, "shared_datasets_dir", lambda: tmp_path / "none")
    assert registry.locate(registry.get("ring").primary) == ("cache", path)
    assert registry.verify("ring") == {"pose_graph_2d/ring.g2o": True,
                                       "pose_graph_2d/ring_groundtruth_poses.txt": True}
    assert len(registry.ground_truth("ring")) == 434


def test_corrupted_download_is_rejected_and_nothing_is_left(served, tmp_path):
    cache = tmp_path / "cache"
    with pytest.raises(ChecksumError, match="sha256 mismatch") as info:
        registry.fetch("ring", url_override=served.url + "corrupt/", cache_dir=cache)
    assert info.value.path.endswith("/corrupt/ring.g2o")
    assert _all_paths(cache) == []  # no partial file, no temporary, no empty folders


def test_missing_file_on_server_is_a_data_error_and_leaves_nothing(served, tmp_path):
    cache = tmp_path / "cache"
    with pytest.raises(DataError, match="download failed"):
        registry.fetch("ring", url_override=served.url + "nothing-here/", cache_dir=cache)
    assert _all_paths(cache) == []


def test_oversized_download_stops_and_leaves_nothing(served, tmp_path, shared_datasets):
    # issue 10: a server sending more than the recorded size is cut off, not read to the end
    (served.folder / "big").mkdir()
    good = (shared_datasets / "pose_graph_2d" / "ring.g2o").read_bytes()
    (served.folder / "big" / "ring.g2o").write_bytes(good + b"#" * (4 << 20))
    cache = tmp_path / "cache"
    size = registry.get("ring").files[0].size_bytes
    with pytest.raises(ChecksumError) as info:
        registry.fetch("ring", url_override=served.url + "big/", cache_dir=cache)
    assert str(info.value) == (f"{served.url}big/ring.g2o: download exceeds its recorded size of {size} bytes; "
                               "stopped and discarded")
    assert size == len(good)
    assert _all_paths(cache) == []  # the partial file and the folders it made are gone


def test_existing_cache_folders_survive_a_failed_fetch(served, tmp_path):
    cache = tmp_path / "cache"
    (cache / "pose_graph_2d").mkdir(parents=True)
    (cache / "pose_graph_2d" / "keep.txt").write_text("x")
    with pytest.raises(ChecksumError):
        registry.fetch("ring", url_override=served.url + "corrupt/", cache_dir=cache)
    assert _all_paths(cache) == ["pose_graph_2d", "pose_graph_2d/keep.txt"]


def test_single_file_url_and_url_rules(served, tmp_path, shared_datasets):
    cache = tmp_path / "cache"
    # a one-file dataset takes a full file URL; serve intel.g2o under another name
    shutil.copy(shared_datasets / "pose_graph_2d" / "intel.g2o", served.folder / "x.g2o")
    path = registry.fetch("intel", url_override=served.url + "x.g2o", cache_dir=cache)
    assert registry.sha256_of(path) == registry.get("intel").primary.sha256
    with pytest.raises(DataError, match="ending in '/'"):
        registry.fetch("ring", url_override=served.url + "ring.g2o", cache_dir=cache)
    with pytest.raises(DataError, match="only http, https and file"):
        registry.fetch("intel", url_override="ftp://127.0.0.1/x.g2o", cache_dir=tmp_path / "c2")
    assert _all_paths(tmp_path / "c2") == []


def test_recorded_sources_are_pinned_urls():
    for entry in registry.REGISTRY.values():
        for f in entry.files:
            assert f.url.startswith("https://raw.githubusercontent.com/")
            assert len(f.sha256) == 64
    intel = registry.get("intel").primary
    assert intel.url == "https://raw.githubusercontent.com/david-m-rosen/SE-Sync/9b631b6b82d8/data/intel.g2o"


def test_fetch_with_progress_bar(served, tmp_path):
    """The rich progress bar path (used when stderr is a terminal) downloads the same bytes."""
    cache = tmp_path / "cache"
    path = registry.fetch("ring", url_override=served.url, cache_dir=cache, progress=True)
    assert registry.sha256_of(path) == registry.get("ring").primary.sha256
