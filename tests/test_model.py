"""DiffDrive: reference values from each seed, known scenarios, the Modern Robotics form."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive import DiffDrive, Twist, WheelVelocities
from strategies import geometry, reals

# r = 0.1 m, half-track D = L = d = b = 0.25 m.
ROBOT = DiffDrive(wheel_radius=0.1, track_width=0.5)


# -- conventions ---------------------------------------------------------------------------


def test_left_wheel_is_on_plus_y_and_both_roll_along_body_x():
    left, right = DiffDrive(wheel_radius=0.1, track_width=0.5, axle_offset=0.2).wheel_frames()
    assert (left.x, left.y, left.theta) == (-0.2, 0.25, 0.0)
    assert (right.x, right.y, right.theta) == (-0.2, -0.25, 0.0)


def test_positive_wheels_drive_forward_and_faster_right_turns_left():
    assert ROBOT.to_twist(WheelVelocities(1.0, 1.0)).vx > 0
    turning = ROBOT.to_twist(WheelVelocities(1.0, 2.0))
    assert turning.omega > 0  # counter-clockwise
    assert ROBOT.instantaneous_center(WheelVelocities(1.0, 2.0))[1] > 0  # centre on the left


def test_reference_point_ahead_of_the_axle_moves_sideways_when_turning():
    robot = DiffDrive(wheel_radius=0.1, track_width=0.5, axle_offset=0.3)
    twist = robot.to_twist(WheelVelocities(-1.0, 1.0))
    assert twist.vy == pytest.approx(0.3 * twist.omega)
    assert twist.vy > 0


# -- seed reference values -----------------------------------------------------------------


def test_seed_001_inverse_kinematics():
    # r*phi_L = x_dot - D*theta_dot; r*phi_R = x_dot + D*theta_dot.
    wheels = ROBOT.to_wheel_velocities(Twist(vx=1.0, omega=2.0))
    assert wheels.left == pytest.approx((1.0 - 0.25 * 2.0) / 0.1)  # 5 rad/s
    assert wheels.right == pytest.approx((1.0 + 0.25 * 2.0) / 0.1)  # 15 rad/s


def test_seed_001_modern_robotics_eq_13_14():
    # theta_dot = r/(2d) (u_R - u_L);  x_dot = r/2 (u_L + u_R) along the heading.
    twist = ROBOT.to_twist(WheelVelocities(5.0, 15.0))
    assert twist.omega == pytest.approx(0.1 / 0.5 * (15.0 - 5.0))
    assert twist.vx == pytest.approx(0.1 / 2 * (5.0 + 15.0))


def test_seed_002_wheel_speeds_and_curvature_radius():
    # V_R = omega (R + d), V_L = omega (R - d); R = d (V_R + V_L)/(V_R - V_L).
    d, omega, radius = 0.25, 2.0, 0.5
    v_right, v_left = omega * (radius + d), omega * (radius - d)
    wheels = WheelVelocities(v_left / 0.1, v_right / 0.1)
    twist = ROBOT.to_twist(wheels)
    assert twist.omega == pytest.approx((v_right - v_left) / (2 * d))
    assert twist.vx == pytest.approx((v_right + v_left) / 2)
    assert ROBOT.turning_radius(wheels) == pytest.approx(
        d * (v_right + v_left) / (v_right - v_left)
    )


def test_seed_003_matrices():
    r, half = 0.1, 0.25
    np.testing.assert_allclose(
        ROBOT.to_twist_matrix(), [[r / 2, r / 2], [-r / (2 * half), r / (2 * half)]]
    )
    np.testing.assert_allclose(
        ROBOT.to_wheel_velocities_matrix(), [[1 / r, -half / r], [1 / r, half / r]]
    )
    product = ROBOT.to_twist_matrix() @ ROBOT.to_wheel_velocities_matrix()
    np.testing.assert_allclose(product, np.eye(2), atol=1e-15)


def test_seed_004_H_Q_and_pseudo_inverse_with_sides_swapped():
    # Seed 004 puts its "l" wheel at y = -L (our right wheel): its rows come out swapped.
    r, half, offset = 0.1, 0.25, 0.15
    robot = DiffDrive(wheel_radius=r, track_width=2 * half, axle_offset=offset)
    seed_h = np.array([[half, 1.0, 0.0], [-half, 1.0, 0.0]]) / r
    np.testing.assert_allclose(robot.h_matrix(), seed_h[::-1])
    np.testing.assert_allclose(robot.constraint_matrix(), [[-offset, 0, 1], [-offset, 0, 1]])
    seed_pinv = np.array([[r / (2 * half), -r / (2 * half)], [r / 2, r / 2], [0.0, 0.0]])
    np.testing.assert_allclose(robot.pseudo_inverse_matrix(), seed_pinv[:, ::-1], atol=1e-15)


# -- known scenarios -----------------------------------------------------------------------


def test_straight_line():
    twist = ROBOT.to_twist(WheelVelocities(4.0, 4.0))
    assert twist == Twist(0.4, 0.0, 0.0)
    assert ROBOT.turning_radius(WheelVelocities(4.0, 4.0)) == math.inf
    assert ROBOT.turning_radius(WheelVelocities(-4.0, -4.0)) == -math.inf


def test_spin_in_place_needs_opposite_wheel_surface_speeds():
    radius = 0.0762
    robot = DiffDrive(wheel_radius=radius, track_width=0.762)
    wheels = robot.to_wheel_velocities(Twist(omega=math.pi))
    assert wheels.left * radius == pytest.approx(-1.1969468, abs=1e-7)
    assert wheels.right * radius == pytest.approx(1.1969468, abs=1e-7)
    assert robot.turning_radius(wheels) == 0.0


def test_standing_still_has_no_centre():
    assert math.isnan(ROBOT.turning_radius(WheelVelocities(0.0, 0.0)))


def test_instantaneous_center_lies_on_the_axle_line():
    robot = DiffDrive(wheel_radius=0.1, track_width=0.5, axle_offset=0.2)
    wheels = WheelVelocities(1.0, 3.0)
    x, y = robot.instantaneous_center(wheels)
    assert x == -0.2
    twist = robot.to_twist(wheels)
    # Seed 001: the centre is where the body velocity is a pure rotation, (-vy/w, vx/w)
    # relative to the reference point.
    assert (x, y) == pytest.approx((-twist.vy / twist.omega, twist.vx / twist.omega))


def test_unequal_wheel_radii():
    robot = DiffDrive(left_wheel_radius=0.1, right_wheel_radius=0.12, track_width=0.5)
    twist = robot.to_twist(WheelVelocities(10.0, 10.0))
    assert twist.vx == pytest.approx(1.1)
    assert twist.omega == pytest.approx((1.2 - 1.0) / 0.5)
    assert robot.wheel_radius == pytest.approx(0.11)


# -- properties ----------------------------------------------------------------------------


@pytest.mark.slow
@given(geometry(), reals(), reals())
def test_inverse_kinematics_undoes_forward_kinematics(params, left, right):
    robot = DiffDrive(**params)
    wheels = WheelVelocities(left, right)
    back = robot.to_wheel_velocities(robot.to_twist(wheels))
    assert back.to_array() == pytest.approx(wheels.to_array(), abs=1e-9)


@given(geometry(), reals(), reals())
def test_forward_kinematics_undoes_inverse_on_feasible_twists(params, vx, omega):
    robot = DiffDrive(**params)
    twist = Twist(vx, robot.axle_offset * omega, omega)
    back = robot.to_twist(robot.to_wheel_velocities(twist))
    assert back.to_array() == pytest.approx(twist.to_array(), abs=1e-9)


@given(geometry())
def test_H_F_is_identity_and_F_honours_the_constraint(params):
    robot = DiffDrive(**params)
    f = robot.f_matrix()
    np.testing.assert_allclose(robot.h_matrix() @ f, np.eye(2), atol=1e-10)
    np.testing.assert_allclose(robot.constraint_matrix() @ f, 0.0, atol=1e-12)


@given(geometry(), reals(), reals())
def test_matrices_agree_with_the_closed_forms(params, left, right):
    robot = DiffDrive(**params)
    wheels = WheelVelocities(left, right)
    twist = robot.to_twist(wheels)
    mr_twist = robot.f_matrix() @ [left, right]  # (omega, vx, vy)
    assert mr_twist == pytest.approx([twist.omega, twist.vx, twist.vy], abs=1e-9)
    mr_order = [twist.omega, twist.vx, twist.vy]
    assert robot.h_matrix() @ mr_order == pytest.approx([left, right], abs=1e-8)
    assert robot.to_twist_matrix() @ [left, right] == pytest.approx([twist.vx, twist.omega])


def test_pseudo_inverse_equals_F_only_on_the_axle():
    on_axle = DiffDrive(wheel_radius=0.1, track_width=0.5)
    np.testing.assert_allclose(on_axle.f_matrix(), on_axle.pseudo_inverse_matrix(), atol=1e-15)

    ahead = DiffDrive(wheel_radius=0.1, track_width=0.5, axle_offset=0.2)
    wheels = [-1.0, 1.0]  # a spin: omega != 0
    pinv_twist = ahead.pseudo_inverse_matrix() @ wheels
    true_twist = ahead.f_matrix() @ wheels
    assert pinv_twist[2] == 0.0  # H+ says the reference point does not move sideways...
    assert np.abs(ahead.constraint_matrix() @ pinv_twist).max() > 0.01  # ...so it slips,
    np.testing.assert_allclose(ahead.constraint_matrix() @ true_twist, 0.0, atol=1e-15)
    assert true_twist[2] == pytest.approx(0.2 * true_twist[0])  # vy = D * omega
    assert pinv_twist[:2] == pytest.approx(true_twist[:2])  # omega and vx agree


# -- bad input -----------------------------------------------------------------------------


@pytest.mark.parametrize("field", ["wheel_radius", "track_width"])
@pytest.mark.parametrize(
    ("value", "message"),
    [
        (0.0, "must be > 0, got 0.0"),
        (-0.3, "must be > 0, got -0.3"),
        (math.nan, "must be finite, got nan"),
        (math.inf, "must be finite, got inf"),
    ],
)
def test_bad_geometry_names_the_field_and_the_value(field, value, message):
    params = {"wheel_radius": 0.1, "track_width": 0.5, field: value}
    with pytest.raises(ValueError, match=f"^{field} {message}$"):
        DiffDrive(**params)


def test_bad_side_radius_and_axle_offset_are_named():
    with pytest.raises(ValueError, match=r"right_wheel_radius must be > 0, got -1\.0"):
        DiffDrive(left_wheel_radius=0.1, right_wheel_radius=-1.0, track_width=0.5)
    with pytest.raises(ValueError, match="axle_offset must be finite, got nan"):
        DiffDrive(wheel_radius=0.1, track_width=0.5, axle_offset=math.nan)


@pytest.mark.parametrize(
    "params",
    [
        {"track_width": 0.5},
        {"left_wheel_radius": 0.1, "track_width": 0.5},
        {
            "wheel_radius": 0.1,
            "left_wheel_radius": 0.1,
            "right_wheel_radius": 0.1,
            "track_width": 0.5,
        },
        {"wheel_radius": 0.1},
    ],
)
def test_radius_must_be_given_one_way(params):
    with pytest.raises(ValueError, match=r"wheel_radius|track_width .*is required"):
        DiffDrive(**params)


def test_robot_is_immutable():
    with pytest.raises(AttributeError):
        ROBOT.track_width = 1.0  # type: ignore[misc]


@given(st.floats(0.01, 1.0), st.floats(0.05, 2.0))
def test_positional_form_matches_keywords(radius, track):
    assert DiffDrive(radius, track) == DiffDrive(wheel_radius=radius, track_width=track)


def test_half_track_is_another_spelling_of_half_the_track_width():
    robot = dd.DiffDrive(wheel_radius=0.05, half_track=0.15)
    assert robot.track_width == 0.3
    assert robot.half_track == 0.15
    assert robot == dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
    with pytest.raises(ValueError, match=r"either track_width .* or half_track .*, not both"):
        dd.DiffDrive(wheel_radius=0.05, track_width=0.3, half_track=0.15)
    with pytest.raises(ValueError, match="half_track must be > 0"):
        dd.DiffDrive(wheel_radius=0.05, half_track=-0.1)
    assert "**full** distance between the two wheel contact points" in " ".join(
        dd.DiffDrive.__doc__.split()
    )
