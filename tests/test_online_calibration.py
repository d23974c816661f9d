"""Online calibration: recursive least squares equals the batch answer, converges to the
robot that made the data, and gates out measurements that cannot be right."""

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.calibration import calibrate, odometry_of
from diffdrive.online_calibration import OnlineCalibrator

NOMINAL = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
TRUE = dd.DiffDrive(left_wheel_radius=0.0497, right_wheel_radius=0.0502, track_width=0.306)


def intervals(seed=0, n=4000):
    """Wheel increments of a weaving drive both ways, and the relative poses they make, with
    reference noise of 0.2 mm and 0.2 mrad per interval."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.05
    wheels = np.stack([8 + 4 * np.sin(0.4 * t), 8 - 4 * np.sin(0.3 * t + 1)], -1) * 0.05
    truth = odometry_of(TRUE, wheels, np.zeros(3))
    relative = dd.batch.relative_to(truth[1:], truth[:-1])
    noisy = relative + rng.normal(0, 2e-4, relative.shape)
    return wheels, noisy, truth


def test_it_converges_to_the_robot_that_made_the_data():
    wheels, relative, truth = intervals()
    online = OnlineCalibrator(NOMINAL, sigma_distance=3e-4, sigma_turn=3e-4)
    for k in range(len(wheels)):
        assert online.update(*wheels[k], relative[k])
    np.testing.assert_allclose(online.parameters, [0.0497, 0.0502, 0.306], rtol=2e-3)
    sigma = np.sqrt(np.diag(online.covariance))
    assert np.all(np.abs(online.parameters - [0.0497, 0.0502, 0.306]) < 5 * sigma)
    batch = calibrate(NOMINAL, [(wheels, truth)], "increments").robot  # the batch fit, no noise
    np.testing.assert_allclose(online.parameters,
                               [batch.left_wheel_radius, batch.right_wheel_radius,
                                batch.track_width], rtol=2e-3)  # fmt: skip


def test_recursive_equals_batch_weighted_least_squares_on_the_same_data():
    wheels, relative, _ = intervals(1, 500)
    online = OnlineCalibrator(NOMINAL, sigma_distance=3e-4, sigma_turn=3e-4, gate=1e12)
    for k in range(len(wheels)):
        online.update(*wheels[k], relative[k])
    np.testing.assert_allclose(online.parameters, online.batch_solution(wheels, relative),
                               rtol=1e-9)  # fmt: skip


def test_measurements_that_cannot_be_right_are_gated_out():
    wheels, relative, _ = intervals(2, 2000)
    clean = OnlineCalibrator(NOMINAL, sigma_distance=3e-4, sigma_turn=3e-4)
    jumpy = OnlineCalibrator(NOMINAL, sigma_distance=3e-4, sigma_turn=3e-4)
    bad = relative.copy()
    bad[[500, 900, 1300, 1700, 1900], 0] += 0.05  # the reference jumps 5 cm
    for k in range(len(wheels)):
        clean.update(*wheels[k], relative[k])
        jumpy.update(*wheels[k], bad[k])
    assert jumpy.rejected == 5
    assert jumpy.accepted == len(wheels) - 5
    np.testing.assert_allclose(jumpy.parameters, clean.parameters, rtol=1e-4)


def test_bad_input_is_refused_and_changes_nothing():
    online = OnlineCalibrator(NOMINAL)
    before = online.parameters
    with pytest.raises(ValueError, match="relative_pose must be 3 finite numbers"):
        online.update(0.1, 0.1, [0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="left must be finite"):
        online.update(np.inf, 0.1, [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="prior_sigma must be > 0"):
        OnlineCalibrator(NOMINAL, prior_sigma=0.0)
    np.testing.assert_array_equal(online.parameters, before)
    assert online.accepted == online.rejected == 0
