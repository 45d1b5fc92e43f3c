"""The ``pose_graph_outliers`` pipeline's config model: datasets x outlier kinds x counts x seeds x
back-ends, with the OutlierConfig and RobustSolveConfig fields every cell shares (checked against
those dataclasses' own models; the fields the combinations set are refused there)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field

from slamkit.backend.robust import RobustSolveConfig
from slamkit.config import YamlDocument, model_of, resolved
from slamkit.experiments.config_models import (PipelineConfig, _check_pose_graph_sources, _nested,
                                               _refuse_pipeline_keys)
from slamkit.sim.outliers import OutlierConfig


class PoseGraphOutliersPipeline(PipelineConfig):
    pipeline: Literal["pose_graph_outliers"]
    datasets: Annotated[list[str], Field(min_length=1)]
    counts: Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=1)] = [0, 10, 100, 1000]
    kinds: Annotated[list[Literal["random", "local", "grouped"]], Field(min_length=1)] = ["random"]
    backends: Annotated[list[Literal["none", "huber", "cauchy", "dcs", "switchable", "gnc", "pcm", "pcm_gnc"]],
                        Field(min_length=1)] = ["none", "huber", "cauchy", "dcs", "switchable", "gnc", "pcm", "pcm_gnc"]
    seeds: Annotated[list[int], Field(min_length=1)] = [0]
    #: slamkit.sim.outliers.OutlierConfig fields other than kind and count
    outliers: dict[str, Any] = {}
    #: slamkit.backend.robust.RobustSolveConfig fields other than backend
    solver: dict[str, Any] = {}

    def check_options(self, config: dict[str, Any], doc: YamlDocument | None, source: str) -> None:
        _check_pose_graph_sources(self.datasets, doc, source)
        _refuse_pipeline_keys(self.outliers, "outliers", {"kind": "kinds", "count": "counts"}, doc, source)
        _refuse_pipeline_keys(self.solver, "solver", {"backend": "backends"}, doc, source)
        _nested(model_of(OutlierConfig), self.outliers, doc, source, ("outliers",))
        _nested(model_of(RobustSolveConfig), self.solver, doc, source, ("solver",))

    def resolve(self, config: dict[str, Any]) -> dict[str, Any]:
        # every OutlierConfig / RobustSolveConfig field but those each cell sets (kind, count,
        # backend), with its default spelt out: config.yaml says what every cell ran with
        outliers = resolved(OutlierConfig, config.get("outliers"), "pose_graph_outliers.outliers",
                            exclude=("kind", "count"))
        solver = resolved(RobustSolveConfig, config.get("solver"), "pose_graph_outliers.solver", exclude=("backend",))
        return {**config, "outliers": outliers, "solver": solver}
