"""Online calibration: recursive least squares equals the batch answer, converges to the
robot that made the data, and gates out measurements that cannot be right."""

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.calibration import calibrate
from diffdrive.calibration.online import OnlineCalibrator
from diffdrive.simulation import dead_reckon

NOMINAL = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
TRUE = dd.DiffDrive(left_wheel_radius=0.0497, right_wheel_radius=0.0502, track_width=0.306)


def intervals(seed=0, n=4000):
    """Wheel increments of a weaving drive both ways, and the relative poses they make, with
    reference noise of 0.2 mm and 0.2 mrad per interval."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.05
    wheels = np.stack([8 + 4 * np.sin(0.4 * t), 8 - 4 * np.sin(0.3 * t + 1)], -1) * 0.05
    truth = dead_reckon(TRUE, wheels, np.zeros(3))
    relative = dd.batch.relative_to(truth[1:], truth[:-1])
    noisy = relative + rng.normal(0, 2e-4, relative.shape)
    return wheels, noisy, truth


@pytest.mark.slow
def test_it_converges_to_the_robot_that_made_the_data():
    wheels, relative, truth = intervals()
    online = OnlineCalibrator(NOMINAL, sigma_distance=3e-4, sigma_turn=3e-4, window=1)
    for k in range(len(wheels)):
        assert online.update(*wheels[k], relative[k])
    np.testing.assert_allclose(online.parameters, [0.0497, 0.0502, 0.306], rtol=2e-3)
    sigma = np.sqrt(np.diag(online.covariance))
    assert np.all(np.abs(online.parameters - [0.0497, 0.0502, 0.306]) < 5 * sigma)
    batch = calibrate(NOMINAL, [(wheels, truth)], "increments").robot  # the batch fit, no noise
    np.testing.assert_allclose(
        online.parameters,
        [batch.left_wheel_radius, batch.right_wheel_radius, batch.track_width],
        rtol=2e-3,
    )


@pytest.mark.parametrize("window", [1, 7, 20])
def test_recursive_equals_batch_weighted_least_squares_on_the_same_data(window):
    wheels, relative, _ = intervals(1, 503)  # not a multiple of 7 or 20: a window left over
    online = OnlineCalibrator(
        NOMINAL, sigma_distance=3e-4, sigma_turn=3e-4, gate=1e12, window=window
    )
    for k in range(len(wheels)):
        online.update(*wheels[k], relative[k])
    assert online.accepted == len(wheels) // window
    np.testing.assert_allclose(
        online.parameters, online.batch_solution(wheels, relative), rtol=1e-9
    )


@pytest.mark.parametrize("prior_sigma", [0.01, 0.5])
def test_batch_solution_takes_the_same_prior(prior_sigma):
    """batch_solution started from the default prior whatever this one's was (7.9 mm from the
    online estimate with a prior of 0.01): the same estimator, started the same way."""
    wheels, relative, _ = intervals(1, 200)
    online = OnlineCalibrator(
        NOMINAL, sigma_distance=3e-4, sigma_turn=3e-4, gate=1e12, window=5, prior_sigma=prior_sigma
    )
    for k in range(len(wheels)):
        online.update(*wheels[k], relative[k])
    np.testing.assert_allclose(
        online.parameters, online.batch_solution(wheels, relative), rtol=1e-9
    )


def test_an_update_that_would_overflow_is_refused_and_changes_nothing():
    """Two wheel increments of 1e308 in one window left [nan, nan, nan] for good."""
    online = OnlineCalibrator(NOMINAL, window=2)
    assert online.update(1e308, 0.0, (0.0, 0.0, 0.0))
    before = (online.parameters, online.covariance, online._gathered[2])
    with pytest.raises(ValueError, match="overflow; refused, nothing changed"):
        online.update(1e308, 0.0, (0.0, 0.0, 0.0))
    np.testing.assert_array_equal(online.parameters, before[0])
    np.testing.assert_array_equal(online.covariance, before[1])
    assert online._gathered[2] == before[2]
    assert np.all(np.isfinite(online.parameters))
    single = OnlineCalibrator(NOMINAL, window=1)
    with pytest.raises(ValueError, match="would make the estimate overflow"):
        single.update(1e300, 1e300, (1e300, 0.0, 0.0))
    assert np.all(np.isfinite(single.parameters))
    assert single.accepted == single.rejected == 0


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"prior_sigma": 1e200}, r"prior_sigma 1e\+200 gives a prior variance"),
        ({"sigma_distance": 1e-200}, "sigma_distance 1e-200 squares to 0.0"),
        ({"sigma_turn": 1e200}, r"sigma_turn 1e\+200 squares to inf"),
    ],
)
def test_noise_and_priors_that_square_out_of_range_are_refused(options, message):
    with pytest.raises(ValueError, match=message):
        OnlineCalibrator(NOMINAL, **options)


def test_a_window_composes_the_relative_poses_and_sums_the_wheels():
    wheels, relative, truth = intervals(3, 40)
    by_cycle = OnlineCalibrator(NOMINAL, window=20, gate=1e12)
    by_window = OnlineCalibrator(NOMINAL, window=1, gate=1e12)
    for k in range(40):
        by_cycle.update(*wheels[k], relative[k])
    for start in (0, 20):
        cycles = [dd.se2.to_matrix(dd.Pose(*p)) for p in relative[start : start + 20]]
        composed = dd.se2.from_matrix(np.linalg.multi_dot(cycles), atol=1e-6)
        moved = dd.batch.relative_to(truth[start + 20], truth[start])
        np.testing.assert_allclose(composed.to_array(), moved, atol=5e-3)  # 0.2 mm a cycle
        by_window.update(*wheels[start : start + 20].sum(axis=0), composed.to_array())
    np.testing.assert_allclose(by_cycle.parameters, by_window.parameters, rtol=1e-12)


@pytest.mark.slow
def test_measurements_that_cannot_be_right_are_gated_out():
    wheels, relative, _ = intervals(2, 2000)
    clean = OnlineCalibrator(NOMINAL, sigma_distance=3e-4, sigma_turn=3e-4, window=1)
    jumpy = OnlineCalibrator(NOMINAL, sigma_distance=3e-4, sigma_turn=3e-4, window=1)
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
    with pytest.raises(ValueError, match="window must be a whole number from 1"):
        OnlineCalibrator(NOMINAL, window=2.5)
    np.testing.assert_array_equal(online.parameters, before)
    assert online.accepted == online.rejected == 0


@pytest.mark.slow
@pytest.mark.parametrize("experiment", ["circular/231220200141", "circular/250620202345"])
def test_one_circular_experiment_lands_within_1_percent_of_batch_least_squares(experiment):
    """One OptiOdom circle run each way, streamed cycle by cycle with the default window: every
    parameter within 1 % of whole-path least squares on the same runs (0.77 % at worst)."""
    from data import data_folder
    from diffdrive.io.optiodom import optiodom_robot, read_optiodom_run

    folder = data_folder("optiodom-diffdrive") / experiment
    runs = [read_optiodom_run(path) for path in sorted(folder.glob("*_run-*.csv"))]
    online = OnlineCalibrator(optiodom_robot())
    for run in runs:
        increments, truth = run.increments(), run.truth
        relative = dd.batch.relative_to(truth[1:], truth[:-1])
        for k in range(len(increments)):
            online.update(*increments[k], relative[k])
    batch = calibrate(optiodom_robot(), runs, "least_squares", integration="rk2").robot
    want = [batch.left_wheel_radius, batch.right_wheel_radius, batch.track_width]
    np.testing.assert_allclose(online.parameters, want, rtol=0.01)
    assert online.rejected == 0
