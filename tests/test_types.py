"""Scalar value types: construction checks, array conversion, wheel-angle bookkeeping."""

import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import Pose, Twist, WheelPositions, WheelVelocities


@pytest.mark.parametrize("cls", [Pose, Twist, WheelPositions, WheelVelocities])
def test_round_trip_through_arrays(cls):
    value = cls(*range(1, len(cls.__dataclass_fields__) + 1))
    array = value.to_array()
    assert array.dtype == np.float64
    assert cls.from_array(array) == value


def test_from_array_names_the_expected_and_actual_shape():
    with pytest.raises(ValueError, match=r"expects shape \(3,\) \[x, y, theta\], got \(2,\)"):
        Pose.from_array([1.0, 2.0])
    with pytest.raises(ValueError, match=r"expects shape \(2,\) \[left, right\], got \(1, 2\)"):
        WheelVelocities.from_array([[1.0, 2.0]])


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_fields_are_refused_with_their_name(bad):
    with pytest.raises(ValueError, match=r"Twist\.omega must be finite"):
        Twist(1.0, 0.0, bad)
    with pytest.raises(ValueError, match=r"WheelPositions\.left must be finite"):
        WheelPositions(bad, 0.0)


def test_non_numbers_are_refused():
    with pytest.raises(TypeError, match=r"Pose\.x must be a real number"):
        Pose("one", 0.0, 0.0)


def test_fields_become_plain_floats():
    pose = Pose(np.float32(1.5), 2, np.int64(3))
    assert all(type(v) is float for v in (pose.x, pose.y, pose.theta))


def test_values_are_immutable_and_hashable():
    pose = Pose(1.0, 2.0, 3.0)
    with pytest.raises(AttributeError):
        pose.x = 0.0  # type: ignore[misc]
    assert {pose: 1}[Pose(1.0, 2.0, 3.0)] == 1


def test_wheel_positions_accumulate_velocity_times_dt():
    # Seed 001, eq. 5-6: theta_L = u_L*dt + theta_L,old.
    after = WheelPositions(1.0, -2.0).advance(WheelVelocities(3.0, 4.0), 0.5)
    assert after == WheelPositions(2.5, 0.0)


def test_wheel_velocities_from_two_readings():
    before, after = WheelPositions(1.0, 2.0), WheelPositions(1.5, 1.0)
    assert WheelVelocities.from_positions(before, after, 0.25) == WheelVelocities(2.0, -4.0)


@pytest.mark.parametrize("dt", [0.0, -0.1, math.nan, math.inf])
def test_wheel_angle_bookkeeping_refuses_bad_dt(dt):
    with pytest.raises(ValueError, match="dt must be"):
        WheelPositions().advance(WheelVelocities(1.0, 1.0), dt)
    with pytest.raises(ValueError, match="dt must be"):
        WheelVelocities.from_positions(WheelPositions(), WheelPositions(1.0, 1.0), dt)


def test_sequences_and_numpy_values_are_taken_where_a_value_type_is_expected():
    robot = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
    twist = robot.to_twist(dd.WheelVelocities(8.0, 10.0))
    assert robot.to_twist((8.0, 10.0)) == twist
    assert robot.to_twist([8, 10]) == twist
    assert robot.to_twist(np.array([8.0, 10.0], dtype=np.float32)) == twist
    assert robot.to_wheel_velocities((twist.vx, twist.vy, twist.omega)) == (
        robot.to_wheel_velocities(twist)
    )
    assert dd.se2.exp((0.5, 0.0, 1.0), 0.1) == dd.se2.exp(dd.Twist(0.5, 0.0, 1.0), 0.1)
    assert dd.Pose(1, 2, 0.3).compose((1, 0, 0)) == dd.Pose(1, 2, 0.3).compose(dd.Pose(1, 0, 0))
    assert dd.integrate.step((0, 0, 0), (1, 0, 0), 0.5) == dd.Pose(0.5, 0.0, 0.0)
    assert dd.Pose(np.float64(1.0), np.float32(2.0)).y == 2.0


@pytest.mark.parametrize(
    ("value", "error", "message"),
    [
        (("8", "10"), TypeError, r"wheels must be a WheelVelocities or a sequence of numbers"),
        (dd.Twist(), TypeError, r"wheels must be a WheelVelocities"),
        ((True, False), TypeError, r"wheels must be a WheelVelocities"),
        ((1.0, 2.0, 3.0), ValueError, r"wheels must have 2 numbers \[left, right\], got shape"),
    ],
)
def test_what_is_not_a_value_is_refused_by_name(value, error, message):
    robot = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
    with pytest.raises(error, match=message):
        robot.to_twist(value)


@pytest.mark.parametrize(
    ("make", "error", "message"),
    [
        (
            lambda: dd.DiffDrive(wheel_radius=10**400, track_width=0.3),
            ValueError,
            "wheel_radius must be finite, got an integer too large for a float",
        ),
        (lambda: Pose(10**400, 0, 0), ValueError, "Pose.x must be finite, got an integer"),
        (lambda: dd.se2.exp(Twist(1.0, 0.0, 0.0), 10**400), ValueError, "dt must be finite"),
        (
            lambda: dd.Odometry(dd.DiffDrive(0.05, 0.3)).jacobians(0, 10**400),
            ValueError,
            "right must be finite, got an integer too large",
        ),
        (
            lambda: dd.DiffDrive(wheel_radius=0.05, track_width="1_0"),
            TypeError,
            "track_width must be a real number, not text: got '1_0'",
        ),
        (
            lambda: dd.Odometry(dd.DiffDrive(0.05, 0.3), ticks_per_revolution="4096"),
            TypeError,
            "ticks_per_revolution must be a real number, not text",
        ),
    ],
)
def test_huge_integers_and_numeric_text_are_refused_by_name(make, error, message):
    with pytest.raises(error, match=message):
        make()
