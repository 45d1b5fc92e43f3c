"""Sweeps on Ray (issue 17): a real local Ray instance (head on 127.0.0.1, 2 CPUs, no dashboard),
started once for the module and shut down afterwards, runs the executor contract and a small sweep
whose aggregate must equal the local pool's."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from slamkit.experiments.executors import RayExecutor, TaskFailure, start_local_ray
from slamkit.experiments.pipeline import PIPELINES
from slamkit.experiments.sweep import run_sweep

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def ray_instance():
    import ray

    import sweep_probe

    sweep_probe.ensure_registered()  # the probe pipeline in this process too

    # the workers find the probe plugin through the job's runtime environment
    instance = start_local_ray(num_cpus=2, runtime_env={"env_vars": {"PYTHONPATH": str(HERE)}})
    yield ray
    instance.shutdown()
    if "sweep_probe" in PIPELINES:
        PIPELINES.unregister("sweep_probe")


def test_the_ray_executor_yields_each_task_once_with_failures_and_one_blas_thread(ray_instance) -> None:
    import sweep_probe

    ex = RayExecutor()
    for x in (3, -1, 4, 5):
        ex.submit(sweep_probe.square, x)
    ex.submit(sweep_probe.worker_env, None)
    outcomes = dict(ex.as_completed())
    ex.close()
    assert ray_instance.is_initialized()  # the connection it found is the caller's: left open
    assert {k: outcomes[k] for k in (3, 4, 5)} == {3: 9, 4: 16, 5: 25}
    assert outcomes[-1] == TaskFailure("ValueError", "negative -1")
    assert set(outcomes[None].values()) == {"1"}


def test_a_sweep_on_ray_equals_the_same_sweep_on_the_local_pool(ray_instance, tmp_path: Path) -> None:
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({"pipeline": {"pipeline": "sweep_probe", "x": 0.0}, "plugins": ["sweep_probe"],
                                     "seeds": 3, "axes": {"x": [1.0, 2.0], "fail": [False, True]}}))
    with RayExecutor() as ex:
        on_ray = run_sweep(sweep, tmp_path / "ray", executor=ex, progress=False)
    local = run_sweep(sweep, tmp_path / "local", workers=2, progress=False)
    assert (on_ray.ran, on_ray.failed) == (12, 6)
    assert on_ray.results["summary"] == local.results["summary"]
    assert [(c["key"], c["status"]) for c in on_ray.results["cells"]] == \
        [(c["key"], c["status"]) for c in local.results["cells"]]
    resumed = run_sweep(sweep, tmp_path / "ray", executor="ray", resume=True, progress=False)
    assert resumed.ran == 0 and ray_instance.is_initialized()


def test_a_local_instance_started_by_the_executor_writes_nothing_in_the_home_folder(tmp_path: Path) -> None:
    # Ray's default for a new local instance writes ~/.ray/auth_token; the executor's instance
    # keeps token authentication with the token in its environment instead (a separate process:
    # the module's instance is already running in this one)
    home = tmp_path / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_AUTH")}
    code = ("import os; from slamkit.experiments.executors import RayExecutor, RAY_TOKEN_ENV\n"
            "import sweep_probe\n"
            "with RayExecutor() as ex:\n"
            "    ex.submit(sweep_probe.square, 7)\n"
            "    outcomes = dict(ex.as_completed())\n"
            "print(outcomes[7], RAY_TOKEN_ENV in os.environ)\n")
    done = subprocess.run([sys.executable, "-c", code], env={**env, "HOME": str(home), "PYTHONPATH": str(HERE)},
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split()[-2:] == ["49", "False"]
    assert list(home.iterdir()) == []


# --- issue 31: a local instance listens on loopback only and leaves no session folder ----------

_LISTEN_PROBE = """
import json, os, sys
import psutil
from slamkit.experiments.executors import RayExecutor
import sweep_probe

def listening(pids):
    out = []
    for pid in pids:
        try:
            for c in psutil.Process(pid).net_connections(kind="inet"):
                if c.status == psutil.CONN_LISTEN:
                    out.append([pid, c.laddr.ip, c.laddr.port])
        except psutil.NoSuchProcess:
            pass
    return out

with RayExecutor() as ex:
    ex.submit(sweep_probe.square, 7)
    outcomes = dict(ex.as_completed())
    me = psutil.Process()
    # the driver, and every process of the instance (GCS, raylet, agents, workers: its descendants)
    pids = [me.pid] + [p.pid for p in me.children(recursive=True)]
    names = sorted({psutil.Process(p).name() for p in pids if psutil.pid_exists(p)})
    sockets = listening(pids)
print(json.dumps({"square": outcomes[7], "sockets": sockets, "names": names}))
"""


def test_a_local_instance_listens_on_loopback_only_and_leaves_no_session_folder(tmp_path: Path) -> None:
    """Before: GCS, raylet, workers and the driver listened on all interfaces (``::``), the
    runtime-env agent on the machine's LAN address, and every run left a /tmp/ray/session_*
    folder. Ray's system temp folder is a fresh one here (TMPDIR), so anything left is seen; it is
    short, as the session's Unix socket paths must fit 107 bytes."""
    import ipaddress
    import json
    import shutil
    import tempfile

    system_tmp = Path(tempfile.mkdtemp(prefix="skt", dir="/tmp"))
    try:
        env = {k: v for k, v in os.environ.items() if not k.startswith(("RAY_AUTH", "RAY_TMPDIR"))}
        done = subprocess.run([sys.executable, "-c", _LISTEN_PROBE],
                              env={**env, "TMPDIR": str(system_tmp), "PYTHONPATH": str(HERE)},
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr[-3000:]
        report = json.loads(done.stdout.strip().splitlines()[-1])
        assert report["square"] == 49
        assert {"gcs_server", "raylet"} <= set(report["names"]), report["names"]
        assert len(report["sockets"]) >= 4, report  # GCS, raylet, the driver's core worker, an agent
        for pid, ip, port in report["sockets"]:
            address = ipaddress.ip_address(ip)
            address = getattr(address, "ipv4_mapped", None) or address  # ::ffff:127.0.0.1
            assert address.is_loopback, (pid, ip, port, report["names"])
        assert list(system_tmp.iterdir()) == []  # no session folder, no slamkit-ray-* folder
    finally:
        shutil.rmtree(system_tmp, ignore_errors=True)
