"""simulate: reference scenarios, the solve_ivp oracle, convergence orders, batches, bad input."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive import integrate, simulation
from strategies import geometry

ROBOT = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)


def constant(wheels, steps):
    return np.tile(np.asarray(wheels, dtype=float), (steps, 1))


def random_wheels(seed, shape):
    return np.random.default_rng(seed).uniform(-10.0, 10.0, (*shape, 2))


# -- reference scenarios -------------------------------------------------------------------


def test_quarter_circle_ends_at_R_R_half_pi():
    radius, speed = 1.3, 0.5
    wheels = ROBOT.to_wheel_velocities(dd.Twist(speed, 0.0, speed / radius)).to_array()
    duration = (math.pi / 2) * radius / speed
    trajectory = dd.simulate(ROBOT, constant(wheels, 50), dt=duration / 50)
    np.testing.assert_allclose(trajectory.final_pose, [radius, radius, math.pi / 2], atol=1e-12)
    assert trajectory.distance[-1] == pytest.approx(math.pi / 2 * radius, abs=1e-12)


def test_straight_line_and_spin_in_place():
    straight = dd.simulate(ROBOT, constant([2.0, 2.0], 10), dt=0.1)
    np.testing.assert_allclose(straight.final_pose, [0.1, 0.0, 0.0], atol=1e-15)
    spin = dd.simulate(ROBOT, constant([-3.0, 3.0], 10), dt=0.1)
    np.testing.assert_allclose(spin.final_pose, [0.0, 0.0, 1.0], atol=1e-15)
    assert spin.distance[-1] == 0.0


def test_initial_pose_defaults_to_the_origin_and_is_honoured():
    wheels = random_wheels(1, (20,))
    moved = dd.simulate(ROBOT, wheels, dt=0.05, initial_pose=[1.0, -2.0, 0.7])
    from_origin = dd.simulate(ROBOT, wheels, dt=0.05)
    expected = dd.batch.compose(np.array([1.0, -2.0, 0.7]), from_origin.poses)
    np.testing.assert_allclose(moved.poses, expected, atol=1e-12)


@pytest.mark.parametrize("method", integrate.METHODS)
def test_batch_equals_scalar_steps(method):
    rng = np.random.default_rng(2)
    wheels = random_wheels(3, (40,))
    times = np.concatenate([[0.0], np.cumsum(rng.uniform(0.01, 0.2, 40))])
    trajectory = dd.simulate(
        ROBOT, wheels, times=times, initial_pose=[0.5, 0.2, -1.0], method=method
    )
    pose = dd.Pose(0.5, 0.2, -1.0)
    for k, (left, right) in enumerate(wheels):
        twist = ROBOT.to_twist(dd.WheelVelocities(left, right))
        pose = integrate.step(pose, twist, times[k + 1] - times[k], method)
        np.testing.assert_allclose(trajectory.poses[k + 1], pose.to_array(), atol=1e-12)


@given(st.integers(2, 6), st.integers(1, 30))
@settings(max_examples=20)
def test_exact_equals_any_finer_substepping(k, steps):
    wheels = random_wheels(steps, (steps,))
    coarse = dd.simulate(ROBOT, wheels, dt=0.1)
    fine = dd.simulate(ROBOT, np.repeat(wheels, k, axis=0), dt=0.1 / k)
    np.testing.assert_allclose(fine.poses[::k], coarse.poses, atol=1e-12)


@pytest.mark.parametrize("method", integrate.METHODS)
def test_driving_the_reversed_history_brings_the_robot_back(method):
    wheels = random_wheels(4, (30,))
    there = dd.simulate(ROBOT, wheels, dt=0.1, method=method)
    back = dd.simulate(ROBOT, -wheels[::-1], dt=0.1, initial_pose=there.final_pose, method=method)
    tolerance = 1e-12 if method == "exact" else 0.5  # only the arc retraces itself exactly
    np.testing.assert_allclose(back.final_pose, [0.0, 0.0, 0.0], atol=tolerance)


# -- the continuous history: oracle and convergence ------------------------------------------


def phi(t):
    """A smooth driving history, wheel angles in rad: speeds up, weaves, turns both ways."""
    t = np.asarray(t, dtype=float)
    left = 8.0 * t + 3.0 * np.sin(0.9 * t) + 0.2 * t**2
    right = 8.0 * t - 2.0 * np.sin(1.3 * t) + 1.5 * np.cos(0.4 * t) - 1.5
    return np.stack([left, right], axis=-1)


def phi_dot(t):
    t = np.asarray(t, dtype=float)
    left = 8.0 + 2.7 * np.cos(0.9 * t) + 0.4 * t
    right = 8.0 - 2.6 * np.cos(1.3 * t) - 0.6 * np.sin(0.4 * t)
    return np.stack([left, right], axis=-1)


DURATION = 10.0


def reference_final_pose():
    from scipy.integrate import solve_ivp  # here, not at collection

    def rates(t, pose):
        twist = dd.batch.to_twist(ROBOT, phi_dot(t))
        return dd.batch.pose_derivative(pose, twist)

    solution = solve_ivp(rates, (0.0, DURATION), [0.0, 0.0, 0.0], rtol=1e-12, atol=1e-12)
    assert solution.success
    return solution.y[:, -1]


def final_error(method, steps):
    times = np.linspace(0.0, DURATION, steps + 1)
    trajectory = dd.simulate(ROBOT, wheel_positions=phi(times), times=times, method=method)
    return np.linalg.norm(trajectory.final_pose[:2] - reference_final_pose()[:2])


def test_exact_agrees_with_solve_ivp_on_the_continuous_unicycle():
    assert final_error("exact", 4000) < 1e-6


def test_a_function_history_agrees_with_solve_ivp():
    trajectory = dd.simulate(ROBOT, phi_dot, dt=DURATION / 4000, duration=DURATION)
    np.testing.assert_allclose(trajectory.final_pose, reference_final_pose(), atol=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize(("method", "order"), [("euler", 1), ("rk2", 2), ("exact", 2)])
def test_convergence_order(method, order):
    errors = [final_error(method, steps) for steps in (200, 400, 800)]
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    for ratio in ratios:
        assert ratio == pytest.approx(2**order, rel=0.15), (errors, ratios)


# -- batches and dtype -----------------------------------------------------------------------


def test_n_robots_in_one_call_equal_one_at_a_time():
    wheels = random_wheels(5, (4, 25))
    starts = np.random.default_rng(6).uniform(-1, 1, (4, 3))
    together = dd.simulate(ROBOT, wheels, dt=0.05, initial_pose=starts)
    assert together.poses.shape == (4, 26, 3)
    for i in range(4):
        alone = dd.simulate(ROBOT, wheels[i], dt=0.05, initial_pose=starts[i])
        np.testing.assert_allclose(together.poses[i], alone.poses, atol=1e-12)


def test_leading_axes_broadcast_against_the_initial_pose():
    wheels = random_wheels(7, (25,))
    starts = np.zeros((3, 1, 3))
    assert dd.simulate(ROBOT, wheels, dt=0.1, initial_pose=starts).poses.shape == (3, 1, 26, 3)


@given(geometry())
@settings(max_examples=10)
def test_blocks_do_not_change_the_result(params):
    robot = dd.DiffDrive(**params)
    wheels = random_wheels(8, (3, 300))
    whole = dd.simulate(robot, wheels, dt=0.01)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(simulation, "_BLOCK_ELEMENTS", 7)  # blocks of 2 steps for 3 robots
        blocked = dd.simulate(robot, wheels, dt=0.01)
    np.testing.assert_allclose(blocked.poses, whole.poses, atol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize(("backend", "slack"), [("numpy", 0.0), ("numba", 1e-13)])
def test_float32_is_kept_and_stays_accurate_over_a_million_steps(backend, slack):
    steps = 1_000_000
    wheels = np.random.default_rng(9).uniform(5.0, 10.0, (steps, 2))
    single = dd.simulate(ROBOT, wheels.astype(np.float32), dt=1e-3, backend=backend)
    assert single.poses.dtype == np.float32
    # The bound: the float32 trajectory is the float64 integration of the same (rounded)
    # inputs, rounded once to float32 -- within half an ulp, at every one of the 10^6 steps;
    # no error accumulates from the long sums. The kernel's float64 runs, one pass against
    # three, agree to about 1e-14 of the value, so a value that close to a rounding boundary
    # of float32 may round either way: hence its relative slack.
    float64_inputs = wheels.astype(np.float32).astype(np.float64)
    same_inputs = dd.simulate(ROBOT, float64_inputs, dt=1e-3, backend=backend).poses
    half_ulp = 0.5 * np.spacing(np.abs(same_inputs).astype(np.float32)).astype(np.float64)
    assert np.all(np.abs(single.poses - same_inputs) <= half_ulp + slack * np.abs(same_inputs))
    # Against the unrounded float64 input: within 1e-7 of the path length (375 m here).
    reference = dd.simulate(ROBOT, wheels, dt=1e-3, backend=backend)
    error = np.abs(single.poses[:, :2] - reference.poses[:, :2]).max()
    assert error < 1e-7 * reference.distance[-1], error


# -- the Trajectory --------------------------------------------------------------------------


def test_trajectory_views():
    wheels = random_wheels(10, (30,))
    trajectory = dd.simulate(ROBOT, wheels, dt=0.1, initial_pose=[0.0, 0.0, 3.0])
    assert trajectory.steps == 30
    assert np.all(np.abs(trajectory.wrapped_headings) <= math.pi)
    np.testing.assert_allclose(trajectory.twists, dd.batch.to_twist(ROBOT, wheels))
    np.testing.assert_allclose(trajectory.wheel_positions[-1], wheels.sum(axis=0) * 0.1)
    table = trajectory.to_array()
    assert table.shape == (31, 4)
    np.testing.assert_allclose(table[:, 0], np.arange(31) * 0.1)
    assert np.all(np.diff(trajectory.distance) >= 0)


def test_sampling_follows_the_arc():
    wheels = ROBOT.to_wheel_velocities(dd.Twist(0.5, 0.0, 0.5)).to_array()
    trajectory = dd.simulate(ROBOT, constant(wheels, 4), dt=1.0)
    at = np.array([0.0, 0.5, 1.0, 2.25, 4.0])
    expected = [dd.se2.exp(dd.Twist(0.5, 0.0, 0.5), t).to_array() for t in at]
    np.testing.assert_allclose(trajectory.sample(at), expected, atol=1e-12)
    with pytest.raises(ValueError, match=r"at must lie within \[0.0, 4.0\] s, got 4.5"):
        trajectory.sample([4.5])


def test_wheel_angle_history_uses_the_increments():
    times = np.linspace(0.0, 2.0, 21)
    angles = phi(times) + 100.0  # the offset of the encoders does not matter
    from_angles = dd.simulate(ROBOT, wheel_positions=angles, times=times)
    velocities = np.diff(angles, axis=0) / 0.1
    from_velocities = dd.simulate(ROBOT, velocities, dt=0.1)
    np.testing.assert_allclose(from_angles.poses, from_velocities.poses, atol=1e-12)
    np.testing.assert_allclose(from_angles.wheel_positions, angles - angles[0], atol=1e-12)


# -- bad input -------------------------------------------------------------------------------


def failing(t):
    raise RuntimeError("sensor offline")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {"wheel_velocities": [[1.0, np.nan], [1.0, 1.0]], "dt": 0.1},
            r"wheel_velocities must be finite, got nan at index \(0, 1\)",
        ),
        ({"wheel_velocities": [[1.0, 1.0], [np.inf, 1.0]], "dt": 0.1}, r"at index \(1, 0\)"),
        (
            {"wheel_velocities": [[1.0, 1.0]], "times": [0.0, 0.0]},
            r"times must increase strictly; times\(1,\) = 0.0 follows 0.0",
        ),
        ({"wheel_velocities": [[1.0, 1.0]] * 2, "times": [0.0, 1.0]}, r"T\+1 = 3 entries"),
        ({"wheel_velocities": [[1.0, 1.0]], "dt": 0.0}, "dt must be a finite number > 0"),
        ({"wheel_velocities": [[1.0, 1.0]], "dt": -1.0}, "dt must be a finite number > 0"),
        ({"wheel_velocities": [[1.0, 1.0]]}, "give exactly one of dt"),
        ({"wheel_velocities": [[1.0, 1.0]], "dt": 0.1, "times": [0, 1]}, "give exactly one of dt"),
        ({"wheel_velocities": [1.0, 1.0], "dt": 0.1}, r"shape \(\.\.\., T, 2\)"),
        (
            {"wheel_velocities": [[1.0, 1.0, 1.0]], "dt": 0.1},
            r"shape \(\.\.\., 2\) \[left, right\]",
        ),
        ({"dt": 0.1}, "give exactly one of wheel_velocities or wheel_positions"),
        ({"wheel_positions": [[0.0, 0.0]], "dt": 0.1}, "at least 2 samples"),
        (
            {"wheel_velocities": np.ones((2, 5, 2)), "dt": 0.1, "initial_pose": np.zeros((3, 3))},
            "leading axes do not broadcast",
        ),
        ({"wheel_velocities": [[1.0, 1.0]], "dt": 0.1, "method": "rk4"}, "method must be one of"),
        (
            {"wheel_velocities": failing, "dt": 0.1, "duration": 1.0},
            "wheel_velocities raised RuntimeError: sensor offline",
        ),
        (
            {"wheel_velocities": lambda t: t, "dt": 0.1, "duration": 1.0},
            r"must return shape \(\.\.\., 10, 2\)",
        ),
        ({"wheel_velocities": phi_dot, "dt": 0.3, "duration": 1.0}, "not a whole number of steps"),
        ({"wheel_velocities": phi_dot, "dt": 0.1}, "give times, or dt and duration"),
        ({"wheel_velocities": [[1.0, 1.0]], "dt": 0.1, "duration": 1.0}, "duration is only for"),
        (
            {"wheel_velocities": [[1.0, 1.0]], "dt": 0.1, "initial_pose": [0, 0, np.nan]},
            "initial_pose must be finite",
        ),
    ],
)
def test_bad_input_is_refused_before_any_work(kwargs, message):
    with pytest.raises(ValueError, match=message):
        dd.simulate(ROBOT, **kwargs)
