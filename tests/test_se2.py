"""Scalar SE(2): reference values from the seeds, group properties, the Taylor threshold."""

import math
import sys

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from diffdrive import Pose, Twist, se2, wrap_angle
from diffdrive._step import TAYLOR_LIMIT
from strategies import reals

poses = st.builds(Pose, reals(), reals(), reals(20.0))
twists = st.builds(Twist, reals(), reals(), reals(3.0))
principal_twists = st.builds(Twist, reals(), reals(), st.floats(-3.1, 3.1))


def pose_close(a: Pose, b: Pose, tol: float = 1e-12) -> bool:
    return np.allclose(a.to_array(), b.to_array(), rtol=0.0, atol=tol)


# -- reference values ----------------------------------------------------------------------


def test_exp_matches_seed_001_T_bb_prime():
    # Seed 001: T_bb' for the twist (omega, x_dot, y_dot) over unit time, written out.
    w, xd, yd = 0.7, 1.3, -0.4
    expected = np.array(
        [
            [math.cos(w), -math.sin(w), (yd * math.cos(w) + xd * math.sin(w) - yd) / w],
            [math.sin(w), math.cos(w), (yd * math.sin(w) - xd * math.cos(w) + xd) / w],
            [0.0, 0.0, 1.0],
        ]
    )
    np.testing.assert_allclose(se2.to_matrix(se2.exp(Twist(xd, yd, w))), expected, atol=1e-15)


def test_exp_straight_line():
    assert se2.exp(Twist(2.0, 0.0, 0.0), 1.5) == Pose(3.0, 0.0, 0.0)


def test_quarter_circle_of_radius_R_ends_at_R_R_half_pi():
    radius, speed = 1.7, 0.4
    duration = (math.pi / 2) * radius / speed
    end = se2.exp(Twist(speed, 0.0, speed / radius), duration)
    assert pose_close(end, Pose(radius, radius, math.pi / 2), 1e-14)


def test_spin_in_place_turns_without_moving():
    assert pose_close(se2.exp(Twist(0.0, 0.0, math.pi), 0.5), Pose(0.0, 0.0, math.pi / 2))


def test_rotation_matrix_turns_body_x_onto_the_heading():
    # Seed 003: [x'; y'] = R(theta) [x_bf; y_bf].
    rotation = se2.rotation_matrix(math.pi / 6)
    np.testing.assert_allclose(rotation @ [1.0, 0.0], [math.sqrt(3) / 2, 0.5], atol=1e-15)
    np.testing.assert_allclose(rotation, se2.to_matrix(Pose(0, 0, math.pi / 6))[:2, :2])


def test_transform_point_is_the_rotation_plus_the_position():
    pose = Pose(1.0, 2.0, math.pi / 2)
    assert np.allclose(pose.transform_point(1.0, 0.0), (1.0, 3.0))


def test_pose_derivative_is_the_unicycle_ode_of_seed_000():
    theta, v, omega = 0.3, 1.2, -0.5
    rates = se2.pose_derivative(Pose(5.0, 6.0, theta), Twist(v, 0.0, omega))
    assert np.allclose(rates, (v * math.cos(theta), v * math.sin(theta), omega))


@pytest.mark.parametrize(
    ("angle", "wrapped"),
    [
        (0.0, 0.0),
        (math.pi, math.pi),
        (-math.pi, math.pi),
        (3 * math.pi, math.pi),
        (2 * math.pi, 0.0),
        (7.0, 7.0 - 2 * math.pi),
        (-4.0, 2 * math.pi - 4.0),
    ],
)
def test_wrap_angle_reference_values(angle, wrapped):
    assert wrap_angle(angle) == pytest.approx(wrapped, abs=1e-15)


@given(reals(1e4))
def test_wrap_angle_lands_in_half_open_interval_and_keeps_the_direction(angle):
    wrapped = wrap_angle(angle)
    assert -math.pi < wrapped <= math.pi
    assert math.cos(wrapped) == pytest.approx(math.cos(angle), abs=1e-11)
    assert math.sin(wrapped) == pytest.approx(math.sin(angle), abs=1e-11)


# -- group properties ----------------------------------------------------------------------


@given(poses, poses, poses)
def test_compose_is_associative(a, b, c):
    assert pose_close(a.compose(b).compose(c), a.compose(b.compose(c)), 1e-9)


@given(poses)
def test_inverse_composes_to_identity(p):
    assert pose_close(p.compose(p.inverse()), Pose(), 1e-12)
    assert pose_close(p.inverse().compose(p), Pose(), 1e-12)


@given(poses, poses)
def test_relative_to_is_inverse_then_compose(p, reference):
    assert pose_close(p.relative_to(reference), reference.inverse().compose(p), 1e-11)
    assert pose_close(reference.compose(p.relative_to(reference)), p, 1e-11)


@given(principal_twists)
def test_log_undoes_exp_on_the_principal_branch(twist):
    back = se2.log(se2.exp(twist))
    assert np.allclose(back.to_array(), twist.to_array(), rtol=0.0, atol=1e-10)


@given(poses)
def test_exp_undoes_log_up_to_whole_turns(p):
    back = se2.exp(se2.log(p))
    assert pose_close(back, Pose(p.x, p.y, wrap_angle(p.theta)), 1e-10)


@given(twists, st.floats(0.01, 2.0), st.integers(2, 16))
def test_exp_of_k_substeps_equals_one_step(twist, dt, k):
    # The exponential of a constant twist: k steps of dt/k compose to one step of dt.
    piece = se2.exp(twist, dt / k)
    total = Pose()
    for _ in range(k):
        total = total.compose(piece)
    assert pose_close(total, se2.exp(twist, dt), 1e-11)


def test_functional_forms_are_the_methods():
    a, b = Pose(1.0, 2.0, 0.3), Pose(-0.5, 0.2, 1.1)
    assert se2.compose(a, b) == a.compose(b)
    assert se2.inverse(a) == a.inverse()
    assert se2.relative_to(a, b) == a.relative_to(b)


# -- matrices ------------------------------------------------------------------------------


@given(poses)
def test_matrix_round_trip_and_homomorphism(p):
    assert pose_close(se2.from_matrix(se2.to_matrix(p)), p.wrapped(), 1e-12)
    q = Pose(0.3, -1.0, 2.0)
    np.testing.assert_allclose(
        se2.to_matrix(p) @ se2.to_matrix(q), se2.to_matrix(p.compose(q)), atol=1e-12
    )


@pytest.mark.parametrize(
    ("matrix", "message"),
    [
        (np.eye(2), r"shape \(3, 3\), got \(2, 2\)"),
        (np.diag([2.0, 2.0, 1.0]), "rigid motion"),
        (np.diag([1.0, -1.0, 1.0]), "rigid motion"),
        (np.array([[1, 0, 0], [0, 1, 0], [0.5, 0, 1.0]]), "rigid motion"),
        (np.full((3, 3), np.nan), "rigid motion"),
    ],
)
def test_from_matrix_refuses_what_is_not_a_rigid_motion(matrix, message):
    with pytest.raises(ValueError, match=message):
        se2.from_matrix(matrix)


# -- the Taylor threshold ------------------------------------------------------------------


def test_sinc_is_continuous_across_its_threshold():
    threshold = TAYLOR_LIMIT
    below, above = math.nextafter(threshold, 0.0), math.nextafter(threshold, 1.0)
    values = [se2.sinc(u) for u in (below, threshold, above)]
    assert max(values) - min(values) <= 4 * sys.float_info.epsilon
    assert se2.sinc(0.0) == 1.0
    assert se2.sinc(1e-300) == 1.0


def test_exp_is_continuous_across_the_threshold():
    threshold = 2 * TAYLOR_LIMIT  # omega*dt/2 crosses it
    below = se2.exp(Twist(1.0, 0.3, math.nextafter(threshold, 0.0)))
    above = se2.exp(Twist(1.0, 0.3, math.nextafter(threshold, 1.0)))
    assert pose_close(below, above, 4e-16)


def test_exp_refuses_non_finite_dt():
    with pytest.raises(ValueError, match="dt must be finite"):
        se2.exp(Twist(1.0), math.nan)
