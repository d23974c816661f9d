"""Commands: desaturation, the limiter, the timeout, and open-loop odometry."""

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import diffdrive as dd
from strategies import geometry

ROBOT = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
wheel_pairs = st.tuples(*[st.floats(-100, 100)] * 2)


# -- desaturate ------------------------------------------------------------------------------


@given(wheel_pairs, st.floats(0.1, 50))
def test_desaturate_keeps_the_limit_and_the_curvature(wheels, limit):
    out = dd.desaturate(dd.WheelVelocities(*wheels), limit)
    assert max(abs(out.left), abs(out.right)) <= limit
    # Same direction in the wheel plane: the twist, hence the path's curvature, is kept.
    assert out.left * wheels[1] - out.right * wheels[0] == pytest.approx(0.0, abs=1e-9)
    if max(map(abs, wheels)) <= limit:
        assert out == dd.WheelVelocities(*wheels)


@pytest.mark.slow
@given(geometry(), wheel_pairs, st.floats(1.0, 50), st.sampled_from(["omega", "v"]))
@settings(max_examples=200)
def test_desaturate_keeping_omega_or_v(params, wheels, limit, keep):
    robot = dd.DiffDrive(**{**params, "axle_offset": 0.0})
    before = robot.to_twist(dd.WheelVelocities(*wheels))
    out = dd.desaturate(dd.WheelVelocities(*wheels), limit, keep, robot)
    assert max(abs(out.left), abs(out.right)) <= limit
    after = robot.to_twist(out)
    radius = min(robot.left_wheel_radius, robot.right_wheel_radius)
    half = robot.track_width / 2
    kept, reach = (after.omega, before.omega), 2 * limit * radius / robot.track_width
    if keep == "v":
        kept, reach = (after.vx, before.vx), limit * radius
    if abs(kept[1]) <= reach * (1 - 1e-9) and keep == "v":
        assert kept[0] == pytest.approx(kept[1], abs=1e-9)
    if keep == "omega" and abs(before.omega) * half <= limit * radius * (1 - 1e-9):
        assert after.omega == pytest.approx(before.omega, abs=1e-9)


def test_desaturate_arrays_and_bad_input():
    out = dd.desaturate(np.array([[20.0, 10.0], [1.0, 2.0]]), 10.0)
    np.testing.assert_allclose(out, [[10.0, 5.0], [1.0, 2.0]])
    with pytest.raises(ValueError, match="max_wheel_velocity must be > 0, got -1"):
        dd.desaturate(dd.WheelVelocities(1, 2), -1)
    with pytest.raises(ValueError, match="keep='omega' needs the robot"):
        dd.desaturate(dd.WheelVelocities(1, 2), 1, "omega")
    with pytest.raises(ValueError, match="wheels must be finite, got nan"):
        dd.desaturate(np.array([1.0, math.nan]), 1.0)


# -- the limiter -----------------------------------------------------------------------------


def test_reaching_a_target_takes_the_minimum_time():
    """From rest to 1.5 m/s at 1 m/s^2: 1.5 s, 15 steps of 0.1 s, not one more or less."""
    limiter = dd.Limiter((dd.Limits(max_velocity=2.0, max_acceleration=1.0),))
    values = [limiter.step([1.5], 0.1)[0] for _ in range(20)]
    np.testing.assert_allclose(values[:15], np.arange(1, 16) * 0.1)
    assert values[14:] == [1.5] * 6


def test_through_zero_it_slows_down_then_speeds_up_the_other_way():
    limits = dd.Limits(max_acceleration=1.0, max_deceleration=2.0, max_reverse_acceleration=0.5)
    limiter = dd.Limiter((limits,))
    limiter.reset([0.3])
    # 0.15 s to rest at 2 m/s^2, then 0.05 s backward at 0.5 m/s^2.
    assert limiter.step([-1.0], 0.2)[0] == pytest.approx(-0.025)


def test_with_jerk_the_acceleration_is_a_trapezoid():
    limiter = dd.Limiter((dd.Limits(max_acceleration=1.0, max_jerk=4.0),))
    accelerations = []
    for _ in range(40):
        limiter.step([1.5], 0.05)
        accelerations.append(limiter.acceleration[0])
    ramp = [0.2, 0.4, 0.6, 0.8]
    expected = [*ramp, *[1.0] * 26, *ramp[::-1], *[0.0] * 6]
    np.testing.assert_allclose(accelerations, expected, atol=1e-9)
    assert limiter.value[0] == pytest.approx(1.5)


limit_values = st.floats(0.1, 10.0)


@given(
    st.tuples(*[limit_values] * 6),
    st.lists(st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(0.01, 0.2)), max_size=60),
)
@settings(max_examples=100)
def test_no_limit_is_ever_exceeded(limits, stream):
    v_fwd, v_rev, acc, dec, acc_rev, dec_rev = limits
    channel = dd.Limits(v_fwd, v_rev, acc, dec, acc_rev, dec_rev)
    limiter = dd.Limiter((channel, dd.Limits(max_velocity=3.0, max_acceleration=2.0)))
    for v, omega, dt in stream:
        before = limiter.value.copy()
        after = limiter.step([v, omega], dt)
        change = (after - before) / dt
        tolerance = 1e-9
        assert -v_rev - tolerance <= after[0] <= v_fwd + tolerance
        assert abs(after[1]) <= 3.0 + tolerance
        assert abs(change[1]) <= 2.0 + tolerance
        # Speeding up or slowing down, forward or backward; a crossing mixes two limits.
        assert abs(change[0]) <= max(acc, dec, acc_rev, dec_rev) + tolerance
        if before[0] >= 0 and after[0] >= 0:
            assert change[0] <= acc + tolerance
            assert -change[0] <= dec + tolerance
        if before[0] <= 0 and after[0] <= 0:
            assert -change[0] <= acc_rev + tolerance
            assert change[0] <= dec_rev + tolerance


@pytest.mark.slow
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), min_size=1, max_size=40))
@settings(max_examples=50)
@example(
    [
        (1.0, 0.0),
        (0.0, 0.0),
        (0.0, 0.0),
        (-1.0, 0.0),
        (0.0, 0.0),
        (0.0, 1.0),
        (0.0, 0.0),
        (1.0, 0.0),
        (-1.0, 0.0),
    ]
)  # at rest, pushed away from -1: it stays
def test_with_jerk_no_limit_is_exceeded(stream):
    limits = dd.Limits(max_velocity=4.0, max_acceleration=2.0, max_jerk=10.0)
    limiter = dd.Limiter((limits, limits))
    for target in stream:
        before, moving = limiter.acceleration.copy(), limiter.value.copy()
        value = limiter.step(target, 0.02)
        assert np.all(np.abs(value) <= 4.0 + 1e-9)
        assert np.all(np.abs(limiter.acceleration) <= 2.0 + 1e-9)
        # The jerk limit holds but where a channel stops at rest rather than carry on past it
        # away from its target, or stays at rest rather than leave it away from a target (the
        # documented exception): there it ends exactly at rest.
        jerked = np.abs(limiter.acceleration - before) > 10.0 * 0.02 + 1e-9
        goal = np.asarray(target)
        held = np.where(moving == 0.0, goal != 0.0, np.sign(goal) != -np.sign(moving))
        stopped = (value == 0.0) & held
        assert np.all(~jerked | stopped)
    for _ in range(300):  # and it settles on the last target
        limiter.step(None, 0.02)
    last = np.array(stream[-1])
    expected = last * min(1.0, 4.0 / max(np.abs(last).max(), 1e-300))  # one scale: curvature
    np.testing.assert_allclose(limiter.value, expected, atol=1e-9)


def test_a_twist_from_rest_keeps_its_curvature():
    limiter = dd.Limiter.for_twist(
        dd.Limits(max_velocity=1.0, max_acceleration=0.5), dd.Limits(max_acceleration=3.0)
    )
    for _ in range(50):
        v, omega = limiter.step([2.0, 1.0], 0.05)  # velocity-limited to (1.0, 0.5)
        assert omega == pytest.approx(0.5 * v)
    assert limiter.value.tolist() == pytest.approx([1.0, 0.5])


def test_the_timeout_brings_the_robot_to_rest_within_the_limits():
    limiter = dd.Limiter.for_wheels(dd.Limits(max_acceleration=10.0), timeout=0.5)
    limiter.reset([8.0, 4.0])
    values = [limiter.step(None, 0.1) for _ in range(20)]
    np.testing.assert_allclose(values[3], [8.0, 4.0])  # 0.4 s: still the last command
    np.testing.assert_allclose(values[4], [7.0, 3.5])  # 0.5 s: stopping at 10 rad/s^2
    np.testing.assert_allclose(values[-1], [0.0, 0.0])
    assert np.all(np.abs(np.diff(values, axis=0)) <= 1.0 + 1e-12)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: dd.Limits(max_velocity=-1.0), "max_velocity must be >= 0"),
        (lambda: dd.Limits(max_acceleration=math.nan), "max_acceleration must be > 0"),
        (lambda: dd.Limits(max_jerk=0.0), "max_jerk must be > 0"),
        (lambda: dd.Limits(max_reverse_velocity=-0.1), "max_reverse_velocity must be >= 0"),
        (lambda: dd.Limiter((dd.Limits(),), timeout=-1), "timeout must be > 0"),
    ],
)
def test_bad_limits_are_refused(make, message):
    with pytest.raises(ValueError, match=message):
        make()


@pytest.mark.parametrize(
    ("target", "dt", "message"),
    [
        ([math.nan, 0.0], 0.1, "target must be finite"),
        ([1.0, 0.0], 0.0, "dt must be finite and > 0, got 0.0"),
        ([1.0, 0.0], -0.1, "dt must be finite and > 0"),
        ([1.0], 0.1, r"target must have shape \(2,\)"),
    ],
)
def test_a_bad_step_is_refused_and_changes_nothing(target, dt, message):
    limiter = dd.Limiter.for_wheels(dd.Limits(max_acceleration=1.0), timeout=1.0)
    limiter.step([1.0, 2.0], 0.5)
    before = (limiter.value.copy(), limiter.acceleration.copy(), limiter._since_target)
    with pytest.raises(ValueError, match=message):
        limiter.step(target, dt)
    np.testing.assert_array_equal(limiter.value, before[0])
    np.testing.assert_array_equal(limiter.acceleration, before[1])
    assert limiter._since_target == before[2]


# -- open-loop odometry ------------------------------------------------------------------------


def limiter():
    return dd.Limiter.for_twist(
        dd.Limits(max_velocity=0.8, max_acceleration=0.5, max_deceleration=1.0),
        dd.Limits(max_velocity=2.0, max_acceleration=2.0),
        timeout=0.5,
    )


def test_streaming_open_loop_equals_the_batch_version():
    t = np.arange(400) * 0.02
    commands = np.stack([0.6 + 0.4 * np.sin(t), 1.5 * np.cos(0.5 * t)], axis=-1)
    commands[300:] = np.nan  # no commands for the last 2 s: the timeout stops the robot
    stream = dd.OpenLoopOdometry(ROBOT, limiter(), max_wheel_velocity=15.0)
    for row in commands:
        stream.update(None if np.isnan(row).all() else row, 0.02)
    batch = dd.drive_commands(ROBOT, commands, 0.02, limiter(), max_wheel_velocity=15.0)
    np.testing.assert_allclose(stream.pose.to_array(), batch.final_pose, atol=1e-9)
    assert np.all(np.abs(batch.wheel_velocities) <= 15.0)
    np.testing.assert_allclose(batch.wheel_velocities[-1], [0.0, 0.0])


def test_drive_commands_refuses_a_half_missing_row():
    commands = np.array([[0.1, 0.0], [math.nan, 0.2]])
    with pytest.raises(ValueError, match="commands row 1 is not finite"):
        dd.drive_commands(ROBOT, commands, 0.1, limiter())


def test_wheel_commands_and_a_bad_kind():
    wheels = dd.Limiter.for_wheels(dd.Limits(max_velocity=10.0))
    stream = dd.OpenLoopOdometry(ROBOT, wheels, "wheels")
    applied = [stream.update([12.0, 6.0], 0.1) for _ in range(10)]
    assert applied[-1] == dd.WheelVelocities(10.0, 5.0)  # one scale: the curvature is kept
    expected = dd.simulate(ROBOT, np.tile([10.0, 5.0], (10, 1)), dt=0.1).final_pose
    np.testing.assert_allclose(stream.pose.to_array(), expected, atol=1e-12)
    with pytest.raises(ValueError, match="kind must be 'twist' or 'wheels', got 'speed'"):
        dd.OpenLoopOdometry(ROBOT, wheels, "speed")


def test_with_jerk_on_every_channel_a_twist_from_rest_keeps_its_curvature():
    limiter = dd.Limiter.for_twist(
        dd.Limits(max_velocity=1.0, max_acceleration=0.5, max_jerk=2.0),
        dd.Limits(max_acceleration=3.0, max_jerk=20.0),
    )
    accelerations = []
    for _ in range(100):
        v, omega = limiter.step([2.0, 1.0], 0.05)  # velocity-limited to (1.0, 0.5)
        assert omega == pytest.approx(0.5 * v, abs=1e-12)
        accelerations.append(limiter.acceleration[0])
    assert limiter.value.tolist() == pytest.approx([1.0, 0.5])
    # The forward channel is the tighter one: its acceleration ramps at 2 m/s^3 to 0.5 m/s^2.
    np.testing.assert_allclose(accelerations[:5], [0.1, 0.2, 0.3, 0.4, 0.5], atol=1e-12)
    assert max(np.abs(np.diff(accelerations))) <= 2.0 * 0.05 + 1e-12
    wheels = dd.desaturate(ROBOT.to_wheel_velocities(dd.Twist(v, 0.0, omega)), 5.0)
    assert ROBOT.to_twist(wheels).omega == pytest.approx(0.5 * ROBOT.to_twist(wheels).vx)


# -- found by the stateful fuzz campaign (tests/test_stateful.py) -------------------------------


def test_a_jerk_profile_never_runs_past_the_velocity_limit():
    limiter = dd.Limiter((dd.Limits(), dd.Limits(max_reverse_velocity=2.0, max_jerk=33.0)))
    outputs = [limiter.step([0.0, -5.0], 0.125) for _ in range(12)]
    outputs += [limiter.step([0.0, 0.0], 0.125) for _ in range(12)]
    assert min(out[1] for out in outputs) >= -2.0


def test_finite_targets_give_finite_outputs_or_are_refused_with_nothing_changed():
    limiter = dd.Limiter((dd.Limits(),))
    limiter.step([-1e308], 1.0)
    with pytest.raises(ValueError, match="would overflow to infinity; refused, nothing changed"):
        limiter.step([1e308], 1.0)
    assert limiter.value.tolist() == [-1e308]
    assert np.all(np.isfinite(limiter.step([0.0], 1.0)))
    with pytest.raises(ValueError, match="target must be finite, got an integer too large"):
        limiter.step([10**400], 1.0)


def test_a_refused_open_loop_update_changes_neither_the_limiter_nor_the_pose():
    robot = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
    open_loop = dd.OpenLoopOdometry(robot, dd.Limiter.for_twist(dd.Limits(), dd.Limits()))
    open_loop.update([0.5, 0.1], 0.1)
    before = (open_loop._path.limiter.value.copy(), open_loop.pose)
    with pytest.raises(ValueError, match="must be finite"):
        open_loop.update([1e300, 0.0], 1e300)
    np.testing.assert_array_equal(open_loop._path.limiter.value, before[0])
    assert open_loop.pose == before[1]


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: dd.Limits(max_velocity=10**400), "max_velocity must be finite, got an integer"),
        (lambda: dd.Limits(max_jerk="3"), "max_jerk must be a number, got '3'"),
        (lambda: dd.Limiter((dd.Limits(),)).step([1.0], "0.1"), "dt must be a number"),
    ],
)
def test_limits_name_the_parameter_of_a_bad_number(make, message):
    with pytest.raises((ValueError, TypeError), match=message):
        make()


@pytest.mark.parametrize(
    "limits",
    [
        dd.Limits(max_velocity=1.0, max_acceleration=2.0, max_deceleration=3.0),
        dd.Limits(max_velocity=1.0, max_reverse_velocity=0.5, max_acceleration=2.0, max_jerk=8.0),
    ],
    ids=["acceleration", "jerk"],
)
def test_a_batched_limiter_limits_each_row_as_its_own_would(limits) -> None:
    rng = np.random.default_rng(7)
    template = dd.Limiter.for_wheels(limits, timeout=0.1)
    many = template.batched(5)
    singles = [dd.Limiter.for_wheels(limits, timeout=0.1) for _ in range(5)]
    for k in range(120):
        targets = None if k % 17 == 16 else rng.uniform(-1.5, 1.5, (5, 2))
        out = many.step(targets, 0.02)
        for n, single in enumerate(singles):
            expected = single.step(None if targets is None else targets[n], 0.02)
            np.testing.assert_allclose(out[n], expected, rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match=r"target must have shape \(5, 2\)"):
        many.step([0.1, 0.2], 0.02)


@pytest.mark.slow
@given(
    st.lists(st.sampled_from([-1.0, 0.0, 0.5, 1.0]), min_size=1, max_size=60),
    st.sampled_from([2.0, 8.0, 32.0]),
    st.sampled_from([0.01, 0.02, 0.03125]),
)
@settings(max_examples=200)
def test_with_jerk_the_reverse_acceleration_holds_and_rest_is_not_left_the_wrong_way(
    targets, jerk, dt
):
    """A jerk-limited channel whose acceleration was left pointing backward by a target that
    changed neither speeds up in reverse beyond max_reverse_acceleration (it did: 0 to
    -0.00785 in 0.03125 s, 0.2512 > 0.25) nor leaves rest away from a target ahead of it."""
    limits = dd.Limits(
        max_velocity=2.0, max_acceleration=1.0, max_reverse_acceleration=0.25, max_jerk=jerk
    )
    limiter = dd.Limiter((limits,))
    for target in targets:
        before = float(limiter.value[0])
        after = float(limiter.step([target], dt)[0])
        if before <= 0.0 and after < 0.0:
            assert (before - after) / dt <= 0.25 * (1 + 1e-9)
        if before == 0.0 and target != 0.0:
            assert after * target >= 0.0  # not away from the target
