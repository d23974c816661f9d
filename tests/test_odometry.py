"""Odometry: worked cases, roll-over, streaming equals batch, faults, covariance, Jacobians."""

import contextlib
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive import integrate
from diffdrive.encoders import count_changes
from strategies import geometry

ROBOT = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
TICKS = 1000  # per revolution
RAD_PER_TICK = 2 * math.pi / TICKS


def state(odometry):
    """Everything an update may change."""
    return (
        odometry._state(),
        odometry._covariance(),
        odometry._window_velocities(),
        odometry.pose,
    )


def close(value, expected, atol=1e-12):
    """Whether two value types (Pose, Twist, WheelVelocities) agree to ``atol``."""
    return np.allclose(value.to_array(), expected.to_array(), rtol=0, atol=atol)


# -- worked cases --------------------------------------------------------------------------


def test_straight_line_from_ticks():
    odometry = dd.Odometry(ROBOT, ticks_per_revolution=TICKS)
    odometry.update_ticks(0, 0)
    odometry.update_ticks(500, 500)  # half a turn of 0.05 m wheels: 0.05 pi m
    assert close(odometry.pose, dd.Pose(0.05 * math.pi, 0.0, 0.0), 1e-15)
    assert odometry.distance == pytest.approx(0.05 * math.pi)


@pytest.mark.parametrize("method", integrate.METHODS)
def test_spin_in_place_turns_without_moving(method):
    odometry = dd.Odometry(ROBOT, method)
    odometry.update_increments(-3.0, 3.0)  # wheels 0.15 m each way: 1 rad
    assert close(odometry.pose, dd.Pose(0.0, 0.0, 1.0), 1e-15)


def test_quarter_circle_is_exact_in_one_update():
    radius, turn = 1.3, math.pi / 2
    left, right = [(radius + side * 0.15) * turn / 0.05 for side in (-1, 1)]
    odometry = dd.Odometry(ROBOT, "exact", initial_pose=dd.Pose(1.0, 2.0, 0.0))
    odometry.update_increments(left, right)
    assert close(odometry.pose, dd.Pose(1.0 + radius, 2.0 + radius, turn), 1e-14)


def test_the_first_reading_is_only_the_reference():
    odometry = dd.Odometry(ROBOT, ticks_per_revolution=TICKS, initial_pose=dd.Pose(1, 2, 3))
    odometry.update_ticks(123456, -98765, t=10.0)
    odometry.update_positions(50.0, -7.0)
    assert odometry.pose == dd.Pose(1.0, 2.0, 3.0)
    assert odometry.time == 10.0


def test_reset_keeps_the_reference_so_nothing_jumps():
    odometry = dd.Odometry(ROBOT, ticks_per_revolution=TICKS)
    odometry.update_ticks(100, 100)
    odometry.update_ticks(600, 600)
    odometry.reset(dd.Pose(5.0, 0.0, 0.0))
    assert odometry.distance == 0.0
    odometry.update_ticks(1100, 1100)
    assert close(odometry.pose, dd.Pose(5.0 + 0.05 * math.pi, 0.0, 0.0))


def test_velocities_keep_a_clock_and_the_twist_follows():
    odometry = dd.Odometry(ROBOT, velocity_window=0.05)
    for _ in range(10):
        odometry.update_velocities(8.0, 10.0, 0.01)
    assert odometry.time == pytest.approx(0.1)
    assert close(odometry.twist, ROBOT.to_twist(dd.WheelVelocities(8.0, 10.0)))


def test_the_twist_averages_over_the_window_only():
    odometry = dd.Odometry(ROBOT, velocity_window=0.1)
    odometry.update_positions(0.0, 0.0, t=0.0)
    for k in range(1, 11):  # 1 s at 2 rad/s
        odometry.update_positions(0.2 * k, 0.2 * k, t=0.1 * k)
    for k in range(1, 3):  # then 0.1 s at 5 rad/s
        odometry.update_positions(2.0 + 0.25 * k, 2.0 + 0.25 * k, t=1.0 + 0.05 * k)
    assert close(odometry.wheel_velocities, dd.WheelVelocities(5.0, 5.0))


def test_the_twist_needs_times():
    odometry = dd.Odometry(ROBOT)
    odometry.update_increments(1.0, 1.0)
    with pytest.raises(ValueError, match="two time-stamped updates"):
        odometry.twist  # noqa: B018


# -- counters and roll-over ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("bits", "before", "after", "change"),
    [
        (16, 65530, 5, 11),  # unsigned, forward through 0
        (16, 5, 65530, -11),  # unsigned, backward
        (16, 32767, -32768, 1),  # signed
        (16, -32760, 32760, -16),  # signed, backward
        (32, 2**32 - 1, 0, 1),
        (32, 2**31 - 1, -(2**31), 1),
        (None, -(10**12), 10**12, 2 * 10**12),
        (12, 4090, 5, 11),  # the widths of hobby and industrial encoders
        (10, 3, 1020, -7),
        (14, 2**14 - 1, 0, 1),
        (24, -(2**23), 2**23 - 1, -1),
        (2, 3, 0, 1),
        (64, 2**64 - 3, 2, 5),  # unsigned 64-bit readings of 2^63 and more
        (64, 2**63 - 1, 2**63, 1),
        (64, -1, 2**64 - 2, -1),
    ],
)
def test_counter_roll_over(bits, before, after, change):
    odometry = dd.Odometry(ROBOT, ticks_per_revolution=TICKS, counter_bits=bits)
    odometry.update_ticks(before, before)
    odometry.update_ticks(after, after)
    assert odometry.pose.x == pytest.approx(change * RAD_PER_TICK * 0.05, rel=1e-12)


@given(st.integers(2, 64), st.booleans(), st.data())
@settings(max_examples=80)
def test_wrapped_counters_give_the_unwrapped_pose(bits, signed, data):
    """Any history of true counts, wrapped to a signed or unsigned counter of any width from
    2 to 64 bits, reads the same in the streaming class and in the whole-array rule."""
    modulus = 2**bits
    low = -(modulus // 2) if signed else 0
    step = st.integers(-(modulus // 2), modulus // 2 - 1)
    steps = data.draw(st.lists(st.tuples(step, step), max_size=30))
    start = data.draw(st.integers(-(2**40), 2**40))
    wrapped = dd.Odometry(ROBOT, ticks_per_revolution=TICKS, counter_bits=bits)
    plain = dd.Odometry(ROBOT)
    counts = np.cumsum(np.array([(start, start), *steps], dtype=object), axis=0)
    readings = (counts - low) % modulus + low
    wrapped.update_ticks(*readings[0].tolist())
    for (left, right), change in zip(
        readings[1:].tolist(), np.diff(counts, axis=0).tolist(), strict=False
    ):
        plain.update_increments(change[0] * RAD_PER_TICK, change[1] * RAD_PER_TICK)
        wrapped.update_ticks(left, right)
    assert wrapped.pose == plain.pose
    dtype = np.uint64 if readings.max() >= 2**63 else np.int64
    changes = count_changes(readings.astype(dtype), bits)
    assert changes.tolist() == np.diff(counts, axis=0).tolist()


def test_a_12_bit_counter_read_as_16_bits_is_a_jump_that_max_wheel_speed_refuses():
    odometry = dd.Odometry(
        ROBOT, ticks_per_revolution=TICKS, counter_bits=16, max_wheel_speed=100.0
    )
    odometry.update_ticks(4090, 4090, t=0.0)
    with pytest.raises(ValueError, match="max_wheel_speed"):
        odometry.update_ticks(5, 5, t=0.01)  # 12-bit roll-over: read as -4085 counts
    twelve = dd.Odometry(ROBOT, ticks_per_revolution=TICKS, counter_bits=12)
    twelve.update_ticks(4090, 4090, t=0.0)
    twelve.update_ticks(5, 5, t=0.01)
    assert twelve.pose.x == pytest.approx(11 * RAD_PER_TICK * 0.05, rel=1e-12)


@pytest.mark.parametrize(
    ("left", "right"),
    [(np.float64(1000.0), np.float32(7.0)), (np.int64(1000), np.uint16(7)), (1000.0, 7)],
)
def test_counter_readings_may_be_numpy_scalars_and_whole_floats(left, right):
    odometry = dd.Odometry(ROBOT, ticks_per_revolution=TICKS)
    odometry.update_ticks(left, right)
    odometry.update_ticks(left + 10, right + 10)
    assert odometry.pose.x == pytest.approx(10 * RAD_PER_TICK * 0.05, rel=1e-12)


@pytest.mark.parametrize(
    ("reading", "error", "message"),
    [
        (np.float64(1.5), ValueError, "must be a whole counter reading"),
        (math.inf, ValueError, "must be a whole counter reading"),
        (True, TypeError, "must be an integer counter reading"),
        ("12", TypeError, "must be an integer counter reading"),
        (2**12, ValueError, r"does not fit a 12-bit counter \(from -2\^11 to 2\^12 - 1"),
        (2**64, ValueError, "does not fit a 64-bit counter"),
    ],
)
def test_bad_counter_readings_are_refused(reading, error, message):
    bits = 64 if reading == 2**64 else 12
    odometry = dd.Odometry(ROBOT, ticks_per_revolution=TICKS, counter_bits=bits)
    with pytest.raises(error, match=message):
        odometry.update_ticks(reading, 0)


# -- streaming equals batch --------------------------------------------------------------------


@pytest.mark.parametrize("method", integrate.METHODS)
def test_streaming_equals_simulate_on_the_same_log(method):
    rng = np.random.default_rng(5)
    robot = dd.DiffDrive(left_wheel_radius=0.05, right_wheel_radius=0.052, track_width=0.3)
    times = np.cumsum(rng.uniform(0.005, 0.05, 2001)) - 0.005
    counters = np.cumsum(rng.integers(-20, 60, (2001, 2)), axis=0)
    start = dd.Pose(0.3, -0.2, 2.0)
    batch = dd.simulate(
        robot,
        wheel_positions=counters * RAD_PER_TICK,
        times=times,
        initial_pose=start.to_array(),
        method=method,
    )
    ticks = dd.Odometry(robot, method, start, ticks_per_revolution=TICKS)
    positions = dd.Odometry(robot, method, start)
    increments = dd.Odometry(robot, method, start)
    velocities = dd.Odometry(robot, method, start)
    ticks.update_ticks(*counters[0].tolist(), t=times[0])
    positions.update_positions(*(counters[0] * RAD_PER_TICK), t=times[0])
    for k in range(1, len(times)):
        ticks.update_ticks(*counters[k].tolist(), t=times[k])
        angles = counters[k] * RAD_PER_TICK
        positions.update_positions(*angles, t=times[k])
        increments.update_increments(*(angles - counters[k - 1] * RAD_PER_TICK), t=times[k])
        velocities.update_velocities(*batch.wheel_velocities[k - 1], times[k] - times[k - 1])
        if k % 400 == 0 or k == len(times) - 1:
            for odometry in (ticks, positions, increments, velocities):
                np.testing.assert_allclose(
                    odometry.pose.to_array(), batch.poses[k], rtol=0, atol=1e-9
                )
    assert ticks.distance == pytest.approx(batch.distance[-1], abs=1e-9)


# -- faults: refused, and nothing changes ------------------------------------------------------


def ready():
    odometry = dd.Odometry(ROBOT, ticks_per_revolution=TICKS, counter_bits=16, max_wheel_speed=50)
    odometry.update_ticks(100, 100, t=1.0)
    odometry.update_ticks(150, 160, t=1.1)
    odometry.update_positions(1.0, 2.0, t=1.1)
    return odometry


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda o: o.update_positions(math.nan, 2.0, t=1.2), "left must be finite, got nan"),
        (lambda o: o.update_increments(0.1, math.inf), "right must be finite, got inf"),
        # A NumPy scalar prints as the number, not as np.float64(nan).
        (lambda o: o.update_increments(np.float64("nan"), 0.1), "left must be finite, got nan$"),
        (lambda o: o.update_velocities(1.0, 1.0, 0.0), "dt must be > 0, got 0.0"),
        (lambda o: o.update_velocities(1.0, 1.0, -0.1), "dt must be > 0"),
        (lambda o: o.update_positions(1.1, 2.1, t=math.nan), "t must be finite, got nan"),
        (lambda o: o.update_ticks(170, 170, t=1.05), "time went backwards: t = 1.05 s after 1.1"),
        (lambda o: o.update_positions(1.5, 2.0, t=1.1), "time stands still at t = 1.1 s"),
        (lambda o: o.update_ticks(30000, 160, t=1.2), r"over max_wheel_speed 50\.0 rad/s"),
        (lambda o: o.update_increments(6.0, 0.0, t=1.2), r"6\.0 rad in 0\.09\d+ s, 60\.0\d+ rad/s"),
        (lambda o: o.update_ticks(1.5, 160, t=1.2), "left must be a whole counter reading"),
        (lambda o: o.update_ticks(150, 70000, t=1.2), "right = 70000 does not fit a 16-bit"),
        (lambda o: o.update_velocities(1.0, 600.0, 0.1), "600.0 rad/s, over max_wheel_speed"),
        # The C core's words, or the pure-Python core's (Python's own).
        (
            lambda o: o.update_positions(1.0),
            "update_positions needs left and right|missing 1 required positional argument",
        ),
        (lambda o: o.update_positions(1.0, 2.0, dt=3), "unexpected keyword argument '?dt"),
    ],
)
def test_a_bad_update_is_refused_and_changes_nothing(call, message):
    odometry, reference = ready(), ready()
    before = state(odometry)
    with pytest.raises((ValueError, TypeError), match=message):
        call(odometry)
    assert state(odometry) == before
    # And the next good update continues as if the bad one had never come.
    for o in (odometry, reference):
        o.update_ticks(200, 230, t=1.3)
        o.update_positions(1.5, 2.5, t=1.4)
    assert state(odometry) == state(reference)


def test_standing_still_in_time_without_moving_is_fine():
    odometry = ready()
    velocities = odometry.wheel_velocities
    odometry.update_positions(1.0, 2.0, t=1.1)
    assert odometry.time == 1.1
    assert odometry.wheel_velocities == velocities


def test_ticks_need_ticks_per_revolution():
    with pytest.raises(ValueError, match="update_ticks needs ticks_per_revolution"):
        dd.Odometry(ROBOT).update_ticks(1, 2)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"method": "midpoint"}, "method must be one of euler, rk2, exact"),
        ({"counter_bits": 1}, "counter_bits must be from 2 to 64 .*got 1"),
        ({"counter_bits": 65}, "counter_bits must be from 2 to 64 .*got 65"),
        ({"ticks_per_revolution": 0}, "ticks_per_revolution must be > 0"),
        ({"max_wheel_speed": -1.0}, "max_wheel_speed must be > 0"),
        ({"wheel_noise": (-0.1, 0.0)}, "wheel noise left must be a number >= 0"),
        ({"wheel_noise": (0.0, math.nan)}, "wheel noise right must be finite"),
        ({"velocity_window": 0.0}, "velocity_window must be > 0"),
        ({"initial_covariance": np.eye(2)}, "covariance must be 3x3"),
        ({"initial_covariance": -np.eye(3)}, "positive semi-definite"),
        ({"initial_covariance": [[1, 2, 0], [0, 1, 0], [0, 0, 1]]}, "symmetric"),
    ],
)
def test_bad_configuration_is_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        dd.Odometry(ROBOT, **kwargs)


# -- uncertainty -------------------------------------------------------------------------------


def central_difference(function, point, h=1e-6):
    point = np.asarray(point, dtype=float)
    columns = []
    for i in range(point.size):
        step = np.zeros_like(point)
        step[i] = h
        columns.append((function(point + step) - function(point - step)) / (2 * h))
    return np.stack(columns, axis=-1)


@given(
    geometry(),
    st.sampled_from(integrate.METHODS),
    st.tuples(*[st.floats(-3, 3)] * 3),
    st.tuples(st.floats(-2, 2), st.floats(-2, 2)),
)
@settings(max_examples=60)
def test_jacobians_match_finite_differences(params, method, pose, increments):
    robot = dd.DiffDrive(**params)

    def moved(pose_and_increments):
        odometry = dd.Odometry(robot, method, dd.Pose(*pose_and_increments[:3]))
        odometry.update_increments(*pose_and_increments[3:])
        return odometry.pose.to_array()

    odometry = dd.Odometry(robot, method, dd.Pose(*pose))
    pose_jacobian, wheel_jacobian = odometry.jacobians(*increments)
    numeric = central_difference(moved, [*pose, *increments])
    np.testing.assert_allclose(pose_jacobian, numeric[:, :3], atol=1e-7)
    np.testing.assert_allclose(wheel_jacobian, numeric[:, 3:], atol=1e-7)


def test_covariance_grows_with_distance_not_with_the_update_rate():
    """k scales the variance: the same straight path in 10 or 1000 updates, same covariance."""
    coarse, fine = (dd.Odometry(ROBOT, wheel_noise=(1e-3, 2e-3)) for _ in range(2))
    for _ in range(10):
        coarse.update_increments(2.0, 2.0)
    for _ in range(1000):
        fine.update_increments(0.02, 0.02)
    # Along the path and in heading the variance adds exactly; sideways it is an integral that
    # the coarse slicing approximates.
    np.testing.assert_allclose(coarse.covariance[[0, 2], [0, 2]], fine.covariance[[0, 2], [0, 2]])
    assert coarse.covariance[1, 1] == pytest.approx(fine.covariance[1, 1], rel=0.02)
    travel = 20 * 0.05  # m per wheel
    assert fine.covariance[0, 0] == pytest.approx(0.25 * (1e-3 + 2e-3) * travel)
    assert fine.covariance[2, 2] == pytest.approx((1e-3 + 2e-3) * travel / 0.3**2)


@pytest.mark.parametrize("method", integrate.METHODS)
def test_propagated_covariance_matches_monte_carlo(method):
    """Perturb each wheel's travel by the model, integrate 4000 copies with simulate."""
    rng = np.random.default_rng(11)
    # Small enough that the heading error stays small (0.04 rad) and the linearisation holds.
    k_left, k_right, steps, copies = 2e-5, 1e-5, 200, 4000
    t = np.arange(steps) * 0.05
    increments = np.stack([0.6 + 0.3 * np.sin(t), 0.6 + 0.3 * np.cos(0.7 * t)], axis=-1)
    odometry = dd.Odometry(ROBOT, method, wheel_noise=(k_left, k_right))
    for left, right in increments:
        odometry.update_increments(left, right)
    radii = np.array([ROBOT.left_wheel_radius, ROBOT.right_wheel_radius])
    variance = np.array([k_left, k_right]) * np.abs(increments * radii) / radii**2
    noisy = increments + rng.standard_normal((copies, steps, 2)) * np.sqrt(variance)
    angles = np.concatenate([np.zeros((copies, 1, 2)), np.cumsum(noisy, axis=1)], axis=1)
    finals = dd.simulate(ROBOT, wheel_positions=angles, dt=1.0, method=method).final_pose
    sample = np.cov(finals.T)
    predicted = odometry.covariance
    scale = np.sqrt(np.outer(np.diag(predicted), np.diag(predicted)))
    # 4000 copies: the sample (co)variances scatter by about sqrt(2/4000) = 2 % of the scale.
    np.testing.assert_allclose(sample / scale, predicted / scale, atol=0.08)


# -- accepted updates never break the object (found by tests/test_stateful.py) ------------------


@pytest.mark.parametrize(
    ("calls", "message"),
    [
        (
            [("update_increments", 1e308, 1e308)],
            r"increments of 1e\+308 and 1e\+308 rad would make the",
        ),
        ([("update_increments", 1e160, 1e160)] * 2, "would make the covariance overflow"),
        ([("update_velocities", 0.0, 0.0, 1e308)] * 2, "the clock would pass the largest"),
        ([("update_increments", 10**400, 0.0)], "left must be finite, got an integer too large"),
        ([("update_increments", "1", 0.0)], "left must be a number, got '1'"),
    ],
)
def test_an_update_whose_result_is_not_finite_is_refused(calls, message):
    odometry = dd.Odometry(ROBOT, wheel_noise=1e-4)
    twin = dd.Odometry(ROBOT, wheel_noise=1e-4)
    *accepted, last = calls
    for name, *args in accepted:
        with contextlib.suppress(ValueError):
            getattr(odometry, name)(*args)
            getattr(twin, name)(*args)
    with pytest.raises((ValueError, TypeError), match=message):
        getattr(odometry, last[0])(*last[1:])
    assert odometry.pose == twin.pose
    assert odometry.time == twin.time
    np.testing.assert_array_equal(odometry.covariance, twin.covariance)
    assert np.all(np.isfinite(odometry.covariance))


def test_a_whole_run_gives_the_same_path_streamed_and_in_batch():
    """odometry_of_run (the streaming core) and simulate_run (prefix sums) on one Run, of
    velocities held from row to row and of accumulated angles."""
    from diffdrive.estimation import odometry_of_run
    from diffdrive.io import Run
    from diffdrive.simulation import simulate_run

    robot = dd.DiffDrive(0.05, 0.3, axle_offset=0.02)
    t = np.linspace(0.0, 4.0, 81)
    wheels = np.stack([6 + 3 * np.sin(t), 6 - 2 * np.cos(1.3 * t)], axis=-1)
    truth = np.tile([0.4, -0.1, 0.3], (len(t), 1))
    velocity = Run(t, "velocity", wheels, truth, "velocity log")
    angles = Run.from_increments(wheels[:-1] * np.diff(t)[:, None], truth, t, "angle log")
    for run in (velocity, angles):
        increments, note = run.checked_increments(robot)
        assert "largest wheel speed" in note
        streamed, covariances = odometry_of_run(robot, run, covariance=True)
        assert covariances.shape == (len(t), 3, 3)
        np.testing.assert_allclose(streamed[0], truth[0])
        np.testing.assert_allclose(streamed, simulate_run(robot, run, increments), atol=1e-12)


def test_a_run_faster_than_any_robot_is_refused_by_its_line():
    from diffdrive.io import Run, TableError

    run = Run(np.arange(3.0), "angle", np.array([[0, 0], [1, 1], [5000, 5000.0]]), None, "fast")
    with pytest.raises(TableError, match="fast, row 3: the left wheel would turn at 4999"):
        run.checked_increments(dd.DiffDrive(0.05, 0.3))
    run.checked_increments(dd.DiffDrive(0.05, 0.3), max_wheel_speed=1e4)  # the user's limit


def test_update_arrays_names_its_time_arguments():
    """Time stamps are t for readings and increments, dt for velocities: the other is refused
    by name, and the velocities held for dt move as update_velocities does."""
    robot = dd.DiffDrive(0.05, 0.3)
    odometry, one = dd.Odometry(robot), dd.Odometry(robot)
    with pytest.raises(ValueError, match="velocities updates take dt, not t"):
        odometry.update_arrays("velocities", [1.0], [2.0], [0.1])
    with pytest.raises(ValueError, match="increments updates take t, not dt"):
        odometry.update_arrays("increments", [1.0], [2.0], dt=[0.1])
    with pytest.raises(ValueError, match="dt must have 2 values, got 1"):
        odometry.update_arrays("velocities", [1.0, 1.0], [2.0, 2.0], dt=[0.1])
    poses, _ = odometry.update_arrays("velocities", [1.0, 3.0], [2.0, 1.0], dt=[0.1, 0.2])
    one.update_velocities(1.0, 2.0, 0.1)
    one.update_velocities(3.0, 1.0, 0.2)
    np.testing.assert_array_equal(poses[-1], one.pose.to_array())
    assert odometry.time == pytest.approx(0.3)
