"""Pose-graph optimisation as an experiment: the library behind ``slamkit optimize`` and the
``pose_graph`` pipeline (datasets x solvers x initialisations -> one table, plots, recording).

Modules (a pipeline is a small package, issue 30): :mod:`.config` (the config model),
:mod:`.optimize` (one graph loaded, solved, scored and certified: ``optimize_source``, the
library behind ``slamkit optimize``), :mod:`.run` (the pipeline's combinations) and
:mod:`.report` (Markdown and plots). This module composes them into the
:class:`~slamkit.experiments.pipeline.Pipeline` ``PIPELINE`` and re-exports the names callers use.
"""

from __future__ import annotations

from slamkit.experiments.pipeline import Pipeline
from slamkit.experiments.pose_graph.config import POSE_GRAPH_RUN_KEYS, PoseGraphPipeline
from slamkit.experiments.pose_graph.optimize import (CERTIFY_AUTO_MAX_UNKNOWNS, CERTIFY_MODES, RETRY_INIT,
                                                     OptimizeReport, certify_decision, optimize_source,
                                                     write_outputs)
from slamkit.experiments.pose_graph.report import published_fstar
from slamkit.experiments.pose_graph.run import run as _run

__all__ = ["CERTIFY_AUTO_MAX_UNKNOWNS", "CERTIFY_MODES", "OptimizeReport", "PIPELINE", "POSE_GRAPH_RUN_KEYS",
           "PoseGraphPipeline", "RETRY_INIT", "certify_decision", "optimize_source", "published_fstar",
           "write_outputs"]


PIPELINE: Pipeline[PoseGraphPipeline, list[OptimizeReport]] = Pipeline(
    "pose_graph", _run, PoseGraphPipeline, list[OptimizeReport],
    "pose-graph datasets x solvers x initialisations")
