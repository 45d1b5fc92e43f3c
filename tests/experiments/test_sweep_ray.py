"""Sweeps on Ray (issue 17): a real local Ray instance (head on 127.0.0.1, 2 CPUs, no dashboard),
started once for the module and shut down afterwards, runs the executor contract and a small sweep
whose aggregate must equal the local pool's."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from slamkit.experiments.executors import RayExecutor, TaskFailure
from slamkit.experiments.pipeline import PIPELINES
from slamkit.experiments.sweep import run_sweep

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def ray_instance():
    import ray

    import sweep_probe

    sweep_probe.ensure_registered()  # the probe pipeline in this process too

    # the workers find the probe plugin through the job's runtime environment
    ray.init(num_cpus=2, include_dashboard=False, _node_ip_address="127.0.0.1", log_to_driver=False,
             runtime_env={"env_vars": {"PYTHONPATH": str(HERE)}})
    yield ray
    ray.shutdown()
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
