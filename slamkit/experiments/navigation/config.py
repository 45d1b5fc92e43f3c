"""The ``navigation`` pipeline's config: its model :class:`NavigationPipeline` (scenarios with
their development and evaluation seeds, the NavigationConfig and EpisodeConfig sections every
variant shares, the variants, the robot's map source) and :func:`variants_of`, which builds each
variant's frozen configs with :func:`slamkit.config.build`."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Mapping, Sequence

import pydantic
from pydantic import BaseModel, Field

from slamkit.config import STRICT, YamlDocument, build, model_of, resolved
from slamkit.errors import ConfigError
from slamkit.experiments.config_models import (PipelineConfig, PlainName, Seed, Seeds, _nested, _refuse_moved_keys,
                                               seed_list)
from slamkit.experiments.navigation.benchmark import seed_blocks
from slamkit.experiments.navigation.episode import EpisodeConfig
from slamkit.experiments.navigation.map_source import MapSourceConfig
from slamkit.systems.lidar_slam import LidarSlamConfig
from slamkit.systems.navigation import MOVED_FIELDS, NavigationConfig


def _section(value: Any, where: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ConfigError(f"{where}: expected a mapping, got {type(value).__name__}")
    return dict(value)


def _variants(config: Mapping[str, Any]) -> list[tuple[str, NavigationConfig, EpisodeConfig]]:
    """:func:`variants_of` of a plain config mapping (the model's check of its sections, a
    notebook's or a test's mapping): its ``navigation``, ``episode`` and ``variants`` sections
    (no ``variants``: one called ``nominal``)."""
    variants = config.get("variants", [{"name": "nominal"}])
    if not isinstance(variants, list):
        raise ConfigError("variants: expected a list of {name, navigation, episode}")
    return variants_of(config.get("navigation"), config.get("episode"), variants)


def variants_of(navigation: Mapping[str, Any] | None, episode: Mapping[str, Any] | None,
                variants: "Sequence[NavigationVariant | Mapping[str, Any]]"
                ) -> list[tuple[str, NavigationConfig, EpisodeConfig]]:
    """(name, stack config, episode config) per variant: the base ``navigation``/``episode``
    sections with each variant's keys on top -- a key the variant names replaces the base's
    value as a whole (a nested section too: ``planning: {...}`` in a variant replaces the base's
    ``planning`` mapping, over the section's defaults) -- built by :func:`slamkit.config.build`."""
    base_nav = _section(navigation, "navigation")
    base_ep = _section(episode, "episode")
    plain = [v.model_dump(exclude_none=True) if isinstance(v, BaseModel) else v for v in variants]
    out = []
    for i, v in enumerate(plain):
        v = _section(v, f"variants.{i}")
        name = str(v.get("name", f"variant_{i}"))
        nav = build(NavigationConfig, {**base_nav, **_section(v.get("navigation"), f"variants.{name}.navigation")},
                    f"variants.{name}.navigation", moved=MOVED_FIELDS)
        ep = build(EpisodeConfig, {**base_ep, **_section(v.get("episode"), f"variants.{name}.episode")},
                   f"variants.{name}.episode")
        out.append((name, nav, ep))
    names = [n for n, _, _ in out]
    for v in plain:
        other = v.get("paired_with") if isinstance(v, Mapping) else None
        if other is not None and (other not in names or other == v.get("name")):
            raise ConfigError(f"variants.{v.get('name')}.paired_with: {other!r} is not another variant ({names})")
    return out


# --- the config model (slamkit.experiments.config_models): checked before anything runs ---------

class NavigationEvaluation(BaseModel):
    """``blocks`` disjoint blocks of ``block_size`` consecutive seeds from ``start`` on: the
    seeds a claimed rate is measured on (slamkit.experiments.navigation.benchmark)."""

    model_config = STRICT
    start: Seed
    blocks: Annotated[int, Field(ge=1, le=100)] = 3
    block_size: Annotated[int, Field(ge=1, le=10_000)] = 30


class NavigationScenarios(BaseModel):
    model_config = STRICT
    worlds: Annotated[list[Literal["office", "warehouse", "willow", "passage"]], Field(min_length=1)] = ["office"]
    #: the development seeds (the ones failures are looked at and fixed on)
    seeds: Seeds = 3
    #: the evaluation blocks, disjoint from ``seeds`` (None: development seeds only)
    evaluation: NavigationEvaluation | None = None
    n_obstacles: Annotated[int, Field(ge=0, le=20)] = 2
    #: the crossing traffic: constant-velocity shuttles or social-force people and forklifts
    #: (slamkit.sim.social_force.crossing_traffic)
    agents: Literal["constant_velocity", "social_force"] = "constant_velocity"
    #: world 'willow': the dataset registry's ``willow`` (default) or a map_server YAML path
    willow_map: str | None = None

    @pydantic.model_validator(mode="after")
    def _evaluation_is_fresh(self) -> "NavigationScenarios":
        if self.evaluation is not None:
            try:
                seed_blocks(seed_list(self.seeds), self.evaluation.model_dump())
            except ConfigError as exc:
                raise ValueError(str(exc)) from None
        return self


class NavigationVariant(BaseModel):
    model_config = STRICT
    name: PlainName
    #: another variant's name: the report adds this one's differences to it, paired by seed
    paired_with: PlainName | None = None
    navigation: dict[str, Any] = {}
    episode: dict[str, Any] = {}


class NavigationPipeline(PipelineConfig):
    pipeline: Literal["navigation"]
    scenarios: NavigationScenarios = NavigationScenarios()
    #: NavigationConfig fields (slamkit.systems.navigation) shared by every variant
    navigation: dict[str, Any] = {}
    #: EpisodeConfig fields (slamkit.experiments.navigation) shared by every variant
    episode: dict[str, Any] = {}
    variants: Annotated[list[NavigationVariant], Field(min_length=1)] = [NavigationVariant(name="nominal")]
    record_scenarios: Annotated[int, Field(ge=0, le=1000)] = 1
    #: the robot's map: MapSourceConfig fields (slamkit.experiments.navigation.map_source)
    map: dict[str, Any] = {}

    def check_options(self, config: dict[str, Any], doc: YamlDocument | None, source: str) -> None:
        # the base sections and every variant's overrides against the models of NavigationConfig
        # (its nested sections included) and EpisodeConfig, each error with its YAML line; a key
        # of the former flat NavigationConfig names the section it moved into (MOVED_FIELDS)
        sections: list[tuple[tuple, dict[str, Any], type]] = [
            (("navigation",), self.navigation, NavigationConfig), (("episode",), self.episode, EpisodeConfig)]
        for i, variant in enumerate(self.variants):
            sections += [(("variants", i, "navigation"), variant.navigation, NavigationConfig),
                         (("variants", i, "episode"), variant.episode, EpisodeConfig)]
        for prefix, values, cls in sections:
            if cls is NavigationConfig:
                _refuse_moved_keys(values, prefix, MOVED_FIELDS, doc, source)
            _nested(model_of(cls), values, doc, source, prefix)
        _variants(config)  # builds every variant's configs: the dataclasses' own checks
        # the map section's fields checked with their YAML line, then the config built (its
        # own checks: source, unknown, the nested lidar-SLAM config)
        _nested(model_of(MapSourceConfig), self.map, doc, source, ("map",))
        build(MapSourceConfig, config.get("map"), "map")

    def resolve(self, config: dict[str, Any]) -> dict[str, Any]:
        # the shared sections spelt out with NavigationConfig's, EpisodeConfig's and
        # MapSourceConfig's defaults (the map's lidar-SLAM mapping with LidarSlamConfig's); a
        # variant's sections stay overrides: each of its keys replaces the base's as a whole, over
        # base values that equal what build filled in before, so every variant builds the same
        robot_map = resolved(MapSourceConfig, config.get("map"), "map")
        robot_map["slam"] = resolved(LidarSlamConfig, robot_map["slam"], "map.slam")
        return {**config,
                "navigation": resolved(NavigationConfig, config.get("navigation"), "navigation", moved=MOVED_FIELDS),
                "episode": resolved(EpisodeConfig, config.get("episode"), "episode"),
                "map": robot_map}
