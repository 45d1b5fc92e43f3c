"""The Controller contract, parametrised over every name in the controller registry: a
ControlOutput with a finite (2,) command inside the limits, what explains it, GOAL_REACHED at the
goal, determinism after reset, no exception on an empty or crowded world; and the registry itself
(names, presets, params, unknown and old spellings)."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.control.mpc import MPCController
from slamkit.control.protocols import (ControlOutput, ControlStatus, Controller, LocalWorld, Reference,
                                       RobotState)
from slamkit.control.registry import CONTROLLERS, controller_config, make_controller
from slamkit.errors import ConfigError
from slamkit.naming import NAME_RULE, SlamkitDeprecationWarning
# every default config shares these limits: |v| <= 0.8 m/s, |omega| <= 1.5 rad/s
V_MAX, OMEGA_MAX = 0.8, 1.5

REF = Reference([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]], speed_mps=0.6)
WORLD = LocalWorld(circle_xy_m=[[1.5, 0.2], [3.2, 1.5]], circle_radius_m=[0.2, 0.3],
                   circle_velocity_mps=[[0.0, -0.3], [0.0, 0.0]])


@pytest.fixture(params=CONTROLLERS.names())
def ctl(request):
    return make_controller(request.param)


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


# --------------------------------------------------------------------------- the registry


def test_registry_names_the_six_controllers_and_each_builds_under_its_name():
    assert CONTROLLERS.names() == ["potential_fields", "dwa", "rollout", "mpc", "mpc_osqp", "mpc_fatrop"]
    for name in CONTROLLERS:
        assert NAME_RULE.match(name)
        ctl = make_controller(name)
        assert isinstance(ctl, CONTROLLERS[name].controller) and ctl.name == name
    assert {make_controller(n).config.solver for n in ("mpc", "mpc_osqp", "mpc_fatrop")} == {"ipopt", "osqp", "fatrop"}


def test_params_override_the_defaults_and_the_preset():
    """YAML lists become the MPC's tuples; a ``solver`` in params wins over the name's preset."""
    cfg = controller_config("mpc_osqp", {"horizon": 12, "u_max": [0.5, 1.0]})
    assert (cfg.solver, cfg.horizon, cfg.u_max) == ("osqp", 12, (0.5, 1.0))
    ctl = make_controller("mpc", {"solver": "fatrop", "horizon": 5})
    assert isinstance(ctl, MPCController) and ctl.name == "mpc_fatrop" and ctl.config.horizon == 5
    assert make_controller("dwa", {"v_max_mps": 0.6}).config.v_max_mps == 0.6


def test_unknown_names_and_keys_are_config_errors_that_say_what_is_known():
    with pytest.raises(ConfigError, match=r"unknown controller 'mpc_osq' \(did you mean 'mpc_osqp'\?\)"):
        make_controller("mpc_osq")
    with pytest.raises(ConfigError, match=r"controller 'dwa': unknown parameter\(s\) \['v_max'\]"):
        make_controller("dwa", {"v_max": 1.0})
    with pytest.raises(ConfigError, match="controller 'mpc'"):
        make_controller("mpc", {"u_max": 0.8})  # a scalar where a pair is needed


def test_an_old_spelling_builds_with_a_deprecation_warning():
    with pytest.warns(SlamkitDeprecationWarning, match="write 'mpc_osqp'"):
        ctl = make_controller("MPC-OSQP")
    assert ctl.name == "mpc_osqp"
