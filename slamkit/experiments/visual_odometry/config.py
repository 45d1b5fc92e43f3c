"""The ``visual_odometry`` pipeline's config model: the image sequences (registry names or the
KITTI layout's files), the VisualOdometryConfig ``vo`` fields (checked against that dataclass's
own model), whether to run without bundle adjustment too, and a frame cap."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, Field

from slamkit.config import STRICT, YamlDocument, model_of, resolved
from slamkit.experiments.config_models import PipelineConfig, PlainName, _nested
from slamkit.systems.visual_odometry import VisualOdometryConfig


class ImageSequenceModel(BaseModel):
    """A camera sequence in the KITTI odometry layout (``times`` optional: frame index x 0.1 s)."""

    model_config = STRICT
    name: PlainName
    images: str
    calib: str
    poses: str | None = None
    times: str | None = None


class VisualOdometryPipeline(PipelineConfig):
    pipeline: Literal["visual_odometry"]
    #: registry names (``kitti-vo-a``) or {name, images, calib, poses, times}
    sequences: Annotated[list[Union[str, ImageSequenceModel]], Field(min_length=1)]
    #: fields of slamkit.systems.visual_odometry.VisualOdometryConfig (nested ``orb``, ``ba``)
    vo: dict[str, Any] = {}
    #: also run without bundle adjustment (window 0), so its effect is measured in the same run
    compare_without_ba: bool = True
    max_frames: Annotated[int, Field(ge=2, le=1_000_000)] | None = None

    def check_options(self, config: dict[str, Any], doc: YamlDocument | None, source: str) -> None:
        _nested(model_of(VisualOdometryConfig), self.vo, doc, source, ("vo",))

    def resolve(self, config: dict[str, Any]) -> dict[str, Any]:
        # every VisualOdometryConfig field (ORB, bundle adjustment...) with its default spelt out
        return {**config, "vo": resolved(VisualOdometryConfig, config.get("vo"), "visual_odometry.vo")}
