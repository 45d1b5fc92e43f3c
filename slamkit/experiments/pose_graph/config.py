"""The ``pose_graph`` pipeline's config model: datasets x solvers x initialisations, one robust
kernel, the certificate mode and the OptimizeConfig ``options`` every combination shares
(checked against :class:`slamkit.backend.solvers.OptimizeConfig`'s own model; the three fields
the combinations set are refused there)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field

from slamkit.backend.solvers import OptimizeConfig
from slamkit.config import YamlDocument, model_of, resolved
from slamkit.experiments.config_models import (PipelineConfig, _check_pose_graph_sources, _nested,
                                               _refuse_pipeline_keys)


def _optimize_options() -> type:
    return model_of(OptimizeConfig)


class PoseGraphPipeline(PipelineConfig):
    pipeline: Literal["pose_graph"]
    datasets: Annotated[list[str], Field(min_length=1)]
    solvers: Annotated[list[Literal["lm", "gn", "dogleg", "isam2"]], Field(min_length=1)] = ["lm"]
    inits: Annotated[list[Literal["file", "odometry", "lago", "chordal"]], Field(min_length=1)] = ["file"]
    robust: Literal["none", "huber", "cauchy", "dcs"] = "none"
    #: SE-Sync optimality certificates: auto (least squares, up to 40k rotation unknowns), on, off
    certify: Literal["auto", "on", "off"] = "auto"
    options: dict[str, Any] = {}

    def check_options(self, config: dict[str, Any], doc: YamlDocument | None, source: str) -> None:
        _check_pose_graph_sources(self.datasets, doc, source)
        _refuse_pipeline_keys(self.options, "options", POSE_GRAPH_RUN_KEYS, doc, source)
        _nested(_optimize_options(), self.options, doc, source, ("options",))

    def resolve(self, config: dict[str, Any]) -> dict[str, Any]:
        # options: every OptimizeConfig field but the three each run sets (solvers x inits, robust)
        options = resolved(OptimizeConfig, config.get("options"), "pose_graph.options",
                           exclude=POSE_GRAPH_RUN_KEYS)
        return {**config, "options": options}


#: OptimizeConfig fields a pose_graph run sets itself (field -> the pipeline key that lists them)
POSE_GRAPH_RUN_KEYS = {"solver": "solvers", "init": "inits", "robust": "robust"}
