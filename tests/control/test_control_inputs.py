"""Controllers never turn bad input into a NaN command (issue 10): a non-finite robot state is
answered with a zero command, non-finite obstacles are refused naming the obstacle."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.control.protocols import ControlStatus, LocalWorld, Reference, RobotState
from slamkit.control.registry import CONTROLLERS, make_controller
from slamkit.errors import ControlError

REFERENCE = Reference(np.array([[0.0, 0.0], [5.0, 0.0]]), speed_mps=0.5)


@pytest.mark.parametrize("name", CONTROLLERS.names())
@pytest.mark.parametrize("pose, command", [((np.nan, 0.0, 0.0), (0.3, 0.0)), ((0.0, 0.0, np.inf), (0.3, 0.0)),
                                           ((0.0, 0.0, 0.0), (np.nan, 0.1))])
def test_a_non_finite_state_brakes_with_a_zero_command(name, pose, command) -> None:
    out = make_controller(name).compute(RobotState(np.array(pose), np.array(command)), REFERENCE, LocalWorld())
    assert out.status is ControlStatus.FALLBACK_BRAKE
    np.testing.assert_array_equal(out.command, [0.0, 0.0])
    assert out.info["reason"] == "non-finite robot state"


@pytest.mark.parametrize("xy, r, v, text", [
    ([[1.0, np.nan]], [0.3], None, r"obstacle 0 has a non-finite centre, radius or velocity \(\[1\.0, nan\], 0\.3"),
    ([[1.0, 1.0], [2.0, 2.0]], [0.3, np.inf], None, r"obstacle 1 has a non-finite centre, radius or velocity"),
    ([[1.0, 1.0]], [0.3], [[np.nan, 0.0]], r"obstacle 0 has a non-finite"),
])
def test_non_finite_obstacles_are_refused(xy, r, v, text) -> None:
    with pytest.raises(ControlError, match=text):
        LocalWorld(np.array(xy), np.array(r), None if v is None else np.array(v))


def test_a_finite_state_still_drives() -> None:
    out = make_controller("mpc").compute(RobotState(np.zeros(3), np.zeros(2)), REFERENCE, LocalWorld())
    assert out.status is ControlStatus.OK and np.all(np.isfinite(out.command)) and out.command[0] > 0
