"""How viewers and progress displays watch experiments without the experiments knowing them.

``slamkit.experiments`` never imports ``slamkit.viz``: the caller (the CLI, a notebook) hands
a ``PipelineObserver`` in; the viz layer implements it (``slamkit.viz.pipelines.observer_for``).
Pipelines call ``on_step`` while they run (live data: estimator snapshots, planner trees) and
``on_output`` once with their finished output (whatever the pipeline returns in
``PipelineOutput.payload``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Mapping, Protocol, runtime_checkable


@dataclass(frozen=True)
class StepSnapshot:
    """One step of one run: ``state`` holds what the observer may draw (arrays, ids)."""

    kind: str
    run: str
    index: int
    stamp_s: float
    state: Mapping[str, Any] = field(default_factory=dict)


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
