"""Estimator registry: the names users type in configs -> factories that build an estimator for
one ``Sequence``.

One table spans the filters of ``slamkit.estimation`` (their rows and construction come from
``slamkit.estimation.registry``) and the smoothers of ``slamkit.backend`` (ARCHITECTURE.md
section 6 names: ``ekf``, ``ukf``, ``pf``, ``mcl``, ``histogram``, ``ekf_slam``, ``fastslam``,
``batch``, ``isam2``, ``fixed_lag``; for inertial sequences ``es_ekf``, ``isam2_imu``,
``fixed_lag_imu``, which read their start state and noise from the sequence's
:class:`~slamkit.data.inertial.InertialSetup` instead of ``NoiseParams``). Smoother modules are imported only when one is built.
Both tables are a :class:`slamkit.naming.Registry`: snake_case names, old spellings accepted
with a deprecation warning, an unknown name one ConfigError with the closest suggestion.

This table is the one registration point for estimators (issue 32): the filters' rows are read
live from ``slamkit.estimation.registry`` (never copied), and a user's own estimator joins with
:func:`register_estimator` (from a module named in a config's ``plugins:`` or ``--plugin``) or
as an entry point of the group ``slamkit.estimators`` whose object is an :class:`EstimatorSpec`::

    [project.entry-points."slamkit.estimators"]
    my_filter = "my_pkg.slamkit_plugin:MY_FILTER"     # an EstimatorSpec named my_filter

A plug-in's class is built with ``cls.from_sequence(sequence, config=..., rng=...)`` when it
has that classmethod, else like the built-in filters: ``cls([world_p_landmarks,] noise=NoiseParams,
config=..., [rng=...])`` (the landmark map only with ``needs_landmark_map``, ``config`` only with
a ``config`` class, ``rng`` only when ``random``). Its ``estimates`` ('pose' or 'pose_and_map')
says under which heading the reports file it.

Every factory reads the noise the estimator should assume from ``Sequence.metadata`` with
:class:`slamkit.data.noise.NoiseParams` (``odometry_sigma``, ``range_bearing_sigma``; see
``slamkit.sim.landmark_world``) unless the config overrides it (``sigma_v_mps``,
``sigma_omega_radps``, ``sigma_range_m``, ``sigma_bearing_rad``); other parameters go to the
estimator's config dataclass by field name (one per smoother: ``BatchLandmarkSLAMConfig``,
``Isam2LandmarkSLAMConfig``, ``FixedLagLandmarkSLAMConfig``). Localisation filters (``ekf``,
``ukf``, ``pf``, ``mcl``) are given the sequence's true landmark map; SLAM filters and smoothers
are not. Every online estimator starts from :func:`prior_of` (``slamkit.data.noise``, imported
here for the runner).
"""

from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass
from typing import Any, Callable, Literal, Mapping

import numpy as np

from slamkit.data.estimate import BatchEstimator, Estimator
from slamkit.data.noise import SENSOR_SIGMAS, NoiseParams
from slamkit.data.noise import prior_of  # noqa: F401  (the runner's and the benchmarks' prior)
from slamkit.data.sequence import Sequence
from slamkit.config import build as build_config
from slamkit.errors import ConfigError
from slamkit.naming import Registry, load_target

#: what a factory returns for one sequence
Factory = Callable[[Sequence], "Estimator | BatchEstimator"]


KINDS = ("filter", "smoother", "batch")
#: what an estimator estimates; the reports file 'pose' estimators given the landmark map under
#: localisation, the others under "pose only", and 'pose_and_map' ones under SLAM
ESTIMATES = ("pose", "pose_and_map")
SEQUENCE_KINDS = ("planar", "inertial")


@dataclass(frozen=True)
class EstimatorSpec:
    """One registry row: ``target`` is ``module:attribute`` of the estimator class (or the class
    itself, stored as that string; ``config`` likewise the config class or its name).

    ``kind`` 'filter' and 'smoother' estimators are driven with ``reset(prior)``, ``step(event)``,
    ``estimate()``; a 'batch' one with ``solve(sequence)``."""

    name: str
    kind: Literal["filter", "smoother", "batch"]
    target: str
    #: localisation against the true landmark map (not SLAM)
    needs_landmark_map: bool
    #: name of the config dataclass in the same module (None: the class takes keyword params)
    config: str | None
    #: the constructor takes ``rng`` (particle methods)
    random: bool
    description: str
    #: the sequences it runs on: 'planar' (landmark worlds and datasets) or 'inertial' (IMU + GPS,
    #: ``slamkit.data.inertial``)
    sequence_kind: str = "planar"
    #: 'pose' (the robot's pose only) or 'pose_and_map' (the landmarks too: SLAM)
    estimates: Literal["pose", "pose_and_map"] = "pose"

    def __post_init__(self) -> None:
        where = f"estimator spec {self.name!r}"
        # a user's one-file plug-in may give its classes themselves: stored as names, so the spec
        # stays a small picklable value and the class is imported where it is built
        if isinstance(self.target, type):
            object.__setattr__(self, "target", f"{self.target.__module__}:{self.target.__qualname__}")
        if isinstance(self.config, type):
            module = self.target.split(":")[0] if isinstance(self.target, str) else None
            if self.config.__module__ != module:
                raise ConfigError(f"{where}: the config class {self.config.__qualname__} must be defined in the "
                                  f"estimator's module {module!r}, not {self.config.__module__!r}")
            object.__setattr__(self, "config", self.config.__qualname__)
        for field_name, allowed in (("kind", KINDS), ("estimates", ESTIMATES), ("sequence_kind", SEQUENCE_KINDS)):
            if getattr(self, field_name) not in allowed:
                raise ConfigError(f"{where}: {field_name} must be one of {', '.join(allowed)}, "
                                  f"got {getattr(self, field_name)!r}")
        if not isinstance(self.target, str) or ":" not in self.target:
            raise ConfigError(f"{where}: target must be 'package.module:Class', got {self.target!r}")
        if self.needs_landmark_map and self.estimates != "pose":
            raise ConfigError(f"{where}: an estimator given the landmark map estimates the pose only "
                              "(needs_landmark_map=True with estimates='pose_and_map')")


#: the GTSAM smoothers (slamkit.backend); the filters' rows come from slamkit.estimation.registry
SMOOTHERS: tuple[EstimatorSpec, ...] = (
    EstimatorSpec("batch", "batch", "slamkit.backend.landmark_slam:BatchLandmarkSLAM", False,
                  "BatchLandmarkSLAMConfig", False, "batch Levenberg-Marquardt over the whole sequence",
                  estimates="pose_and_map"),
    EstimatorSpec("isam2", "smoother", "slamkit.backend.landmark_slam:Isam2LandmarkSLAM", False,
                  "Isam2LandmarkSLAMConfig", False, "iSAM2 incremental smoothing", estimates="pose_and_map"),
    EstimatorSpec("fixed_lag", "smoother", "slamkit.backend.landmark_slam:FixedLagLandmarkSLAM",
                  False, "FixedLagLandmarkSLAMConfig", False, "fixed-lag smoother (lag in seconds)",
                  estimates="pose_and_map"),
    EstimatorSpec("isam2_imu", "smoother", "slamkit.backend.inertial:Isam2Inertial", False,
                  "InertialSmootherConfig", False,
                  "iSAM2 with preintegrated IMU (CombinedImuFactor) and GPS factors", "inertial"),
    EstimatorSpec("fixed_lag_imu", "smoother", "slamkit.backend.inertial:FixedLagInertial", False,
                  "FixedLagInertialConfig", False,
                  "fixed-lag smoother with preintegrated IMU and GPS factors (lag in seconds)", "inertial"),
)

#: estimators built by ``cls.from_sequence(sequence, config=...)`` outside the filter table: the
#: wheel-odometry baseline and the multi-rate fusion systems (``slamkit.systems.fusion``), which
#: read IMU, encoder and scan events and need a grid world's metadata and map
SYSTEMS: tuple[EstimatorSpec, ...] = (
    EstimatorSpec("dead_reckoning", "filter", "slamkit.estimation.wheel_odometry:WheelOdometry", False,
                  "WheelOdometryConfig", False, "wheel-encoder dead reckoning"),
    EstimatorSpec("fusion_ekf", "filter", "slamkit.systems.fusion:FusionLocalizer", False,
                  "FusionLocalizerConfig", False, "5-state IMU/encoder EKF with scan-to-map pose fixes"),
    EstimatorSpec("fusion_isam2", "smoother", "slamkit.systems.fusion:FusionSmoother", False,
                  "FusionSmootherConfig", False,
                  "iSAM2 over lidar keyframes: preintegrated wheel/gyro odometry and scan-to-map fixes"),
)


def _filter_row(name: str, f: Any) -> EstimatorSpec:
    return EstimatorSpec(name, "filter", f"{f.cls.__module__}:{f.cls.__name__}", f.needs_landmark_map,
                         f.config_cls.__name__, f.random, f.description, f.sequence_kind, f.estimates)


def _filter_rows() -> dict[str, EstimatorSpec]:
    """The filters as registered by the estimation layer, read at every lookup (one table, not a
    copy of it: a filter registered there is an estimator here)."""
    from slamkit.estimation import registry as filters

    return {name: _filter_row(name, f) for name, f in filters.REGISTRY.items()}


def _adapt(name: str, entry: Any) -> EstimatorSpec:
    """An entry point's object: an :class:`EstimatorSpec` registered under its own name."""
    if not isinstance(entry, EstimatorSpec):
        raise ConfigError(f"an estimator entry point names an EstimatorSpec "
                          f"(slamkit.experiments.estimators), got {type(entry).__name__}")
    if entry.name != name:
        raise ConfigError(f"the entry point is called {name!r} but its EstimatorSpec {entry.name!r}")
    return entry


REGISTRY: Registry[EstimatorSpec] = Registry("estimator", {s.name: s for s in SMOOTHERS + SYSTEMS},
                                             group="slamkit.estimators", adapt=_adapt, derived=_filter_rows)


def register_estimator(spec: EstimatorSpec) -> None:
    """Make ``spec.name`` usable in every config, the CLI and the reports (see module doc)."""
    if not isinstance(spec, EstimatorSpec):
        raise ConfigError(f"register_estimator takes an EstimatorSpec, got {type(spec).__name__}")
    REGISTRY.register(spec.name, spec)


def is_builtin_filter(name: str) -> bool:
    """Whether ``name`` is a row of the estimation layer's filter table (built by its
    ``make_estimator``)."""
    from slamkit.estimation import registry as filters

    return REGISTRY.canonical(name) in filters.REGISTRY


def names() -> list[str]:
    return list(REGISTRY)


def spec(name: str) -> EstimatorSpec:
    """The row of ``name`` (an old spelling warns; an unknown name is a ConfigError)."""
    return REGISTRY[name]


def _resolve(target: str) -> Any:
    return load_target(target)


def config_class(name: str) -> type | None:
    """The config dataclass of estimator ``name`` (its params are that class's fields)."""
    s = spec(name)
    if s.config is None:
        return None
    return getattr(importlib.import_module(s.target.split(":")[0]), s.config, None)


def is_available(name: str) -> bool:
    """True when the estimator's module is installed and defines its class."""
    try:
        _resolve(spec(name).target)
    except (ImportError, AttributeError):
        return False
    return True


def available() -> list[str]:
    return [n for n in REGISTRY if is_available(n)]


@dataclass(frozen=True)
class EstimatorFactory:
    """A registry estimator with its params and seed: ``factory(sequence)`` builds one. The
    runner reads ``kind`` (filter, smoother or batch) from here instead of guessing it."""

    name: str
    kind: Literal["filter", "smoother", "batch"]
    build: Callable[[Sequence], Any]

    def __call__(self, sequence: Sequence) -> Any:
        return self.build(sequence)


def factory(name: str, params: Mapping[str, Any] | None = None, seed: int = 0) -> EstimatorFactory:
    """A callable ``sequence -> estimator`` for registry ``name`` with ``params``.

    ``seed`` seeds the estimator's own ``np.random.Generator`` (particle methods), so a run is
    reproducible and independent of the sequence's noise."""
    s = spec(name)
    name = s.name
    params = dict(params or {})
    try:
        cls = _resolve(s.target)
    except (ImportError, AttributeError) as exc:
        raise ConfigError(f"estimator {name!r} is not available in this installation ({exc})") from None
    module = importlib.import_module(s.target.split(":")[0])
    noise_params = {k: params.pop(k) for k in SENSOR_SIGMAS if k in params}
    config_cls = getattr(module, s.config, None) if s.config else None

    def build(sequence: Sequence):
        if is_builtin_filter(name):
            from slamkit.estimation.registry import make_estimator

            rng = np.random.default_rng(seed) if s.random else None
            return make_estimator(name, sequence, {**noise_params, **params}, rng=rng)
        if s in SYSTEMS:
            config = build_config(config_cls, {**noise_params, **params}, f"estimator {name!r}")
            return cls.from_sequence(sequence, config=config)
        if s not in SMOOTHERS:
            return _build_plugin(s, cls, config_cls, noise_params, params, seed, sequence)
        # smoothers carry their noise inside their config (slamkit.backend.landmark_slam)
        given = dict(params)
        if any(f.name == "noise" for f in dataclasses.fields(config_cls)):
            given["noise"] = NoiseParams.from_metadata(sequence.metadata,
                                                       **{k: float(v) for k, v in noise_params.items()})
        config = build_config(config_cls, given, f"estimator {name!r}")
        if hasattr(cls, "from_sequence"):
            return cls.from_sequence(sequence, config=config)
        return cls(config=config)

    return EstimatorFactory(name, s.kind, build)


def _build_plugin(s: EstimatorSpec, cls: type, config_cls: type | None, noise_params: Mapping[str, Any],
                  params: Mapping[str, Any], seed: int, sequence: Sequence) -> Any:
    """A plug-in estimator for ``sequence`` (the construction rule of the module doc)."""
    where = f"estimator {s.name!r}"
    if config_cls is None and params:
        raise ConfigError(f"{where}: takes no parameters (its spec names no config class), got {sorted(params)}")
    kwargs: dict[str, Any] = {}
    if config_cls is not None:
        kwargs["config"] = build_config(config_cls, params, where)
    if s.random:
        kwargs["rng"] = np.random.default_rng(seed)
    if hasattr(cls, "from_sequence"):
        return cls.from_sequence(sequence, **kwargs)
    noise = NoiseParams.from_metadata(sequence.metadata, **{k: float(v) for k, v in noise_params.items()})
    if s.needs_landmark_map:
        if not sequence.world_p_landmarks:
            raise ConfigError(f"{where} localizes against a known landmark map, but sequence "
                              f"{sequence.name!r} has none")
        return cls(sequence.world_p_landmarks, noise=noise, **kwargs)
    return cls(noise=noise, **kwargs)
