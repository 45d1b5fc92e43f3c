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
from slamkit.errors import ConfigError
from slamkit.naming import Registry

#: what a factory returns for one sequence
Factory = Callable[[Sequence], "Estimator | BatchEstimator"]


@dataclass(frozen=True)
class EstimatorSpec:
    """One registry row: ``target`` is ``module:attribute`` of the estimator class."""

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


#: the GTSAM smoothers (slamkit.backend); the filters' rows come from slamkit.estimation.registry
SMOOTHERS: tuple[EstimatorSpec, ...] = (
    EstimatorSpec("batch", "batch", "slamkit.backend.landmark_slam:BatchLandmarkSLAM", False,
                  "BatchLandmarkSLAMConfig", False, "batch Levenberg-Marquardt over the whole sequence"),
    EstimatorSpec("isam2", "smoother", "slamkit.backend.landmark_slam:Isam2LandmarkSLAM", False,
                  "Isam2LandmarkSLAMConfig", False, "iSAM2 incremental smoothing"),
    EstimatorSpec("fixed_lag", "smoother", "slamkit.backend.landmark_slam:FixedLagLandmarkSLAM",
                  False, "FixedLagLandmarkSLAMConfig", False, "fixed-lag smoother (lag in seconds)"),
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


def _filter_rows() -> dict[str, EstimatorSpec]:
    """The filters as registered by the estimation layer (one table, not a copy of it)."""
    from slamkit.estimation import registry as filters

    return {name: EstimatorSpec(name, "filter", f"{f.cls.__module__}:{f.cls.__name__}",
                                f.needs_landmark_map, f.config_cls.__name__, f.random, f.description,
                                f.sequence_kind)
            for name, f in filters.REGISTRY.items()}


REGISTRY: Registry[EstimatorSpec] = Registry("estimator", {**_filter_rows(),
                                                           **{s.name: s for s in SMOOTHERS + SYSTEMS}})


def names() -> list[str]:
    return list(REGISTRY)


def spec(name: str) -> EstimatorSpec:
    """The row of ``name`` (an old spelling warns; an unknown name is a ConfigError)."""
    return REGISTRY[name]


def _resolve(target: str) -> Any:
    module_name, attr = target.split(":")
    return getattr(importlib.import_module(module_name), attr)


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


def _config(cls: type, params: Mapping[str, Any], where: str) -> Any:
    """``cls(**params)``; a mapping given for a field whose default is a dataclass overrides
    that default's fields (recursively), a list for a tuple field becomes a tuple."""
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(params) - set(fields))
    if unknown:
        raise ConfigError(f"{where}: unknown parameter(s) {unknown}; {cls.__name__} has {sorted(fields)}")
    kwargs = {}
    for name, value in params.items():
        f = fields[name]
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        if isinstance(value, Mapping) and dataclasses.is_dataclass(default) and not isinstance(default, type):
            nested = _config(type(default), value, f"{where}.{name}")
            value = dataclasses.replace(default, **{k: getattr(nested, k) for k in value})
        elif isinstance(value, list):
            value = tuple(value)
        kwargs[name] = value
    return cls(**kwargs)


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
        if s in SYSTEMS:
            config = _config(config_cls, {**noise_params, **params}, f"estimator {name!r}")
            return cls.from_sequence(sequence, config=config)
        if s.kind == "filter":
            from slamkit.estimation.registry import make_estimator

            rng = np.random.default_rng(seed) if s.random else None
            return make_estimator(name, sequence, {**noise_params, **params}, rng=rng)
        # smoothers carry their noise inside their config (slamkit.backend.landmark_slam)
        given = dict(params)
        if any(f.name == "noise" for f in dataclasses.fields(config_cls)):
            given["noise"] = NoiseParams.from_metadata(sequence.metadata,
                                                       **{k: float(v) for k, v in noise_params.items()})
        config = _config(config_cls, given, f"estimator {name!r}")
        if hasattr(cls, "from_sequence"):
            return cls.from_sequence(sequence, config=config)
        return cls(config=config)

    return EstimatorFactory(name, s.kind, build)
