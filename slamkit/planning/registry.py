"""Planners by registry name: what configs, the CLI and the benchmark type.

``make_planner("rrt_star", rng=np.random.default_rng(3), max_iterations=2000)`` builds the
planner with its config's defaults overridden by the keyword arguments. Names follow the one
naming rule of :mod:`slamkit.naming`; the old hyphenated spellings (``rrt-star``) still work and
are reported as deprecated.

A user's planner joins with :func:`register_planner` (from a module named in a config's
``plugins:``) or as an entry point of the group ``slamkit.planners`` whose object is a
:class:`PlannerSpec`; it is built like the built-in ones: ``planner(config, [rng=...,] hook=...)``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from slamkit.config import build
from slamkit.errors import ConfigError
from slamkit.naming import Registry
from slamkit.planning.astar import AStarConfig, AStarPlanner
from slamkit.planning.dijkstra import DijkstraConfig, DijkstraPlanner
from slamkit.planning.dstar_lite import DStarLiteConfig, DStarLitePlanner
from slamkit.planning.informed_rrt_star import InformedRRTStarPlanner
from slamkit.planning.prm import PRMConfig, PRMPlanner
from slamkit.planning.protocols import Hook, Planner
from slamkit.planning.rrt import RRTConfig, RRTPlanner
from slamkit.planning.rrt_connect import RRTConnectConfig, RRTConnectPlanner
from slamkit.planning.rrt_star import RRTStarConfig, RRTStarPlanner

class PlannerSpec(NamedTuple):
    """A registry row: ``planner(config_cls(**params), [rng=...,] hook=...)`` builds one."""

    planner: type
    config: type
    #: the constructor takes ``rng`` (sampling planners)
    needs_rng: bool = False


def _adapt(name: str, entry: Any) -> PlannerSpec:
    if not isinstance(entry, PlannerSpec):
        raise ConfigError(f"a planner entry point names a PlannerSpec (slamkit.planning.registry), "
                          f"got {type(entry).__name__}")
    return entry


#: name -> (planner class, config class, needs an rng)
PLANNERS: Registry[PlannerSpec] = Registry("planner", {
    "astar": PlannerSpec(AStarPlanner, AStarConfig, False),
    "dijkstra": PlannerSpec(DijkstraPlanner, DijkstraConfig, False),
    "dstar_lite": PlannerSpec(DStarLitePlanner, DStarLiteConfig, False),
    "prm": PlannerSpec(PRMPlanner, PRMConfig, True),
    "rrt": PlannerSpec(RRTPlanner, RRTConfig, True),
    "rrt_connect": PlannerSpec(RRTConnectPlanner, RRTConnectConfig, True),
    "rrt_star": PlannerSpec(RRTStarPlanner, RRTStarConfig, True),
    "informed_rrt_star": PlannerSpec(InformedRRTStarPlanner, RRTStarConfig, True),
}, group="slamkit.planners", adapt=_adapt)
GRID_PLANNERS = ("astar", "dijkstra", "dstar_lite")


def canonical(name: str) -> str:
    return PLANNERS.canonical(name)


def make_planner(name: str, rng: np.random.Generator | None = None, hook: Hook | None = None,
                 **config: Any) -> Planner:
    key = canonical(name)
    cls, cfg_cls, needs_rng = PLANNERS[key]
    cfg = build(cfg_cls, config, key)
    if needs_rng:
        return cls(cfg, rng=np.random.default_rng(0) if rng is None else rng, hook=hook)
    return cls(cfg, hook=hook)


def register_planner(name: str, spec: PlannerSpec) -> None:
    """Make planner ``name`` usable in configs, the CLI and the benchmark."""
    PLANNERS.register(name, _adapt(name, spec))


def planner_names() -> list[str]:
    return list(PLANNERS)

