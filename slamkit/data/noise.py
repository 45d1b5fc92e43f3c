"""What a Sequence declares about its noise, read once for every estimator: :class:`NoiseParams`
and the start :class:`~slamkit.data.estimate.Prior` it implies (:func:`prior_of`).

Architecture note (issue 18): the filters (``NoiseParams`` in ``estimation/_common.py``) and the
GTSAM smoothers (``SmootherNoise`` in ``backend/landmark_slam.py``) used to read the same
metadata with two readers, and the runner (``prior_of``) and the batch smoother
(``prior_from_sequence``) built the start prior twice. Both now live here, in the data layer
that estimation and backend may both import. The readers agreed on every key slamkit writes;
where they differed the union is kept (the smoothers now also read the plain field names and
skip a ``None`` entry, as the filters did), and where the two priors differ in value (a floor,
a ground-truth start) :func:`prior_of` keeps each caller's numbers through its two options.

Metadata keys (``slamkit.sim.landmark_world`` and the dataset readers write them):

* ``odometry_sigma`` = (sigma_v_mps, sigma_omega_radps): noise on the body-frame velocities
  (v, omega) held over ``dt_s``, so the pose noise of one step is ``L diag(sigma_v^2,
  sigma_omega^2) L^T`` with ``L`` the motion Jacobian with respect to the control (Thrun,
  Probabilistic Robotics, eq. 7.11 and Table 7.1);
* ``range_bearing_sigma`` = (sigma_range_m, sigma_bearing_rad);
* ``initial_pose_sigma`` = (x_m, y_m, theta_rad): the standard deviations of the start pose;
* ``range_gate_m``: the range-only outlier gate (:meth:`NoiseParams.range_rejected`);
* ``range_scale_sigma``: > 0 when the ranges carry an unknown scale s (measured = s * true range,
  e.g. a ranging radio's clock rate): every range-only estimator then estimates s jointly, with
  a prior N(1, range_scale_sigma^2) (issue 12 follow-up); 0 (default) takes the ranges as
  calibrated;
* or the field names of :class:`NoiseParams` directly (``sigma_v_mps`` ...).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from slamkit.data.estimate import Prior
from slamkit.data.sequence import Sequence
from slamkit.errors import ConfigError

#: the per-measurement standard deviations (a pipeline config may override these by name)
SENSOR_SIGMAS: tuple[str, ...] = ("sigma_v_mps", "sigma_omega_radps", "sigma_range_m",
                                  "sigma_bearing_rad")


@dataclass(frozen=True)
class NoiseParams:
    """Standard deviations the estimators assume (SI units): odometry (v, omega), range-bearing
    and the start pose. ``initial_pose_sigma`` may be zero (a start pose known exactly, see
    :class:`~slamkit.data.estimate.Prior`); the others must be positive."""

    sigma_v_mps: float = 0.1
    sigma_omega_radps: float = 0.05
    sigma_range_m: float = 0.1
    sigma_bearing_rad: float = 0.02
    initial_pose_sigma: tuple[float, float, float] = (1e-3, 1e-3, 1e-3)
    #: range-only outlier gate: a range whose residual against the estimator's current
    #: prediction exceeds this is rejected and counted (the same rule in every estimator;
    #: inf keeps every range)
    range_gate_m: float = float("inf")
    #: > 0: the ranges are s * the true range with s unknown; the range-only estimators estimate
    #: s from a prior N(1, range_scale_sigma^2). 0: ranges calibrated (s = 1, not estimated)
    range_scale_sigma: float = 0.0

    def __post_init__(self) -> None:
        if not self.range_gate_m > 0:
            raise ConfigError(f"NoiseParams.range_gate_m must be positive, got {self.range_gate_m}")
        if not (np.isfinite(self.range_scale_sigma) and self.range_scale_sigma >= 0):
            raise ConfigError(f"NoiseParams.range_scale_sigma must be finite and >= 0, got "
                              f"{self.range_scale_sigma}")
        for name in SENSOR_SIGMAS:
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ConfigError(f"NoiseParams.{name} must be positive and finite, got {value}")
        sigma = np.asarray(self.initial_pose_sigma, dtype=float).reshape(-1)
        if sigma.size != 3 or not (np.all(np.isfinite(sigma)) and np.all(sigma >= 0)):
            raise ConfigError(f"NoiseParams.initial_pose_sigma must be 3 finite sigmas >= 0 "
                              f"(x_m, y_m, theta_rad), got {self.initial_pose_sigma}")

    def range_rejected(self, residual_m: float | np.ndarray) -> bool | np.ndarray:
        """True where a range residual (measured - predicted) lies outside the gate."""
        return np.abs(residual_m) > self.range_gate_m

    @property
    def control_cov(self) -> np.ndarray:
        """(2, 2) covariance of (v, omega)."""
        return np.diag([self.sigma_v_mps**2, self.sigma_omega_radps**2])

    @property
    def range_bearing_cov(self) -> np.ndarray:
        """(2, 2) covariance of one (range, bearing) measurement."""
        return np.diag([self.sigma_range_m**2, self.sigma_bearing_rad**2])

    @classmethod
    def from_metadata(cls, metadata: Mapping[str, Any], **overrides: Any) -> "NoiseParams":
        """Read a Sequence's ``metadata`` (keys in the module docstring; a missing or ``None``
        key keeps the default); ``overrides`` (field names) win over both."""
        values: dict[str, Any] = {}
        for key, names in (("odometry_sigma", ("sigma_v_mps", "sigma_omega_radps")),
                           ("range_bearing_sigma", ("sigma_range_m", "sigma_bearing_rad")),
                           ("initial_pose_sigma", None)):
            if metadata.get(key) is None:
                continue
            given = np.asarray(metadata[key], dtype=float).reshape(-1)
            if given.size != (3 if names is None else 2):
                raise ConfigError(f"metadata field {key} must have {3 if names is None else 2} "
                                  f"values, got {given.size}")
            if names is None:
                values[key] = tuple(given.tolist())
            else:
                values.update(zip(names, given.tolist()))
        for name in (*SENSOR_SIGMAS, "range_gate_m", "range_scale_sigma"):
            if metadata.get(name) is not None:
                values[name] = float(metadata[name])
        values.update(overrides)
        return cls(**values)


def prior_of(sequence: Sequence, noise: NoiseParams | None = None, *, sigma_floor: float = 1e-6,
             start_from_ground_truth: bool = True) -> Prior:
    """The prior an estimator starts from: the sequence's declared start pose and
    ``noise.initial_pose_sigma`` (``noise`` defaults to the sequence's metadata) as its
    standard deviations, each raised to at least ``sigma_floor``.

    A sequence that declares no start pose starts at its ground truth's first pose when
    ``start_from_ground_truth`` (the true start, which the scoring is against anyway), else at
    the origin.

    The defaults are what the runner gives every online estimator (filters, iSAM2, fixed-lag);
    the floor keeps a filter's covariance invertible when a sequence declares its start known
    exactly (sigma 0). The batch smoother's ``solve(sequence)`` asks for ``sigma_floor=0`` and
    ``start_from_ground_truth=False``: it has always started at the declared start (or the
    origin) with the sigmas as given, and keeps those numbers. The two agree on every sequence
    slamkit writes (simulators and dataset readers declare the start and sigmas of 1e-3).
    """
    if sequence.initial_world_xytheta_body is not None:
        pose = np.asarray(sequence.initial_world_xytheta_body, dtype=float).reshape(3)
    elif start_from_ground_truth and sequence.ground_truth is not None:
        pose = sequence.ground_truth.xytheta()[0]
    else:
        pose = np.zeros(3)
    if noise is None:
        noise = NoiseParams.from_metadata(sequence.metadata)
    sigma = np.maximum(np.asarray(noise.initial_pose_sigma, dtype=float).reshape(3), sigma_floor)
    return Prior(pose, np.diag(sigma**2))
