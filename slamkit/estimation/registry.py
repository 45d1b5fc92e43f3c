"""The filters of ``slamkit.estimation`` by the names users type in configs.

``make_estimator(name, sequence, params, rng)`` builds a ready-to-``reset`` Estimator for one
Sequence: the noise it assumes comes from ``sequence.metadata`` (``odometry_sigma``,
``range_bearing_sigma``; override with the ``NoiseParams`` field names in ``params``), the
localization filters get the sequence's landmark map, and the remaining ``params`` fill the
filter's config dataclass by field name. The cross-package table that also lists the GTSAM
smoothers and users' plug-ins is ``slamkit.experiments.estimators``, the one place to register
an estimator; it reads the rows of this table live (never a copy), and this one stays inside the
estimation layer so the filters' own tests and benchmark can iterate over every filter. Both
are a :class:`slamkit.naming.Registry`: one naming rule, and an unknown name is one ConfigError
with the closest suggestion.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from slamkit.data.estimate import Estimator
from slamkit.data.noise import SENSOR_SIGMAS, NoiseParams
from slamkit.data.sequence import Sequence
from slamkit.config import build
from slamkit.errors import ConfigError
from slamkit.estimation.ekf import EKFLocalization, EKFLocalizationConfig
from slamkit.estimation.ekf_slam import EKFSLAM, EKFSLAMConfig
from slamkit.estimation.eskf import ErrorStateEKF, ErrorStateEKFConfig
from slamkit.estimation.fastslam import FastSLAM, FastSLAMConfig
from slamkit.estimation.histogram_filter import HistogramFilter, HistogramFilterConfig
from slamkit.estimation.mcl import MCLConfig, MonteCarloLocalization
from slamkit.estimation.particle_filter import ParticleFilterConfig, ParticleFilterLocalization
from slamkit.estimation.ukf import UKFLocalization, UKFLocalizationConfig
from slamkit.naming import Registry


@dataclass(frozen=True)
class FilterSpec:
    name: str
    cls: type
    config_cls: type
    #: localization against the sequence's known landmark map (False: SLAM)
    needs_landmark_map: bool
    #: takes an ``rng`` (particle methods)
    random: bool
    description: str
    #: the sequences it runs on: 'planar' (odometry + range-bearing landmark worlds) or
    #: 'inertial' (IMU + GPS; the start state and noise come from slamkit.data.inertial)
    sequence_kind: str = "planar"
    #: what it estimates: 'pose' (the robot's pose only) or 'pose_and_map' (SLAM: the landmarks too)
    estimates: str = "pose"


REGISTRY: Registry[FilterSpec] = Registry("filter", [(s.name, s) for s in [
    FilterSpec("ekf", EKFLocalization, EKFLocalizationConfig, True, False,
               "EKF localization on a known landmark map"),
    FilterSpec("ukf", UKFLocalization, UKFLocalizationConfig, True, False,
               "UKF localization (angle-aware sigma points)"),
    FilterSpec("pf", ParticleFilterLocalization, ParticleFilterConfig, True, True,
               "bootstrap particle filter localization"),
    FilterSpec("mcl", MonteCarloLocalization, MCLConfig, True, True,
               "Monte Carlo localization: global init, KLD-sampling, augmented MCL"),
    FilterSpec("histogram", HistogramFilter, HistogramFilterConfig, True, False,
               "grid (histogram) Bayes filter localization"),
    FilterSpec("ekf_slam", EKFSLAM, EKFSLAMConfig, False, False, "EKF-SLAM, O(n^2) updates",
               estimates="pose_and_map"),
    FilterSpec("fastslam", FastSLAM, FastSLAMConfig, False, True, "FastSLAM 1.0", estimates="pose_and_map"),
    FilterSpec("es_ekf", ErrorStateEKF, ErrorStateEKFConfig, False, False,
               "15-state error-state EKF: IMU propagation, GPS updates (inertial sequences)", "inertial"),
]])

#: the planar filters (one contract: the same landmark sequence, a planar Estimate)
NAMES: tuple[str, ...] = tuple(n for n, f in REGISTRY.items() if f.sequence_kind == "planar")
#: the inertial filters (IMU + GPS sequences, 3D Estimate)
INERTIAL_NAMES: tuple[str, ...] = tuple(n for n, f in REGISTRY.items() if f.sequence_kind == "inertial")


def _config(spec: FilterSpec, params: Mapping[str, Any]) -> Any:
    return build(spec.config_cls, params, f"filter {spec.name!r}")


def make_estimator(name: str, sequence: Sequence, params: Mapping[str, Any] | None = None,
                   rng: np.random.Generator | None = None) -> Estimator:
    """Build filter ``name`` for ``sequence`` (see module doc)."""
    name = REGISTRY.canonical(name)
    spec = REGISTRY[name]
    params = dict(params or {})
    if spec.sequence_kind == "inertial":
        # inertial filters read their start state and noise from the sequence
        # (slamkit.data.inertial.setup_of); their params are their config's fields only
        return spec.cls.from_sequence(sequence, config=_config(spec, params))
    noise = NoiseParams.from_metadata(sequence.metadata,
                                      **{k: float(params.pop(k)) for k in SENSOR_SIGMAS if k in params})
    kwargs: dict[str, Any] = {"noise": noise, "config": _config(spec, params)}
    if spec.random:
        kwargs["rng"] = rng if rng is not None else np.random.default_rng(0)
    if spec.needs_landmark_map:
        if not sequence.world_p_landmarks:
            raise ConfigError(f"filter {name!r} localizes against a known landmark map, but "
                              f"sequence {sequence.name!r} has none")
        return spec.cls(sequence.world_p_landmarks, **kwargs)
    return spec.cls(**kwargs)
