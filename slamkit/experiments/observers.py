"""How viewers and progress displays watch experiments without the experiments knowing them.

``slamkit.experiments`` never imports ``slamkit.viz``: the caller (the CLI, a notebook) hands
a ``PipelineObserver`` in; the viz layer implements it (``slamkit.viz.pipelines.observer_for``).
Pipelines call ``on_step`` while they run (live data: estimator snapshots, planner trees) and
``on_output`` once with their finished output (the ``PipelineOutput`` whose ``payload`` has the
type the pipeline declares, ``Pipeline.payload_type``).

The runner (:func:`slamkit.experiments.runner.run_estimators`) sends a :class:`BeliefSnapshot`
as the ``state`` of its steps: a frozen record of what one estimator believes after one event,
read by attribute, planar or 3D.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Generic, Protocol, TypeVar, runtime_checkable

import numpy as np

from slamkit.data.sequence import RangeBearing
from slamkit.data.trajectory import Trajectory

StateT = TypeVar("StateT")


@dataclass(frozen=True)
class StepSnapshot(Generic[StateT]):
    """One step of one run: ``state`` is the pipeline's record of it (the runner's
    :class:`BeliefSnapshot`; for navigation a ``navigation.NavigationSnapshot``; for local
    planning a ``closed_loop.LocalPlanningSnapshot``; for lidar SLAM a ``lidar_slam.LidarSlamSnapshot``)."""

    kind: str
    run: str
    index: int
    stamp_s: float
    state: StateT = field(default_factory=dict)  # type: ignore[assignment]


@dataclass(frozen=True)
class BeliefSnapshot:
    """An estimator's belief after one event, as an observer may draw it.

    ``pose`` is the latest pose as a one-pose :class:`Trajectory` (planar or 3D);
    ``covariance`` its (3, 3) or (6, 6) covariance in the runner's world convention (see
    ``runner.world_pose_error``), None when the estimator reports none; ``landmark_ids`` (K,)
    with ``world_p_landmarks`` (K, 2 or 3) the map a SLAM estimator holds (K = 0 otherwise);
    ``particles`` (M, 3) at most ``runner.SNAPSHOT_MAX_PARTICLES`` of a particle belief;
    ``observation`` the range-bearing measurement just processed (None for other events)."""

    estimator: str
    pose: Trajectory
    covariance: np.ndarray | None = None
    landmark_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    world_p_landmarks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    particles: np.ndarray | None = None
    observation: RangeBearing | None = None


@runtime_checkable
class PipelineObserver(Protocol):
    """What a pipeline may rely on: whether the observer wants live steps at all, how often
    (every ``step_every``-th event), and the three callbacks. Runners read these attributes
    directly -- an observer that does not declare them does not satisfy the protocol."""

    wants_steps: bool
    step_every: int

    def on_step(self, snapshot: StepSnapshot) -> None: ...

    def on_output(self, output: Any) -> None: ...

    def close(self) -> None: ...


class NullObserver:
    """Observes nothing (the default)."""

    wants_steps: ClassVar[bool] = False
    step_every: ClassVar[int] = 10

    def on_step(self, snapshot: StepSnapshot) -> None:
        pass

    def on_output(self, output: Any) -> None:
        pass

    def close(self) -> None:
        pass
