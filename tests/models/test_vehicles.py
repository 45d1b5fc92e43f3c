"""Bicycle, tracked, three-wheel omni and mecanum kinematics: worked examples with numbers and
forward/inverse properties for every holonomic model."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import ConfigError
from slamkit.models import diff_drive as dd
from slamkit.models import planar
from slamkit.models.bicycle import Bicycle
from slamkit.models.mecanum import Mecanum
from slamkit.models.omni import Omni3
from slamkit.models.tracked import Tracked

speed = st.floats(-3.0, 3.0, allow_nan=False)


def test_bicycle_quarter_circle():
    car = Bicycle(wheelbase_m=2.5, max_steer_rad=0.6)
    delta = np.arctan(0.5)  # tan(delta) / L = 0.2 1/m, turning radius 5 m
    assert car.curvature(delta) == pytest.approx(0.2, abs=1e-15)
    np.testing.assert_allclose(car.icc([0.0, 0.0, 0.0], delta), [0.0, 5.0], atol=1e-14)
    np.testing.assert_allclose(car.icc([1.0, 2.0, np.pi / 2], delta), [-4.0, 2.0], atol=1e-14)
    assert np.all(np.isnan(car.icc([0.0, 0.0, 0.0], 0.0)))
    # a quarter of the 5 m circle at 1 m/s takes 2.5 pi s and ends at (5, 5) facing +y
    end = car.motion([0.0, 0.0, 0.0], [1.0, delta], 2.5 * np.pi)
    np.testing.assert_allclose(end, [5.0, 5.0, np.pi / 2], atol=1e-12)
    np.testing.assert_allclose(car.from_unicycle(car.to_unicycle([1.0, delta])), [1.0, delta], atol=1e-15)


def test_bicycle_steering_limit():
    car = Bicycle(wheelbase_m=2.0, max_steer_rad=0.5)
    assert car.curvature(1.2) == pytest.approx(np.tan(0.5) / 2.0)
    assert car.min_turning_radius_m == pytest.approx(2.0 / np.tan(0.5))
    np.testing.assert_allclose(car.motion(np.zeros(3), [1.0, 1.2], 1.0), car.motion(np.zeros(3), [1.0, 0.5], 1.0))
    _, L = car.motion_jacobians(np.zeros(3), [1.0, 1.2], 1.0)
    np.testing.assert_array_equal(L[:, 1], 0.0)  # saturated steering has no effect
    with pytest.raises(ConfigError):
        car.from_unicycle([0.0, 1.0])  # no turning on the spot
    with pytest.raises(ConfigError):
        car.from_unicycle([1.0, 5.0])  # tighter than the minimum radius
    with pytest.raises(ConfigError):
        Bicycle(max_steer_rad=2.0)


def test_tracked_without_slip_is_diff_drive():
    tank = Tracked(track_width_m=0.4)
    robot = dd.DiffDrive(wheel_radius_m=1.0, half_axle_m=0.2)  # r = 1: wheel speed = track speed
    tracks = np.array([[1.0, 0.5], [-0.3, 0.7], [2.0, 2.0]])
    twist = tank.forward(tracks)
    np.testing.assert_allclose(twist[:, [0, 2]], robot.forward(tracks), atol=1e-15)
    np.testing.assert_array_equal(twist[:, 1], 0.0)
    pose = np.array([1.0, 2.0, 0.3])
    np.testing.assert_allclose(tank.motion(pose, tracks, 0.5), dd.motion(pose, robot.forward(tracks), 0.5), atol=1e-14)


def test_tracked_slip_numbers():
    # 10 % longitudinal slip on both tracks: 1 m/s tracks give 0.9 m/s
    assert Tracked(slip_left=0.1, slip_right=0.1).forward([1.0, 1.0])[0] == pytest.approx(0.9)
    # turning on the spot with ICRs at +-0.4 m instead of the track positions +-0.25 m:
    # omega = (1 - (-1)) / 0.8 = 2.5 rad/s instead of the ideal 2 / 0.5 = 4 rad/s
    tank = Tracked(track_width_m=0.5, icr_left_m=0.4, icr_right_m=-0.4)
    np.testing.assert_allclose(tank.forward([1.0, -1.0]), [0.0, 0.0, 2.5], atol=1e-15)
    # a longitudinal ICR shift of 0.1 m makes the turning vehicle skid sideways: v_y = -0.25
    skid = Tracked(track_width_m=0.5, icr_left_m=0.4, icr_right_m=-0.4, icr_x_m=0.1)
    np.testing.assert_allclose(skid.forward([1.0, -1.0]), [0.0, -0.25, 2.5], atol=1e-15)
    with pytest.raises(ConfigError):
        Tracked(slip_left=1.0)


def test_omni_worked_example():
    robot = Omni3(wheel_radius_m=0.05, center_distance_m=0.2)
    # pure rotation at 1 rad/s: every wheel rim moves d * omega = 0.2 m/s -> 4 rad/s
    np.testing.assert_allclose(robot.inverse([0.0, 0.0, 1.0]), [4.0, 4.0, 4.0], atol=1e-14)
    # driving +y at 1 m/s: wheel 0 (at 0 deg) rolls fully, the others at cos(120 deg) = -1/2
    np.testing.assert_allclose(robot.inverse([0.0, 1.0, 0.0]), [20.0, -10.0, -10.0], atol=1e-13)
    with pytest.raises(ConfigError):
        Omni3(wheel_angles_rad=(0.5, 0.5 + 2 * np.pi, 2.0))


def test_mecanum_worked_example():
    robot = Mecanum(wheel_radius_m=0.05, half_length_m=0.2, half_width_m=0.15)
    # strafing left at 0.5 m/s: FL and RR spin backwards, FR and RL forwards, 10 rad/s each
    np.testing.assert_allclose(robot.inverse([0.0, 0.5, 0.0]), [-10.0, 10.0, 10.0, -10.0], atol=1e-13)
    # inconsistent wheel speeds (only FL turns) map to the least-squares twist r/4 (1, -1, -1/(l+w))
    np.testing.assert_allclose(robot.forward([1.0, 0.0, 0.0, 0.0]), [0.0125, -0.0125, -0.0125 / 0.35], atol=1e-15)


HOLONOMIC = [Omni3(), Omni3(wheel_radius_m=0.03, center_distance_m=0.15, wheel_angles_rad=(0.3, 2.0, 4.5)),
             Mecanum(), Mecanum(wheel_radius_m=0.1, half_length_m=0.3, half_width_m=0.25)]


@pytest.mark.parametrize("robot", HOLONOMIC, ids=lambda r: type(r).__name__)
@settings(max_examples=100, deadline=None)
@given(vx=speed, vy=speed, w=speed)
def test_holonomic_forward_of_inverse_is_identity(robot, vx, vy, w):
    twist = np.array([vx, vy, w])
    np.testing.assert_allclose(robot.forward(robot.inverse(twist)), twist, atol=1e-10)
    wheels = robot.inverse(twist)  # consistent wheel speeds come back unchanged
    np.testing.assert_allclose(robot.inverse(robot.forward(wheels)), wheels, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(st.lists(speed, min_size=3, max_size=3))
def test_omni_inverse_of_forward_is_identity(wheels):
    robot = Omni3(wheel_angles_rad=(0.1, 2.2, 4.0))
    np.testing.assert_allclose(robot.inverse(robot.forward(wheels)), wheels, atol=1e-10)


@settings(max_examples=100, deadline=None)
@given(st.floats(0.0, 0.9), st.floats(0.0, 0.9), st.floats(0.2, 1.0), st.floats(-0.2, 0.2), speed, speed)
def test_tracked_inverse_of_forward_is_identity(sl, sr, yl, xv, right, left):
    tank = Tracked(track_width_m=0.4, slip_left=sl, slip_right=sr, icr_left_m=yl, icr_right_m=-yl * 0.9, icr_x_m=xv)
    np.testing.assert_allclose(tank.inverse(tank.forward([right, left])), [right, left], atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(speed, speed)
def test_twist_with_zero_vy_is_the_diff_drive_arc(v, w):
    pose = np.array([0.4, -0.2, 2.0])
    np.testing.assert_allclose(planar.motion_twist(pose, [v, 0.0, w], 0.8), dd.motion(pose, [v, w], 0.8), atol=1e-12)


def test_holonomic_strafe_moves_sideways():
    robot = Mecanum()
    pose = robot.motion([0.0, 0.0, np.pi / 2], robot.inverse([0.0, 1.0, 0.0]), 2.0)
    np.testing.assert_allclose(pose, [-2.0, 0.0, np.pi / 2], atol=1e-12)  # body +y is world -x
