"""``slamkit data list|info|fetch`` through typer's runner (fetch against a 127.0.0.1 server)."""

from __future__ import annotations

import functools
import http.server
import json
import shutil
import threading

import pytest
from typer.testing import CliRunner

from slamkit.cli import app
from slamkit.data import registry

runner = CliRunner()


def test_list_json_shows_local_datasets_with_counts(shared_datasets, monkeypatch):
    # the folder beside the checkout is found by itself and labelled "shared" (with SLAMKIT_DATA
    # pointing at it, the same files would be labelled by that variable instead)
    monkeypatch.delenv("SLAMKIT_DATA", raising=False)
    result = runner.invoke(app, ["data", "list", "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    rows = {r["name"]: r for r in out["datasets"]}
    assert rows["intel"]["poses"] == 1728 and rows["intel"]["edges"] == 2512
    assert rows["intel"]["location"] == "shared" and rows["intel"]["format"] == "g2o"
    assert rows["ring"]["ground_truth"] is True
    assert all(r["available"] for r in out["datasets"])
    assert [root["label"] for root in out["search_roots"]][-1] == "cache"
    everything = json.loads(runner.invoke(app, ["data", "list", "--all", "--json"]).stdout)
    assert len(everything["datasets"]) == len(registry.REGISTRY)
    three_d = json.loads(runner.invoke(app, ["data", "list", "--all", "--kind", "pose_graph_3d", "--json"]).stdout)
    names = {r["name"] for r in three_d["datasets"]}
    assert {"torus3d", "parking-garage", "cubicle", "sphere400"} <= names
    assert all(r["kind"] == "pose_graph_3d" for r in three_d["datasets"])


def test_list_table_and_verify(shared_datasets):
    result = runner.invoke(app, ["data", "list", "--verify"])
    assert result.exit_code == 0, result.output
    assert "torus3d" in result.stdout and "MISMATCH" not in result.stdout
    assert "ok" in result.stdout


def test_info_json_has_sources_licence_and_flagged_references():
    result = runner.invoke(app, ["data", "info", "torus3d", "--json"])
    assert result.exit_code == 0, result.output
    info = json.loads(result.stdout)
    assert info["files"][0]["sha256"].startswith("1ef8831023b37218")
    assert "david-m-rosen/SE-Sync" in info["files"][0]["source"]
    assert "LGPL-3.0" in info["licence"]
    refs = {r["kind"]: r for r in info["references"]}
    assert refs["sesync_fstar"]["value"] == 24230.0 and refs["sesync_fstar"]["published"] is True
    assert refs["gtsam_local_check"]["published"] is False


def test_info_text_and_unknown_name():
    result = runner.invoke(app, ["data", "info", "city10000"])
    assert result.exit_code == 0, result.output
    assert "ISAM2_GT_city10000.txt" in result.stdout and "sesync_fstar = 638.6" in result.stdout
    bad = runner.invoke(app, ["data", "info", "city1000"])
    assert bad.exit_code == 2
    assert "did you mean city10000" in bad.output


@pytest.fixture
def server(tmp_path, shared_datasets):
    folder = tmp_path / "www"
    (folder / "bad").mkdir(parents=True)
    shutil.copy(shared_datasets / "pose_graph_3d" / "tinyGrid3D.g2o", folder / "tiny.g2o")
    # same length, one byte changed: a longer file now stops at the recorded size before any sha256
    (folder / "bad" / "tiny.g2o").write_bytes((folder / "tiny.g2o").read_bytes().replace(b"EDGE", b"EDGX", 1))

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(folder)))
    thread = threading.Thread(target=httpd.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}/"
    httpd.shutdown()
    httpd.server_close()


def test_fetch_command(server, tmp_path):
    cache = tmp_path / "cache"
    result = runner.invoke(app, ["data", "fetch", "tinygrid3d", "--url", server + "tiny.g2o", "--cache-dir", str(cache)])
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() == str(cache / "pose_graph_3d" / "tinyGrid3D.g2o")
    bad_cache = tmp_path / "bad-cache"
    bad = runner.invoke(app, ["data", "fetch", "tinygrid3d", "--url", server + "bad/tiny.g2o",
                              "--cache-dir", str(bad_cache)])
    assert bad.exit_code == 2 and "sha256 mismatch" in bad.output  # bad input (issue 10 exit codes)
    assert not bad_cache.exists() or not any(bad_cache.rglob("*"))
