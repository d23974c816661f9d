"""WheelNoise: one type, one default for every estimator, none for every simulator, one draw."""

from __future__ import annotations

import inspect
import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import sensor_noise
from diffdrive.control import FollowSettings
from diffdrive.estimation import EstimatorSettings, GyroOdometry, PoseEstimator, estimate_trajectory
from diffdrive.estimation.odometry import odometry_of_run
from diffdrive.montecarlo import monte_carlo
from diffdrive.sensor_noise import DEFAULT, NONE, WheelNoise, draw_geometry, draw_travel
from diffdrive.sensors import EncoderModel


def test_a_number_is_both_wheels_and_a_pair_is_left_then_right():
    assert WheelNoise.coerce(2e-4) == WheelNoise(2e-4, 2e-4) == WheelNoise.symmetric(2e-4)
    assert WheelNoise.coerce((1e-4, 3e-4)) == WheelNoise(1e-4, 3e-4)
    assert WheelNoise.coerce(np.array([1e-4, 3e-4])).right == 3e-4
    assert WheelNoise.coerce(DEFAULT) is DEFAULT
    np.testing.assert_array_equal(WheelNoise(1.0, 2.0).k, [1.0, 2.0])
    assert not NONE
    assert WheelNoise(0.0, 1e-9)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (-1e-4, "wheel noise left must be a number >= 0 m, got -0.0001"),
        ((0.0, math.nan), "wheel noise right must be finite"),
        ((1e-4, math.inf), "wheel noise right must be finite"),
        ((1e300, 0.0), "wheel noise left 1e\\+300 m is past any wheel's"),
        ((1e-4, 1e-4, 1e-4), "a pair \\(left, right\\), got \\(0.0001, 0.0001, 0.0001\\)"),
        ("1e-4", "wheel_noise must be a WheelNoise"),
        (True, "wheel_noise must be a WheelNoise"),
    ],
)
def test_bad_noise_is_refused_by_name(value, message):
    with pytest.raises(ValueError, match=message):
        WheelNoise.coerce(value)


def _default(function, name="wheel_noise"):
    return inspect.signature(function).parameters[name].default


def test_every_estimator_assumes_the_one_default_and_every_simulator_none():
    assert WheelNoise(1e-4, 1e-4) == DEFAULT
    # Odometry's signature says None (the default loads with its first robot, not with
    # diffdrive); the value it takes is DEFAULT.
    assert _default(dd.Odometry.__init__) is None
    assert _default(odometry_of_run) is None
    # The estimators take theirs from EstimatorSettings, whose default is None: a whole log
    # with a gyro identifies it, and everything else takes DEFAULT (``wheels``).
    assert EstimatorSettings().wheel_noise is None
    assert EstimatorSettings().wheels is DEFAULT
    assert PoseEstimator(dd.DiffDrive(0.05, 0.3)).config.k == (DEFAULT.left, DEFAULT.right)
    assert GyroOdometry(dd.DiffDrive(0.05, 0.3)).config.k == (DEFAULT.left, DEFAULT.right)
    assert dd.Odometry(dd.DiffDrive(0.05, 0.3)).wheel_noise is DEFAULT
    assert "wheel_noise" not in inspect.signature(estimate_trajectory).parameters  # its settings
    assert _default(monte_carlo) is NONE
    assert FollowSettings().wheel_noise is NONE  # follow's simulated fleet
    assert EncoderModel().wheel_noise == NONE


def test_the_draw_has_the_variance_k_times_the_travel():
    rng = np.random.default_rng(0)
    travel = np.tile([[0.2, -0.05]], (200_000, 1))  # m, left and right
    k = np.array([1e-4, 4e-4])
    noise = draw_travel(travel, k, rng)
    np.testing.assert_allclose(noise.var(axis=0), k * np.abs(travel[0]), rtol=0.02)
    assert abs(noise.mean(axis=0) / np.sqrt(k * np.abs(travel[0]))).max() < 0.02
    assert draw_travel(np.zeros((3, 2)), k, rng).tolist() == [[0.0, 0.0]] * 3


def test_the_geometry_draw_spreads_each_by_its_relative_sigma_and_refuses_a_negative_robot():
    rng = np.random.default_rng(1)
    nominal, sigma = np.array([0.05, 0.051, 0.3]), np.array([0.01, 0.02, 0.005])
    drawn = draw_geometry(nominal, sigma, 100_000, rng)
    np.testing.assert_allclose(drawn.mean(axis=0), nominal, rtol=1e-3)
    np.testing.assert_allclose(drawn.std(axis=0) / nominal, sigma, rtol=0.02)
    np.testing.assert_array_equal(draw_geometry(nominal, np.zeros(3), 2, rng), [nominal] * 2)
    with pytest.raises(ValueError, match="geometry_sigma draws a radius or track <= 0"):
        draw_geometry(nominal, np.array([2.0, 0.0, 0.0]), 1000, rng)


def test_odometry_and_the_monte_carlo_of_the_same_noise_agree():
    """The covariance Odometry predicts with a WheelNoise is the spread monte_carlo draws
    with it: one meaning of the value for the estimator and the simulator."""
    robot, noise = dd.DiffDrive(0.05, 0.3), WheelNoise(1e-4, 3e-4)
    wheels = np.tile([8.0, 9.0], (100, 1))
    spread = monte_carlo(robot, wheels, 0.02, 20_000, wheel_noise=noise, seed=3, backend="numpy")
    odometry = dd.Odometry(robot, wheel_noise=noise)
    _, covariances = odometry.update_arrays(
        "velocities", wheels[:, 0], wheels[:, 1], dt=np.full(100, 0.02), covariance=True
    )
    np.testing.assert_allclose(spread.covariance[-1], covariances[-1], rtol=0.05, atol=1e-9)
    assert sensor_noise.DEFAULT is DEFAULT


def test_one_gyro_noise_for_the_estimators_the_synthetic_gyro_and_the_allan_fit():
    """The estimators assume DEFAULT_GYRO (a mid-range MEMS gyro), the synthetic gyro draws
    none unless given one, and identify_gyro hands back the same type."""
    from diffdrive import sensors
    from diffdrive.calibration.noise import identify_gyro
    from diffdrive.sensor_noise import DEFAULT_GYRO, GyroNoise

    assert PoseEstimator(dd.DiffDrive(0.05, 0.3)).settings.gyro is DEFAULT_GYRO
    assert GyroNoise(2e-3, 1e-4, 5e-3) == DEFAULT_GYRO
    assert sensors.GyroModel().noise == GyroNoise()
    assert GyroNoise() == GyroNoise(0.0, 0.0, 0.0, 0.0, 100.0)  # made without arguments: none
    t = np.arange(0, 600, 0.01)
    model = sensors.GyroModel(noise=GyroNoise(angle_random_walk=3e-3))
    rates = sensors.gyro_readings(dd.DiffDrive(0.05, 0.3), t, np.zeros((len(t), 3)), model, seed=1)
    found = identify_gyro(t, rates.rates[0])
    assert isinstance(found.noise, GyroNoise)
    assert found.noise.angle_random_walk == pytest.approx(3e-3, rel=0.1)  # (accuracy: test_noise)


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"angle_random_walk": -1e-3}, "angle_random_walk must be >= 0"),
        ({"rate_random_walk": math.nan}, "rate_random_walk must be finite"),
        ({"initial_bias_sigma": 1e200}, "initial_bias_sigma 1e\\+200 squares past"),
        ({"correlation_time": 0.0}, "correlation_time must be > 0"),
    ],
)
def test_bad_gyro_noise_is_refused_by_name(fields, message):
    from diffdrive.sensor_noise import GyroNoise

    with pytest.raises(ValueError, match=message):
        GyroNoise(**fields)
