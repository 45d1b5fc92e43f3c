"""A pipeline that does nothing (``bench_noop``), registered on import: ``slamkit bench sweep``
names this module as a sweep plugin to time the sweep machinery alone."""

from __future__ import annotations

from slamkit.experiments.pipeline import PIPELINES, Pipeline, PipelineOutput, register_pipeline
from slamkit.experiments.results import RunRecord

NAME = "bench_noop"


def run(config, folder, progress, observer) -> PipelineOutput[None]:
    return PipelineOutput([RunRecord("none", "noop", {"x": float(config.get("x", 0))}, None)], "# noop\n")


if NAME not in PIPELINES:
    register_pipeline(Pipeline(NAME, run))
