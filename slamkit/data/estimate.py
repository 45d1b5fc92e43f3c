"""What every estimator returns, and the protocols filters and smoothers satisfy."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Protocol, runtime_checkable

import numpy as np

from slamkit.data.sequence import Event, Sequence
from slamkit.data.trajectory import Trajectory


@dataclass(frozen=True)
class Estimate:
    """An estimator's answer.

    ``trajectory`` holds the estimate at the sequence's pose stamps; ``pose_covariances``
    (N, 3, 3) or (N, 6, 6) in the pose's tangent order (x, y, theta for SE(2)) when the
    estimator provides them; ``world_p_landmarks`` and ``landmark_covariances`` keyed by
    landmark id; ``innovations`` holds (nu, S) pairs for NIS where a filter records them;
    ``step_latency_s`` the wall time of every ``step`` call.
    """

    trajectory: Trajectory
    pose_covariances: np.ndarray | None = None
    world_p_landmarks: Mapping[int, np.ndarray] = field(default_factory=dict)
    landmark_covariances: Mapping[int, np.ndarray] = field(default_factory=dict)
    nis: np.ndarray | None = None
    nis_dof: np.ndarray | None = None
    step_latency_s: np.ndarray | None = None
    extras: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Prior:
    """Initial belief: planar pose (x, y, theta) and its covariance."""

    pose_xytheta: np.ndarray
    covariance: np.ndarray


@runtime_checkable
class Estimator(Protocol):
    """Online estimators (filters, iSAM2, fixed-lag smoothers)."""

    name: str

    def reset(self, prior: Prior) -> None: ...

    def step(self, event: Event) -> None: ...

    def estimate(self) -> Estimate: ...


@runtime_checkable
class BatchEstimator(Protocol):
    name: str

    def solve(self, sequence: Sequence) -> Estimate: ...
