"""What the navigation stack answers each control cycle: :class:`NavigationCommand` with its
:class:`CommandStatus` (which part of the stack decided it), and :func:`speed_capped`, the one
way any part slows a command (along the same arc).

Where each status comes from (the package's modules, :mod:`slamkit.systems.navigation`):
``NO_GOAL`` / ``NO_PATH`` / ``DRIVING`` / ``YIELDING`` the stack (:mod:`.stack`: the local
planner's command, capped by :mod:`.yielding`); ``FALLBACK_BRAKE`` / ``LOCAL_MINIMUM`` /
``ESCAPING`` the local planner's own status when it did not drive; ``EVADING`` the safety guard
(:mod:`.safety`) at the goal; ``APPROACH`` / ``ALIGNING`` / ``GOAL_REACHED`` the goal regulator
(:mod:`.goal`); ``RECOVERY`` :mod:`.recovery`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from slamkit.control.protocols import ControlOutput


class CommandStatus(enum.StrEnum):
    """Why the stack sent its command (a ``str``: ``status == "driving"`` holds)."""

    NO_GOAL = "no_goal"
    NO_PATH = "no_path"
    DRIVING = "driving"
    YIELDING = "yielding"
    #: the local planner's status when it did not drive (``ControlStatus`` values)
    FALLBACK_BRAKE = "fallback_brake"
    LOCAL_MINIMUM = "local_minimum"
    ESCAPING = "escaping"
    #: out of the way of a moving track about to run into the robot at the goal
    EVADING = "evading"
    RECOVERY = "recovery"
    #: the goal regulator's phases
    APPROACH = "approach"
    ALIGNING = "aligning"
    GOAL_REACHED = "goal_reached"


@dataclass(frozen=True)
class NavigationCommand:
    """One decision: ``command`` (v, omega); ``status`` a :class:`CommandStatus`; ``output`` the
    local planner's :class:`ControlOutput` (None in the regulator's phases); ``safe_stop``
    whether the planned command kept a collision-free braking trajectory (False both when the
    stack braked instead and when no braking was free: ``no_safe_stop_cycles`` counts those)."""

    command: np.ndarray
    status: CommandStatus
    output: ControlOutput | None = None
    safe_stop: bool = True


def speed_capped(command: np.ndarray, v_max_mps: float) -> np.ndarray:
    """``command`` (v, omega) slowed to |v| <= ``v_max_mps`` along the same arc (omega scaled
    with v, so the path the robot drives does not change, only how fast)."""
    v = abs(float(command[0]))
    if v <= v_max_mps:
        return np.asarray(command, float)
    return np.asarray(command, float) * (v_max_mps / v)
