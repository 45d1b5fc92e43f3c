"""Controllers by registry name: what pipeline configs, the notebooks and the benchmark type.

``make_controller("mpc_osqp", {"horizon": 15})`` builds the controller with its config's defaults
overridden by ``params`` (the ``controller_params`` of a ``local_planning`` pipeline). This table is
the one place that maps a controller name to its class and config; names follow the one naming
rule of :mod:`slamkit.naming` (an old spelling such as ``mpc-osqp`` still builds, with a
deprecation warning; an unknown name is a ConfigError suggesting the closest).

The three MPC names are one controller with its solver preset (``MPCConfig.solver``): ``mpc``
(IPOPT), ``mpc_osqp`` (the real-time-iteration QP), ``mpc_fatrop``; a ``solver`` given in
``params`` wins over the preset, as it always did.

A user's controller joins with :func:`register_controller` (from a module named in a config's
``plugins:``) or as an entry point of the group ``slamkit.controllers`` whose object is a
:class:`ControllerSpec`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from slamkit.control.dwa import DWAConfig, DWAController
from slamkit.control.mpc import MPCConfig, MPCController
from slamkit.control.potential_fields import PotentialFieldConfig, PotentialFieldController
from slamkit.control.protocols import Controller
from slamkit.control.trajectory_rollout import RolloutConfig, RolloutController
from slamkit.config import build
from slamkit.errors import ConfigError
from slamkit.naming import Registry


@dataclass(frozen=True)
class ControllerSpec:
    """``controller(config)`` builds it (``controller(config, rng=...)`` when ``needs_rng``);
    ``preset`` holds the config values the name itself stands for."""

    controller: type
    config: type
    preset: Mapping[str, Any] = field(default_factory=dict)
    needs_rng: bool = False


def _adapt(name: str, entry: Any) -> ControllerSpec:
    if not isinstance(entry, ControllerSpec):
        raise ConfigError(f"a controller entry point names a ControllerSpec (slamkit.control.registry), "
                          f"got {type(entry).__name__}")
    return entry


CONTROLLERS: Registry[ControllerSpec] = Registry("controller", {
    "potential_fields": ControllerSpec(PotentialFieldController, PotentialFieldConfig, needs_rng=True),
    "dwa": ControllerSpec(DWAController, DWAConfig),
    "rollout": ControllerSpec(RolloutController, RolloutConfig),
    "mpc": ControllerSpec(MPCController, MPCConfig, {"solver": "ipopt"}),
    "mpc_osqp": ControllerSpec(MPCController, MPCConfig, {"solver": "osqp"}),
    "mpc_fatrop": ControllerSpec(MPCController, MPCConfig, {"solver": "fatrop"}),
}, group="slamkit.controllers", adapt=_adapt)


def register_controller(name: str, spec: ControllerSpec) -> None:
    """Make controller ``name`` usable in configs, the CLI and the benchmark."""
    CONTROLLERS.register(name, _adapt(name, spec))


def controller_config(name: str, params: Mapping[str, Any] | None = None) -> Any:
    """The config dataclass of controller ``name``: its defaults, the name's preset, then
    ``params``, built by :func:`slamkit.config.build` (a list given for a tuple-valued field, the
    MPC's limits and weights, becomes a tuple; an unknown key names the controller)."""
    key = CONTROLLERS.canonical(name)
    spec = CONTROLLERS[key]
    return build(spec.config, {**spec.preset, **dict(params or {})}, f"controller {key!r}")


def make_controller(name: str, params: Mapping[str, Any] | None = None, seed: int = 0) -> Controller:
    """Controller ``name`` with ``params`` over its config; ``seed`` seeds the ones that draw
    random numbers (the potential fields' random-walk escape)."""
    key = CONTROLLERS.canonical(name)
    spec, config = CONTROLLERS[key], controller_config(key, params)
    if spec.needs_rng:
        return spec.controller(config, rng=np.random.default_rng(seed))
    return spec.controller(config)


def controller_names() -> list[str]:
    return CONTROLLERS.names()
