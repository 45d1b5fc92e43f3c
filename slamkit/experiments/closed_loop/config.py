"""The ``local_planning`` pipeline's config model: controllers (registry names, with their own
parameters), the seeded scenarios and the ClosedLoopConfig ``closed_loop`` fields every episode
shares (checked against those dataclasses' own models)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

import pydantic
from pydantic import BaseModel, Field

from slamkit.control.registry import CONTROLLERS, controller_config
from slamkit.config import STRICT, YamlDocument, dump, model_of, resolved, validate
from slamkit.errors import ConfigError
from slamkit.experiments.closed_loop.episode import ClosedLoopConfig
from slamkit.experiments.config_models import PipelineConfig, Seeds, _nested
from slamkit.naming import suggestion


# --- the config model (slamkit.experiments.config_models): checked before anything runs ---------

class LocalPlanningScenarios(BaseModel):
    model_config = STRICT
    kinds: Annotated[list[Literal["office", "warehouse", "open"]], Field(min_length=1)] = ["office"]
    seeds: Seeds = 5
    n_obstacles: Annotated[int, Field(ge=0, le=100)] = 3
    obstacle_speed_mps: tuple[Annotated[float, Field(ge=0, le=10)], Annotated[float, Field(ge=0, le=10)]] = (0.2, 0.5)
    obstacle_min_side_m: Annotated[float, Field(ge=0, le=100)] = 0.5


class LocalPlanningPipeline(PipelineConfig):
    pipeline: Literal["local_planning"]
    #: names in ``slamkit.control.registry.CONTROLLERS`` (checked in ``check_options``)
    controllers: Annotated[list[str], Field(min_length=1)] = ["dwa", "mpc"]
    scenarios: LocalPlanningScenarios = LocalPlanningScenarios()
    closed_loop: dict[str, Any] = {}
    controller_params: dict[str, dict[str, Any]] = {}
    record_scenarios: Annotated[int, Field(ge=0, le=1000)] = 1

    def check_options(self, config: dict[str, Any], doc: YamlDocument | None, source: str) -> None:
        _nested(model_of(ClosedLoopConfig), self.closed_loop, doc, source, ("closed_loop",))
        for i, name in enumerate(self.controllers):
            if name not in CONTROLLERS:
                where = doc.where(("controllers", i)) if doc is not None else source
                raise ConfigError(f"{where}: controllers.{i}: unknown controller {name!r}"
                                  + suggestion(name, CONTROLLERS) + f"; known: {', '.join(CONTROLLERS)}")
        for name, params in self.controller_params.items():
            if name not in CONTROLLERS:
                validate(pydantic.create_model("ControllerParams", __config__=STRICT,
                                               **{k: (dict, None) for k in CONTROLLERS}),
                         {name: params}, doc, source, ("controller_params",))
            _nested(model_of(CONTROLLERS.get(name).config), params, doc, source, ("controller_params", name))

    def resolve(self, config: dict[str, Any]) -> dict[str, Any]:
        # every ClosedLoopConfig field, and every field of each listed controller's config (its
        # defaults, the name's preset, the given params: what make_controller builds), spelt out
        params = dict(config.get("controller_params") or {})
        for name in config.get("controllers") or type(self).model_fields["controllers"].default:
            built = dump(controller_config(name, params.get(name)))
            params[name] = {k: v for k, v in built.items() if v is not None}
        return {**config, "closed_loop": resolved(ClosedLoopConfig, config.get("closed_loop"), "closed_loop"),
                "controller_params": params}
