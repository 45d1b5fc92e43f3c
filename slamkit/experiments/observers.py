"""How viewers and progress displays watch experiments without the experiments knowing them.

``slamkit.experiments`` never imports ``slamkit.viz``: the caller (the CLI, a notebook) hands
a ``PipelineObserver`` in; the viz layer implements it (``slamkit.viz.pipelines.observer_for``).
Pipelines call ``on_step`` while they run (live data: estimator snapshots, planner trees) and
``on_output`` once with their finished output (whatever the pipeline returns in
``PipelineOutput.payload``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Protocol


@dataclass(frozen=True)
class StepSnapshot:
    """One step of one run: ``state`` holds what the observer may draw (arrays, ids)."""

    kind: str
    run: str
    index: int
    stamp_s: float
    state: Mapping[str, Any] = field(default_factory=dict)


class PipelineObserver(Protocol):
    def on_step(self, snapshot: StepSnapshot) -> None: ...

    def on_output(self, output: Any) -> None: ...

    def close(self) -> None: ...


class NullObserver:
    """Observes nothing (the default)."""

    wants_steps = False

    def on_step(self, snapshot: StepSnapshot) -> None:
        pass

    def on_output(self, output: Any) -> None:
        pass

    def close(self) -> None:
        pass
