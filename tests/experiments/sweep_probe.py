"""A pipeline for the sweep tests, imported as a sweep plugin in every worker: it appends the key of
its config to ``log`` (one line per run, so a test can count how often each cell ran), sleeps
``sleep_s``, raises when ``fail`` is true, and reports ``value_m = 2 x + sum(offsets) + seed / 10``
per seed (``offsets``, a list, defaults to none)."""

from __future__ import annotations

import os
import time

from slamkit.experiments.pipeline import PIPELINES, Pipeline, PipelineOutput, register_pipeline
from slamkit.experiments.results import RunRecord
from slamkit.experiments.sweep import config_key

NAME = "sweep_probe"


def run(config, folder, progress, observer) -> PipelineOutput[None]:
    # registered without a config model: its keys are free, the validated model's extras
    config = config.model_dump(exclude_none=True)
    if config.get("log"):
        with open(config["log"], "a") as f:
            f.write(f"{config_key(config)} {os.getpid()}\n")
    time.sleep(float(config.get("sleep_s", 0.0)))
    if config.get("fail"):
        raise RuntimeError(f"probe asked to fail at x={config.get('x')}")
    x = float(config.get("x", 0.0)) + sum(float(o) for o in config.get("offsets", [])) / 2
    seeds = config.get("seeds", [0])
    runs = [RunRecord(str(config.get("dataset", "probe")), "probe", {"value_m": 2 * x + s / 10}, s) for s in seeds]
    return PipelineOutput(runs, "# probe\n")


def square(x: int) -> int:
    """An executor task."""
    if x < 0:
        raise ValueError(f"negative {x}")
    return x * x


def worker_env(_: object) -> dict[str, str | None]:
    """An executor task: the thread variables the worker runs with."""
    from slamkit.experiments.executors import ONE_THREAD_ENV

    return {k: os.environ.get(k) for k in ONE_THREAD_ENV}


def ensure_registered() -> None:
    """Register the probe in this process (again, after a test module unregistered it)."""
    if NAME not in PIPELINES:
        register_pipeline(Pipeline(NAME, run))


ensure_registered()  # on import: what a worker does with the plugin
