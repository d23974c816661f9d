"""Dynamic simulation: commands through a drive model, worked by hand, batched, refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.dynamics import DriveModel, Feedforward, simulate_commands

T = np.arange(0, 101) * 0.01  # s


def test_a_velocity_step_through_delay_and_lag_is_the_exponential() -> None:
    model = DriveModel(delay=0.05, time_constant=0.1, gain=0.9)
    wheels = model.wheel_velocities(T, [0.0], [[10.0, -4.0]])
    late = np.clip(T - 0.05, 0.0, None)
    expected = 0.9 * (1.0 - np.exp(-late / 0.1))
    np.testing.assert_allclose(wheels[:, 0], 10.0 * expected, atol=1e-12)
    np.testing.assert_allclose(wheels[:, 1], -4.0 * expected, atol=1e-12)


def test_an_acceleration_limit_makes_a_ramp() -> None:
    wheels = DriveModel(max_acceleration=20.0).wheel_velocities(T, [0.0], [[10.0, 10.0]])
    np.testing.assert_allclose(wheels[:, 0], np.minimum(20.0 * T, 10.0), atol=1e-12)


def test_a_voltage_driven_wheel_worked_by_hand() -> None:
    ff = Feedforward(ks=1.0, kv=0.5, ka=0.05)  # target (V - kS) / kV, time constant kA / kV
    model = DriveModel(feedforward=ff)
    wheels = model.wheel_velocities(T, [0.0], [[6.0, 0.5]])
    np.testing.assert_allclose(wheels[:, 0], 10.0 * (1.0 - np.exp(-T / 0.1)), atol=1e-12)
    assert np.all(wheels[:, 1] == 0.0)  # 0.5 V does not overcome kS: static friction holds
    # Reversing: from 5 rad/s with -6 V the wheel slows toward (-6 - 1) / 0.5 = -14 rad/s
    # (kS against the forward motion), stops at zero in the step where it would cross, then
    # turns the other way toward (-6 + 1) / 0.5 = -10 rad/s.
    back = model.wheel_velocities(T, [0.0], [[-6.0, -6.0]], initial=[5.0, 5.0])[:, 0]
    crossing = 0.1 * math.log((5.0 + 14.0) / 14.0)  # s
    before = np.less(T, crossing)
    np.testing.assert_allclose(back[before], -14 + 19 * np.exp(-T[before] / 0.1))
    assert back[np.searchsorted(T, crossing)] == 0.0
    assert back[-1] == pytest.approx(-10.0, abs=1e-3)


def test_a_batch_is_its_robots_each_alone() -> None:
    rng = np.random.default_rng(2)
    commands = rng.uniform(-10, 10, (3, 4, 2, 2))  # 3 x 4 robots, 2 stamps
    stamps = [0.0, 0.4]
    for model in (
        DriveModel(0.03, 0.08, 1.1, 50.0),
        DriveModel(feedforward=Feedforward(1, 0.5, 0.05)),
    ):
        many = model.wheel_velocities(T, stamps, commands)
        assert many.shape == (3, 4, len(T), 2)
        for index in np.ndindex(3, 4):
            np.testing.assert_allclose(
                many[index], model.wheel_velocities(T, stamps, commands[index])
            )


def test_simulate_commands_drives_the_pose_the_wheels_travel() -> None:
    robot = dd.DiffDrive(wheel_radius=0.1, track_width=0.5)
    model = DriveModel(delay=0.02, time_constant=0.1)
    run = simulate_commands(robot, model, [0.0], [[10.0, 10.0]], dt=0.001, duration=1.0)
    # Straight ahead: x = r * integral of the lagged velocity (the trapezoid's error ~ dt^2).
    late = max(1.0 - 0.02, 0.0)
    travel = 0.1 * 10.0 * (late - 0.1 * (1.0 - math.exp(-late / 0.1)))
    assert run.poses[-1, 0] == pytest.approx(travel, abs=1e-6)
    assert run.poses[-1, 1:] == pytest.approx([0.0, 0.0], abs=1e-12)
    turning = simulate_commands(robot, model, [0.0, 0.5], [[5.0, 10.0], [10.0, 5.0]], dt=0.01)
    assert turning.wheel_velocities.shape == (len(turning.times) - 1, 2)
    # The delay and lag carry the command past its last stamp: five time constants and more.
    assert turning.times[-1] >= 0.5 + 0.02 + 0.5


def test_from_an_identified_response() -> None:
    response = dd.dynamics.VelocityResponse(0.04, 0.12, 0.95, 30.0, np.eye(2), 0.0)
    model = DriveModel.from_response(response)
    commands = np.array([[8.0, 4.0], [2.0, 9.0]])
    np.testing.assert_allclose(
        model.wheel_velocities(T, [0.0, 0.5], commands),
        response.predict(T, [0.0, 0.5], commands, [0.0, 0.0]),
    )


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: DriveModel(delay=-0.1), "delay must be >= 0"),
        (lambda: DriveModel(feedforward=Feedforward(1.0, 0.0, 0.1)), "kV > 0"),
        (lambda: DriveModel(gain=0.0), "gain must be > 0"),
        (lambda: Feedforward(1.0, np.nan, 0.1), "kv must be finite"),
        (
            lambda: DriveModel().wheel_velocities(T, [0.0, 1.0], [[1.0, 1.0]]),
            r"commands must be \(\.\.\., 2, 2\)",
        ),
        (lambda: DriveModel().wheel_velocities(T[::-1], [0.0], [[1.0, 1.0]]), "increasing"),
        (lambda: DriveModel().wheel_velocities(T, [0.0], [[np.nan, 1.0]]), "must be finite"),
    ],
)
def test_bad_models_and_commands_are_refused_by_name(make, message) -> None:
    with pytest.raises(ValueError, match=message):
        make()


@pytest.mark.parametrize(
    "model",
    [
        DriveModel(time_constant=0.12, gain=0.9),
        DriveModel(time_constant=0.05, max_acceleration=40.0),
        DriveModel(feedforward=Feedforward(0.3, 0.2, 0.03)),
    ],
    ids=["lag and gain", "acceleration limit", "voltage-driven"],
)
def test_a_step_a_period_is_the_whole_history_model(model) -> None:
    """DriveModel.step, period by period with the commands held (what follow does), ends each
    period where wheel_velocities puts the wheels at that time; a voltage-driven model's step
    takes velocities and applies their steady voltage (kS sgn v + kV v)."""
    dt = 0.02
    times = np.arange(0, 101) * dt
    commands = np.column_stack([8 * np.sin(times[:-1] * 2), -5 + 0 * times[:-1]])
    ff = model.feedforward
    applied = commands if ff is None else ff.voltage(commands)
    want = model.wheel_velocities(times, times[:-1], applied)
    wheels, ends = np.zeros(2), [np.zeros(2)]
    for command in commands:
        wheels, _ = model.step(wheels, command, dt)
        ends.append(wheels)
    np.testing.assert_allclose(np.array(ends), want, rtol=1e-12, atol=1e-12)
