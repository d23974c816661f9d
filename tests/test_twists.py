"""diffdrive.estimation.twists: each interval's body twist and its covariance, by hand, against
forward kinematics for every robot model, and against the noise it comes from."""

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import batch
from diffdrive.estimation import EstimatorSettings, Gyro, estimate_trajectory
from diffdrive.estimation.twists import interval_twists

ROBOT = dd.DiffDrive(wheel_radius=0.1, track_width=0.5)


def test_one_interval_by_hand():
    """Wheels turn 1 and 2 rad in 0.5 s: arcs 0.1 and 0.2 m, k = 1e-3 m."""
    twists, covariances = interval_twists(ROBOT, [0.0, 0.5], [[1.0, 2.0]], 1e-3)
    np.testing.assert_allclose(twists, [[0.3, 0.0, 0.4]] * 2)
    # var f = (1e-4 + 2e-4) / 4, var w = 3e-4 / 0.25, cov(f, w) = (2e-4 - 1e-4) / (2 * 0.5),
    # each over dt^2 = 0.25.
    expected = np.array([[3e-4, 0.0, 4e-4], [0.0, 0.0, 0.0], [4e-4, 0.0, 4.8e-3]])
    np.testing.assert_allclose(covariances, [expected] * 2, rtol=1e-12, atol=1e-18)


@pytest.mark.parametrize(
    "robot",
    [
        ROBOT,
        dd.DiffDrive(
            left_wheel_radius=0.05, right_wheel_radius=0.052, track_width=0.3, axle_offset=0.1
        ),
        dd.SkidSteer(0.11, 0.45, -0.40, icr_x=0.03),
    ],
    ids=["diffdrive", "offset", "skid-steer"],
)
def test_the_wheels_twist_is_forward_kinematics_for_every_model(robot):
    rng = np.random.default_rng(1)
    times = np.cumsum(rng.uniform(0.01, 0.05, 40))
    increments = rng.uniform(-0.5, 1.0, (39, 2))
    twists, covariances = interval_twists(robot, times, increments, (1e-4, 2e-4))
    expected = batch.to_twist(robot, increments) / np.diff(times)[:, None]
    np.testing.assert_allclose(twists[1:], expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(twists[0], twists[1])
    assert np.all(np.linalg.eigvalsh(covariances) > -1e-15)


def test_the_covariance_is_the_noise_it_comes_from():
    """Each wheel's travel drawn with variance k |travel|: the twists' sample covariance."""
    robot = dd.SkidSteer(0.11, 0.45, -0.40, icr_x=0.03)
    increments = np.array([[0.8, 1.3]])
    _, covariances = interval_twists(robot, [0.0, 0.1], increments, (1e-3, 3e-3))
    rng = np.random.default_rng(2)
    arcs = increments[0] * np.array([robot.left_wheel_radius, robot.right_wheel_radius])
    noise = rng.standard_normal((200_000, 2)) * np.sqrt(np.array([1e-3, 3e-3]) * np.abs(arcs))
    drawn = increments + noise / np.array([robot.left_wheel_radius, robot.right_wheel_radius])
    sample = np.cov((batch.to_twist(robot, drawn) / 0.1).T)
    np.testing.assert_allclose(sample, covariances[1], rtol=0.02, atol=1e-9)


def test_a_known_turn_scale_adds_nothing_to_a_huge_turn():
    """A wheel spun 1e300 rad (a glitch the estimator still integrates, spinning in place): a
    turn scale of zero variance adds zero, not 0 * inf = NaN."""
    _, covariances = interval_twists(ROBOT, [0.0, 0.1], [[1e300, -1e300]], 1e-4)
    assert np.all(np.isfinite(covariances))


def test_a_turn_from_elsewhere_and_a_turn_scale():
    times, increments = np.array([0.0, 0.2, 0.4]), np.array([[1.0, 1.2], [1.0, 1.0]])
    twists, covariances = interval_twists(
        ROBOT, times, increments, 1e-4, turns=[0.05, -0.01], turn_variances=[1e-6, 2e-6]
    )
    np.testing.assert_allclose(twists[1:, 2], [0.25, -0.05])
    np.testing.assert_allclose(covariances[1:, 2, 2], [1e-6 / 0.04, 2e-6 / 0.04])
    np.testing.assert_array_equal(covariances[:, 0, 2], 0.0)  # another sensor's turn
    scaled, spread = interval_twists(
        ROBOT, times, increments, 0.0, turn_scale=1.1, turn_scale_variances=0.01
    )
    wheel_turn = 0.1 * 0.2 / 0.5  # rad, the first interval's
    assert scaled[1, 2] == pytest.approx(1.1 * wheel_turn / 0.2)
    assert spread[1, 2, 2] == pytest.approx(wheel_turn**2 * 0.01 / 0.04)
    with pytest.raises(ValueError, match=r"turns must be one value or one per interval \(2,\)"):
        interval_twists(ROBOT, times, increments, 0.0, turns=[0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="increments"):
        interval_twists(ROBOT, times, increments[:1], 0.0)


def test_the_estimators_twist_turns_with_the_gyro_less_its_bias():
    times = np.arange(101) * 0.02
    increments = np.tile([0.2, 0.21], (100, 1))
    gyro = Gyro(times, np.full(101, 0.05 + 0.01))  # a turn of 0.05 rad/s and a bias of 0.01
    found = estimate_trajectory(
        ROBOT, times, increments, gyro=gyro, settings=EstimatorSettings("gyro", bias=0.01)
    )
    np.testing.assert_allclose(found.twists[:, 2], 0.05, rtol=1e-9)
    np.testing.assert_allclose(found.twists[:, 0], 0.1 * 0.205 / 0.02, rtol=1e-12)
    arw = 2e-3  # GyroNoise's default
    np.testing.assert_allclose(found.twist_covariances[1:, 2, 2], arw**2 / 0.02, rtol=1e-9)
    wheels = estimate_trajectory(
        ROBOT, times, increments, settings=EstimatorSettings("wheels"), smooth=False
    )
    expected, spread = interval_twists(ROBOT, times, increments, 1e-4)
    np.testing.assert_allclose(wheels.twists, expected, rtol=1e-12)
    np.testing.assert_allclose(wheels.twist_covariances, spread, rtol=1e-12)
