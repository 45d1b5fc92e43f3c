"""The Controller contract, parametrised over every implementation: a ControlOutput with a finite
(2,) command inside the limits, what explains it, GOAL_REACHED at the goal, determinism after
reset, no exception on an empty or crowded world."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.control.dwa import DWAController
from slamkit.control.mpc import MPCConfig, MPCController
from slamkit.control.potential_fields import PotentialFieldController
from slamkit.control.protocols import (ControlOutput, ControlStatus, Controller, LocalWorld, Reference,
                                       RobotState)

FACTORIES = {
    "potential_fields": lambda: PotentialFieldController(rng=np.random.default_rng(0)),
    "dwa": DWAController,
    "mpc": lambda: MPCController(MPCConfig(solver="ipopt")),
    "mpc_osqp": lambda: MPCController(MPCConfig(solver="osqp")),
    "mpc_fatrop": lambda: MPCController(MPCConfig(solver="fatrop")),
}
# every default config shares these limits: |v| <= 0.8 m/s, |omega| <= 1.5 rad/s
V_MAX, OMEGA_MAX = 0.8, 1.5

REF = Reference([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]], speed_mps=0.6)
WORLD = LocalWorld(circle_xy_m=[[1.5, 0.2], [3.2, 1.5]], circle_radius_m=[0.2, 0.3],
                   circle_velocity_mps=[[0.0, -0.3], [0.0, 0.0]])


@pytest.fixture(params=sorted(FACTORIES))
def ctl(request):
    return FACTORIES[request.param]()


def _explained(out: ControlOutput) -> bool:
    return bool(out.force_xy) or out.candidates_xytheta is not None or out.predicted_xytheta is not None


def test_is_a_controller_and_explains_its_command(ctl):
    assert isinstance(ctl, Controller)
    out = ctl.compute(RobotState([0.0, 0.0, 0.0], [0.3, 0.0]), REF, WORLD)
    assert isinstance(out, ControlOutput) and out.command.shape == (2,)
    assert np.all(np.isfinite(out.command))
    assert 0.0 - 1e-9 <= out.command[0] <= V_MAX + 1e-9 and abs(out.command[1]) <= OMEGA_MAX + 1e-9
    assert out.status is ControlStatus.OK and _explained(out)
    assert out.solve_time_s > 0


def test_goal_reached_stops(ctl):
    out = ctl.compute(RobotState([3.0, 2.95, 1.57], [0.0, 0.0]), REF, LocalWorld())
    assert out.status is ControlStatus.GOAL_REACHED
    np.testing.assert_allclose(out.command, [0.0, 0.0], atol=1e-12)


def test_deterministic_after_reset(ctl):
    states = [RobotState([0.0, 0.0, 0.0], [0.3, 0.0]), RobotState([0.05, 0.0, 0.0], [0.35, 0.05])]
    first = [ctl.compute(s, REF, WORLD).command for s in states]
    ctl.reset()
    second = [ctl.compute(s, REF, WORLD).command for s in states]
    np.testing.assert_allclose(first, second, atol=1e-9)


def test_never_raises_in_a_crowded_world(ctl):
    crowd = LocalWorld(circle_xy_m=np.random.default_rng(1).uniform(-1, 1, size=(20, 2)),
                       circle_radius_m=np.full(20, 0.3))
    out = ctl.compute(RobotState([0.0, 0.0, 0.0], [0.5, 0.0]), REF, crowd)
    assert np.all(np.isfinite(out.command)) and out.status in set(ControlStatus)
