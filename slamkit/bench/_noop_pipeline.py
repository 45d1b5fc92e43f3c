"""A pipeline that does nothing (``bench_noop``), registered on import: ``slamkit bench sweep``
names this module as a sweep plugin to time the sweep machinery alone."""

from __future__ import annotations

from typing import Literal

from slamkit.experiments.config_models import PipelineConfig
from slamkit.experiments.pipeline import PIPELINES, Pipeline, PipelineOutput, register_pipeline
from slamkit.experiments.results import RunRecord

NAME = "bench_noop"


class NoopConfig(PipelineConfig):
    pipeline: Literal["bench_noop"]
    #: the sweep's axis (any number; reported back as the run's one metric)
    x: float = 0.0


def run(config: NoopConfig, folder, progress, observer) -> PipelineOutput[None]:
    return PipelineOutput([RunRecord("none", "noop", {"x": config.x}, None)], "# noop\n")


if NAME not in PIPELINES:
    register_pipeline(Pipeline(NAME, run, NoopConfig))
