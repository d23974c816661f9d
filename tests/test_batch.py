"""The batch layer: scalar equals batch to 1e-12 over batch shapes; dtype kept; shapes checked."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive import (
    DiffDrive,
    Pose,
    Twist,
    WheelPositions,
    WheelVelocities,
    batch,
    integrate,
    se2,
)
from diffdrive._step import TAYLOR_LIMIT
from strategies import BATCH_SHAPES, batch_of, geometry

TOL = 1e-12


def each(array: np.ndarray, size: int):
    """The rows of ``array`` over its leading axes, with their index."""
    for index in np.ndindex(*array.shape[: array.ndim - size]):
        yield index, array[index]


def same(batch_value: np.ndarray, scalar_value) -> None:
    np.testing.assert_allclose(batch_value, np.asarray(scalar_value), rtol=0.0, atol=TOL)


# -- scalar equals batch -------------------------------------------------------------------


@given(batch_of(3, bound=5.0), st.floats(0.01, 2.0))
def test_exp(twists, dt):
    out = batch.exp(twists, dt)
    assert out.shape == twists.shape
    for i, row in each(twists, 1):
        same(out[i], se2.exp(Twist(*row), dt).to_array())


@given(batch_of(3, bound=20.0))
def test_log_and_wrap(poses):
    out = batch.log(poses)
    for i, row in each(poses, 1):
        same(out[i], se2.log(Pose(*row)).to_array())
        same(batch.wrap_angle(poses[..., 2])[i], se2.wrap_angle(row[2]))


@given(batch_of(3), batch_of(3))
def test_compose_inverse_relative(a, b):
    b = b.reshape(-1, 3)[0] if b.size else np.zeros(3)  # one b broadcast against every a
    composed, relative, inverted = batch.compose(a, b), batch.relative_to(a, b), batch.inverse(a)
    for i, row in each(a, 1):
        pa, pb = Pose(*row), Pose(*b)
        same(composed[i], pa.compose(pb).to_array())
        same(relative[i], pa.relative_to(pb).to_array())
        same(inverted[i], pa.inverse().to_array())


@given(batch_of(3), batch_of(3, shapes=[()]))
def test_transform_points_and_pose_derivative(poses, twist):
    points = poses[..., :2] * 0.5
    moved = batch.transform_points(poses, points)
    rates = batch.pose_derivative(poses, twist)
    for i, row in each(poses, 1):
        pose = Pose(*row)
        same(moved[i], pose.transform_point(*points[i]))
        same(rates[i], se2.pose_derivative(pose, Twist(*twist)))


@given(batch_of(3))
def test_matrices(poses):
    matrices = batch.to_matrix(poses)
    assert matrices.shape == (*poses.shape[:-1], 3, 3)
    rotations = batch.rotation_matrix(poses[..., 2])
    back = batch.from_matrix(matrices)
    for i, row in each(poses, 1):
        same(matrices[i], se2.to_matrix(Pose(*row)))
        same(rotations[i], se2.rotation_matrix(row[2]))
        same(back[i], se2.from_matrix(se2.to_matrix(Pose(*row))).to_array())


@pytest.mark.parametrize("method", integrate.METHODS)
@given(poses=batch_of(3), twists=batch_of(3, bound=3.0), dt=st.floats(0.001, 1.0))
def test_integration_step(method, poses, twists, dt):
    twists = np.broadcast_to(twists.reshape(-1, 3)[0], poses.shape)
    out = batch.step(poses, twists, dt, method)
    for i, row in each(poses, 1):
        same(out[i], integrate.step(Pose(*row), Twist(*twists[i]), dt, method).to_array())


@given(geometry(), batch_of(2), batch_of(3))
def test_kinematics(params, wheels, twists):
    robot = DiffDrive(**params)
    to_twist = batch.to_twist(robot, wheels)
    radius = batch.turning_radius(robot, wheels)
    centre = batch.instantaneous_center(robot, wheels)
    for i, (left, right) in each(wheels, 1):
        w = WheelVelocities(left, right)
        same(to_twist[i], robot.to_twist(w).to_array())
        expected = robot.turning_radius(w)
        np.testing.assert_allclose(radius[i], expected, rtol=1e-12, atol=TOL)
        np.testing.assert_allclose(centre[i], robot.instantaneous_center(w), rtol=1e-12, atol=TOL)
    wheel_out = batch.to_wheel_velocities(robot, twists)
    for i, row in each(twists, 1):
        np.testing.assert_allclose(
            wheel_out[i], robot.to_wheel_velocities(Twist(*row)).to_array(), rtol=1e-12, atol=1e-9
        )


@given(batch_of(2), batch_of(2, shapes=[()]), st.floats(0.01, 1.0))
def test_wheel_angle_bookkeeping(positions, velocities, dt):
    after = batch.advance_wheel_positions(positions, velocities, dt)
    speeds = batch.wheel_velocities_from_positions(positions, after, dt)
    for i, row in each(positions, 1):
        p, w = WheelPositions(*row), WheelVelocities(*velocities)
        same(after[i], p.advance(w, dt).to_array())
        np.testing.assert_allclose(speeds[i], w.to_array(), atol=1e-9)


# -- properties over batch shapes ------------------------------------------------------------


@given(geometry(), batch_of(2))
def test_inverse_kinematics_undoes_forward_in_batch(params, wheels):
    robot = DiffDrive(**params)
    back = batch.to_wheel_velocities(robot, batch.to_twist(robot, wheels))
    np.testing.assert_allclose(back, wheels, atol=1e-9)


@given(batch_of(3, bound=5.0))
def test_exp_log_round_trip_in_batch(twists):
    twists = twists.copy()
    twists[..., 2] = np.clip(twists[..., 2], -3.1, 3.1)  # principal branch
    np.testing.assert_allclose(batch.log(batch.exp(twists)), twists, atol=1e-10)


@given(batch_of(3), batch_of(3), batch_of(3))
def test_compose_is_associative_in_batch(a, b, c):
    a, b, c = np.broadcast_arrays(
        a[..., :1, :] if a.ndim > 1 else a, b[..., :1, :] if b.ndim > 1 else b, c
    )
    left = batch.compose(batch.compose(a, b), c)
    right = batch.compose(a, batch.compose(b, c))
    np.testing.assert_allclose(left, right, atol=1e-9)
    np.testing.assert_allclose(batch.compose(a, batch.inverse(a)), np.zeros_like(a), atol=1e-12)


def test_leading_axes_broadcast():
    a = np.zeros((3, 1, 3))
    b = np.ones((4, 3))
    assert batch.compose(a, b).shape == (3, 4, 3)
    assert batch.exp(np.ones((5, 3)), np.full((5,), 0.1)).shape == (5, 3)


# -- dtype -----------------------------------------------------------------------------------

ROBOT = DiffDrive(wheel_radius=0.1, track_width=0.5, axle_offset=0.05)

ALL_CALLS = {
    "exp": lambda a3, a2: batch.exp(a3, 0.1),
    "log": lambda a3, a2: batch.log(a3),
    "compose": lambda a3, a2: batch.compose(a3, a3),
    "inverse": lambda a3, a2: batch.inverse(a3),
    "relative_to": lambda a3, a2: batch.relative_to(a3, a3),
    "relative_jacobians": lambda a3, a2: batch.relative_jacobians(a3, a3[::-1])[0],
    "wrap_angle": lambda a3, a2: batch.wrap_angle(a3),
    "rotation_matrix": lambda a3, a2: batch.rotation_matrix(a3[..., 2]),
    "to_matrix": lambda a3, a2: batch.to_matrix(a3),
    "from_matrix": lambda a3, a2: batch.from_matrix(batch.to_matrix(a3)),
    "transform_points": lambda a3, a2: batch.transform_points(a3, a2),
    "pose_derivative": lambda a3, a2: batch.pose_derivative(a3, a3),
    "sinc": lambda a3, a2: batch.sinc(a3),
    "step": lambda a3, a2: batch.step(a3, a3, 0.1, "rk2"),
    "to_twist": lambda a3, a2: batch.to_twist(ROBOT, a2),
    "to_wheel_velocities": lambda a3, a2: batch.to_wheel_velocities(ROBOT, a3),
    "turning_radius": lambda a3, a2: batch.turning_radius(ROBOT, a2),
    "instantaneous_center": lambda a3, a2: batch.instantaneous_center(ROBOT, a2),
    "advance_wheel_positions": lambda a3, a2: batch.advance_wheel_positions(a2, a2, 0.1),
    "accumulate": lambda a3, a2: batch.accumulate(a3, method="rk2"),
    "rollout": lambda a3, a2: batch.rollout(ROBOT, a2, 0.1),
    "twists": lambda a3, a2: batch.twists(np.asarray([0.1, 0.1, 0.5, 0.05], a2.dtype), a2),
    "wheel_velocities_from_positions": lambda a3, a2: batch.wheel_velocities_from_positions(
        a2, a2, 0.1
    ),
}


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("name", sorted(ALL_CALLS))
def test_floating_dtype_is_kept(name, dtype):
    rng = np.random.default_rng(0)
    a3 = rng.uniform(-1, 1, (4, 3)).astype(dtype)
    a2 = rng.uniform(-1, 1, (4, 2)).astype(dtype)
    a2[0] = [1.0, 1.0]  # a straight line: turning_radius is inf there, not a warning
    assert ALL_CALLS[name](a3, a2).dtype == dtype


def test_integers_become_float64():
    assert batch.to_twist(ROBOT, np.array([[1, 2]])).dtype == np.float64
    assert batch.exp([1, 0, 1]).dtype == np.float64


def test_names_cover_the_batch_api():
    assert set(ALL_CALLS) == set(batch.__all__) - {"delta"}


def test_float32_sinc_is_continuous_across_its_threshold():
    eps = float(np.finfo(np.float32).eps)
    t = np.float32(TAYLOR_LIMIT)
    u = np.array([np.nextafter(t, np.float32(0)), t, np.nextafter(t, np.float32(1))])
    values = batch.sinc(u)
    assert values.dtype == np.float32
    assert float(values.max() - values.min()) <= 4 * eps
    exact = np.sin(u.astype(np.float64)) / u.astype(np.float64)
    np.testing.assert_allclose(values, exact, rtol=2 * eps)


def test_special_turning_radii_in_batch():
    wheels = np.array([[1.0, 1.0], [-1.0, -1.0], [-1.0, 1.0], [0.0, 0.0]])
    radius = batch.turning_radius(ROBOT, wheels)
    assert radius[0] == math.inf
    assert radius[1] == -math.inf
    assert radius[2] == 0.0
    assert math.isnan(radius[3])


# -- shapes ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda: batch.to_twist(ROBOT, np.zeros(3)),
            r"wheels must have shape \(\.\.\., 2\) \[left, right\], got \(3,\)",
        ),
        (lambda: batch.to_twist(ROBOT, np.zeros((4, 1))), r"got \(4, 1\)"),
        (lambda: batch.to_twist(ROBOT, 1.0), r"got \(\)"),
        (
            lambda: batch.exp(np.zeros((2, 2))),
            r"twists must have shape \(\.\.\., 3\) \[vx, vy, omega\], got \(2, 2\)",
        ),
        (
            lambda: batch.compose(np.zeros((2, 3)), np.zeros((3, 3))),
            r"leading axes do not broadcast: a \(2,\), b \(3,\)",
        ),
        (lambda: batch.exp(np.zeros((2, 3)), np.ones(3)), r"twists \(2,\), dt \(3,\)"),
        (lambda: batch.from_matrix(np.zeros((3, 2))), r"matrices must have shape \(\.\.\., 3, 3\)"),
        (lambda: batch.from_matrix(np.zeros((2, 3, 3))), "rigid motions"),
        (
            lambda: batch.advance_wheel_positions(np.zeros(2), np.zeros(2), 0.0),
            "dt must be finite and > 0",
        ),
        (
            lambda: batch.wheel_velocities_from_positions(np.zeros(2), np.zeros(2), [0.1, -1.0]),
            "dt must be",
        ),
    ],
)
def test_bad_shapes_and_values_are_named(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_complex_input_is_refused():
    with pytest.raises(TypeError, match="wheels must hold real numbers"):
        batch.to_twist(ROBOT, np.zeros(2, dtype=complex))


@pytest.mark.parametrize("shape", BATCH_SHAPES)
def test_output_shapes_follow_the_input(shape):
    assert batch.to_twist(ROBOT, np.zeros((*shape, 2))).shape == (*shape, 3)
    assert batch.to_wheel_velocities(ROBOT, np.zeros((*shape, 3))).shape == (*shape, 2)
    assert batch.turning_radius(ROBOT, np.ones((*shape, 2))).shape == shape
    assert batch.to_matrix(np.zeros((*shape, 3))).shape == (*shape, 3, 3)


@pytest.mark.slow
@given(geometry(), batch_of(2))
def test_every_batch_twist_is_F_times_the_wheels_and_does_not_slip(params, wheels):
    robot = DiffDrive(**params)
    twists = batch.to_twist(robot, wheels)
    mr_order = twists[..., [2, 0, 1]]  # (omega, vx, vy)
    np.testing.assert_allclose(mr_order, wheels @ robot.f_matrix().T, atol=1e-9)
    np.testing.assert_allclose(mr_order @ robot.constraint_matrix().T, 0.0, atol=1e-12)
    np.testing.assert_allclose(mr_order @ robot.h_matrix().T, wheels, atol=1e-8)


def test_overflow_propagates_as_numpy_does():
    """The batch layer's rule (docs/conventions.md): finite input whose result overflows gives
    inf, with NumPy's RuntimeWarning under NumPy's errstate; nothing is checked per element."""
    robot = dd.DiffDrive(wheel_radius=1.0, track_width=1e-10, axle_offset=0.1)
    wheels = np.array([[-1e300, 1e300]])  # a turn rate of 2e310 rad/s
    with pytest.warns(RuntimeWarning, match="overflow"):
        twists = dd.batch.to_twist(robot, wheels)
    assert twists[0, 0] == 0.0
    assert np.isinf(twists[0, 2])
    with np.errstate(over="ignore"):
        poses = dd.batch.exp(np.array([[1e308, 0.0, 0.0]]), 10.0)
    assert np.isinf(poses[0, 0])
    with np.errstate(over="raise"), pytest.raises(FloatingPointError):
        dd.batch.to_twist(robot, wheels)
