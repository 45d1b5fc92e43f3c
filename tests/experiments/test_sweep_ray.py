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

from slamkit.experiments.executors import RAY_TOKEN_ENV, RayExecutor, TaskFailure, start_local_ray
from slamkit.experiments.pipeline import PIPELINES
from slamkit.experiments.sweep import run_sweep

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def ray_instance():
    import ray

    import sweep_probe

    sweep_probe.ensure_registered()  # the probe pipeline in this process too

    # the workers find the probe plugin through the job's runtime environment
    token_set = start_local_ray(num_cpus=2, _node_ip_address="127.0.0.1",
                                runtime_env={"env_vars": {"PYTHONPATH": str(HERE)}})
    yield ray
    ray.shutdown()
    if token_set:
        os.environ.pop(RAY_TOKEN_ENV, None)
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
