"""Calibration: recovers known parameters, refuses what it cannot identify; real-data checks."""

import csv
import math

import numpy as np
import pytest

import diffdrive as dd
from data import DATA, data_folder, rows_or_missing
from diffdrive.calibration import (
    CalibrationError,
    Increments,
    LeastSquares,
    UMBmark,
    calibrate,
)
from diffdrive.evaluation import run_errors, worst
from diffdrive.io.optiodom import optiodom_robot, read_optiodom_run
from diffdrive.simulation import dead_reckon

NOMINAL = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
TRUE = dd.DiffDrive(left_wheel_radius=0.0497, right_wheel_radius=0.0502, track_width=0.306)


def synthetic_run(robot, wheels, dt=0.05):
    """Increments and the exact poses they drive ``robot`` through."""
    increments = np.asarray(wheels, dtype=float) * dt
    truth = dead_reckon(robot, increments, np.zeros(3), "exact")
    return increments, truth


def turning_runs():
    t = np.arange(400) * 0.05
    weave = np.stack([8 + 3 * np.sin(0.5 * t), 8 - 3 * np.sin(0.5 * t)], axis=-1)
    circle = np.tile([6.0, 9.0], (300, 1))
    return [synthetic_run(TRUE, weave), synthetic_run(TRUE, circle)]


@pytest.mark.parametrize("method", ["least_squares", "minimax"])
def test_recovers_the_parameters_that_made_the_runs(method):
    result = calibrate(NOMINAL, turning_runs(), method, integration="exact")
    assert result.robot.left_wheel_radius == pytest.approx(0.0497, abs=1e-7)
    assert result.robot.right_wheel_radius == pytest.approx(0.0502, abs=1e-7)
    assert result.robot.track_width == pytest.approx(0.306, abs=1e-6)
    assert max(r.max() for r in result.residuals) < 1e-6
    assert result.condition < 1e3


def test_the_uncertainty_covers_the_truth_on_noisy_runs():
    rng = np.random.default_rng(3)
    runs = []
    for increments, truth in turning_runs():
        noisy = truth.copy()  # mocap jitter after the first pose, which the odometry starts from
        noisy[1:, :2] += rng.normal(0, 0.002, truth[1:, :2].shape)
        runs.append((increments, noisy))
    result = calibrate(NOMINAL, runs, integration="exact")
    error = np.array(
        [
            result.robot.left_wheel_radius - 0.0497,
            result.robot.right_wheel_radius - 0.0502,
            result.robot.track_width - 0.306,
        ]
    )
    assert np.all(np.abs(error) < 5 * result.standard_errors), (error, result.standard_errors)


def test_a_long_fit_shows_its_progress_when_asked(capsys):
    calibrate(NOMINAL, turning_runs(), progress=True)
    assert "fitting 2 runs" in capsys.readouterr().err


def test_straight_runs_cannot_fix_the_track_width():
    straight = [synthetic_run(TRUE, np.tile([8.0, 8.0 * 0.0497 / 0.0502], (200, 1)))]
    with pytest.raises(CalibrationError, match="turn in place in both directions to identify"):
        calibrate(NOMINAL, straight)
    fixed = calibrate(NOMINAL, straight, fixed=("track_width",))
    assert fixed.robot.track_width == NOMINAL.track_width
    assert fixed.covariance[2, 2] == 0.0
    assert fixed.robot.left_wheel_radius == pytest.approx(0.0497, abs=1e-7)


def test_runs_that_turn_one_way_or_barely_drive_are_refused_with_advice():
    circle = [synthetic_run(TRUE, np.tile([6.0, 9.0], (300, 1)))]
    with pytest.raises(CalibrationError, match=r"turn only left \(counter-clockwise\).*other way"):
        calibrate(NOMINAL, circle)
    spin = [synthetic_run(TRUE, np.tile([-0.5, 0.5], (20, 1)))]
    with pytest.raises(CalibrationError, match="too little to identify the wheel radii"):
        calibrate(NOMINAL, spin)
    with pytest.raises(ValueError, match="fixed names 'track'"):
        calibrate(NOMINAL, circle, fixed=("track",))
    one_way = calibrate(NOMINAL, circle, fixed=("track_width",))
    assert one_way.robot.track_width == NOMINAL.track_width


def test_bad_runs_are_refused():
    with pytest.raises(CalibrationError, match="run 0: ground truth must be"):
        calibrate(NOMINAL, [(np.zeros((5, 2)), np.zeros((5, 3)))])
    with pytest.raises(CalibrationError, match="umbmark needs square_side"):
        calibrate(NOMINAL, turning_runs(), "umbmark")
    with pytest.raises(CalibrationError, match="0 clockwise and 1 counter-clockwise"):
        calibrate(NOMINAL, square_runs(1.0, 1, clockwise=False), "umbmark", UMBmark(1.0))


def square_run(side, clockwise, robot=TRUE, speed=8.0, dt=0.02):
    """Increments and truth of ``robot`` driving a square: straight sides, turns in place."""
    sign = -1.0 if clockwise else 1.0
    side_steps = round(side / (speed * robot.wheel_radius * dt))
    turn_rate = 4.0  # rad/s of each wheel, opposite
    turn_steps = round(
        (math.pi / 2) * robot.track_width / (2 * turn_rate * robot.wheel_radius * dt)
    )
    legs = []
    for _ in range(4):
        legs.append(np.tile([speed, speed], (side_steps, 1)))
        legs.append(np.tile([-sign * turn_rate, sign * turn_rate], (turn_steps, 1)))
    return synthetic_run(robot, np.vstack(legs), dt)


def square_runs(side, count, clockwise):
    return [square_run(side, clockwise) for _ in range(count)]


def test_umbmark_refuses_runs_that_are_not_squares_and_names_them():
    runs = [square_run(1.0, True), square_run(1.0, False), turning_runs()[0]]
    with pytest.raises(CalibrationError, match=r"run 2 is not one: it turns .* deg in all"):
        calibrate(NOMINAL, runs, "umbmark", UMBmark(1.0))
    with pytest.raises(CalibrationError, match=r"a is not one: it is 4 m long, not about 8 m"):
        calibrate(NOMINAL, runs[:2], "umbmark", UMBmark(2.0), names=["a", "weave.csv"])


def test_umbmark_gives_an_uncertainty_from_repeated_runs_or_says_why_not():
    rng = np.random.default_rng(4)
    runs = []
    for clockwise in (True, False, True, False, True, False):
        increments, truth = square_run(1.0, clockwise)
        jittered = truth.copy()
        jittered[-1, :2] += rng.normal(0, 0.003, 2)  # where the robot really stopped varies
        runs.append((increments, jittered))
    result = calibrate(NOMINAL, runs, "umbmark", UMBmark(1.0))
    assert result.covariance.shape == (3, 3)
    assert np.all(np.isfinite(result.standard_errors))
    assert np.all(result.standard_errors > 0)
    assert result.condition is None
    single = calibrate(NOMINAL, runs[:2], "umbmark", UMBmark(1.0))
    assert single.covariance is None
    assert single.standard_errors is None
    assert "needs 2 or more in each direction" in single.uncertainty_note


def test_a_window_of_steps_outweighs_jitter_in_when_the_wheels_are_read():
    """Encoders read a few ms off the reference's instants: per step that error sits in the
    regressors and pulls the fit (errors in variables); twenty steps at a time it weighs a
    twentieth as much."""
    rng = np.random.default_rng(7)
    t = np.arange(1201) * 0.05
    runs = []
    for sign in (1, -1):
        wheels = np.stack([8 + sign * 4 * np.sin(0.3 * t), 8 - sign * 4 * np.sin(0.3 * t)], -1)
        increments, truth = synthetic_run(TRUE, wheels[:-1])
        angles = np.vstack([[0, 0], np.cumsum(increments, axis=0)])
        read_at = t + rng.normal(0.0, 0.005, t.shape)  # when each reading was really taken
        read = np.stack([np.interp(read_at, t, angles[:, k]) for k in (0, 1)], axis=-1)
        runs.append((np.diff(read, axis=0), truth))
    error = {}
    for window in (1, 20):
        robot = calibrate(NOMINAL, runs, "increments", Increments(window)).robot
        found = np.array([robot.left_wheel_radius, robot.right_wheel_radius])
        error[window] = np.abs(found / [TRUE.left_wheel_radius, TRUE.right_wheel_radius] - 1).max()
    assert error[20] < 0.002 < 0.01 < error[1]  # 0.05 % against 1.8 %: the radii shrink


def test_windows_keep_every_step_and_a_short_last_one():
    from diffdrive.calibration.offline import _windows

    increments = np.arange(90.0).reshape(45, 2)
    truth = np.arange(46.0)[:, None] * np.ones(3)
    blocks, ends = _windows(increments, truth, 20)
    assert blocks.shape == (3, 20, 2)
    np.testing.assert_array_equal(blocks.reshape(-1, 2)[:45], increments)
    np.testing.assert_array_equal(blocks[2, 5:], 0.0)  # steps of no motion fill the last
    np.testing.assert_array_equal(ends[:, 0], [0, 20, 40, 45])
    np.testing.assert_array_equal(_windows(increments, truth, 1)[0][:, 0], increments)


def test_a_window_follows_a_turn_that_changes_within_it():
    """A weave whose curvature changes within each window: the windows' steps are composed,
    so the exact runs give back the robot that drove them (summing the wheels over a window
    as one constant twist missed its track by 0.4 %)."""
    t = np.arange(800) * 0.05
    runs = [
        synthetic_run(
            TRUE, np.stack([8 + s * 5 * np.sin(0.8 * t), 8 - s * 5 * np.sin(0.8 * t)], -1)
        )
        for s in (1, -1)
    ]
    robot = calibrate(NOMINAL, runs, "increments", Increments(20)).robot
    assert robot.track_width == pytest.approx(TRUE.track_width, rel=1e-9)
    assert robot.left_wheel_radius == pytest.approx(TRUE.left_wheel_radius, rel=1e-9)


def test_a_window_is_the_increments_methods_only():
    with pytest.raises(ValueError, match="window is for the increments method only; got 5"):
        calibrate(NOMINAL, turning_runs(), "least_squares", Increments(5))
    with pytest.raises(ValueError, match="window must be a whole number from 1, got 0"):
        calibrate(NOMINAL, turning_runs(), "increments", Increments(0))


@pytest.mark.parametrize(
    ("method", "options", "message"),
    [
        ("least_squares", UMBmark(1.0), "square_side is for the umbmark method only"),
        ("increments", LeastSquares(("axle_offset",)), "extra parameters are for least_squares"),
        ("umbmark", Increments(20), "window is for the increments method only; got 20"),
        ("minimax", "fast", "options must be UMBmark, LeastSquares or Increments"),
        ("gradient", None, "method must be one of umbmark, least_squares, minimax"),
    ],
)
def test_the_options_of_one_method_are_refused_for_another(method, options, message):
    with pytest.raises((ValueError, TypeError), match=message):
        calibrate(NOMINAL, turning_runs(), method, options)


def test_minimax_takes_the_least_squares_options():
    fit = calibrate(NOMINAL, turning_runs(), "minimax", LeastSquares(extra=("axle_offset",)))
    assert fit.method == "minimax"


# -- real data ---------------------------------------------------------------------------------

FOLDER = DATA / "optiodom-diffdrive"


def authors(method_prefix, plain=False):
    """The authors' rows of a method (``plain``: those without a note), as parameters."""

    def rows():
        with (FOLDER / "reference_results_from_authors.csv").open() as table:
            return [
                row
                for row in csv.DictReader(table)
                if row["method"].startswith(method_prefix)
                and (FOLDER / row["experiment"]).is_dir()
                and not (plain and row["note"])
            ]

    return rows_or_missing("optiodom-diffdrive", rows)


def runs_of(experiment):
    folder = data_folder("optiodom-diffdrive") / experiment
    return [read_optiodom_run(p) for p in sorted(folder.glob("*_run-*.csv"))]


@pytest.mark.parametrize(
    ("experiment", "limit"), [("circular/231220200141", 0.06), ("circular/250620202345", 0.02)]
)
def test_a_window_of_twenty_cycles_fits_the_optiodom_circles(experiment, limit):
    """Per 50 ms cycle the fit leaves 346 and 577 mm; 20 cycles at a time 53 and 12 mm."""
    runs = runs_of(experiment)

    def worst_error(window):
        robot = calibrate(optiodom_robot(), runs, "increments", Increments(window)).robot
        return worst(
            [
                run_errors(dead_reckon(robot, run.increments(), run.truth[0], "rk2"), run.truth)
                for run in runs
            ]
        ).max_position

    assert worst_error(20) < limit < 0.3 < worst_error(1)


@pytest.mark.parametrize("row", authors("UMBmark", plain=True), ids=lambda r: r["experiment"])
def test_umbmark_reproduces_the_authors_parameters(row):
    data_folder("optiodom-diffdrive")
    result = calibrate(
        optiodom_robot(),
        runs_of(row["experiment"]),
        "umbmark",
        UMBmark(float(row["path_param_m"])),
    )
    robot = result.robot
    # The spreadsheet keeps 6 significant digits.
    assert robot.track_width == pytest.approx(float(row["calib_L_m"]), abs=5e-7)
    assert 2 * robot.right_wheel_radius == pytest.approx(float(row["calib_Dr_m"]), abs=5e-7)
    assert 2 * robot.left_wheel_radius == pytest.approx(float(row["calib_Dl_m"]), abs=5e-7)


@pytest.mark.slow
def test_minimax_beats_optiodom_on_every_experiment_with_the_papers_protocol():
    data_folder("optiodom-diffdrive")
    ours, theirs = [], []
    for row in authors("OptiOdom"):
        if row["note"]:
            continue
        runs = runs_of(row["experiment"])
        # The paper's protocol and its odometry method, rk2.
        robot = calibrate(optiodom_robot(), runs, "minimax", integration="rk2").robot
        errors = worst(
            [
                run_errors(dead_reckon(robot, run.increments(), run.truth[0], "rk2"), run.truth)
                for run in runs
            ]
        )
        ours.append(errors.max_position)
        theirs.append(float(row["calib_max_pos_err_m"]))
        assert ours[-1] <= theirs[-1], row["experiment"]
    assert len(ours) == 10
    assert np.mean(ours) < np.mean(theirs)
    assert math.isfinite(sum(ours))


def test_a_prior_pulls_the_fit_toward_the_nominal_geometry():
    t = np.arange(160) * 0.05
    wheels = np.stack([8 + 3 * np.sin(0.8 * t), 8 - 3 * np.sin(0.8 * t)], -1)
    increments, truth = synthetic_run(TRUE, wheels)
    truth[1:, :2] += np.random.default_rng(1).normal(0, 0.03, truth[1:, :2].shape)
    track = {
        sigma: calibrate(
            NOMINAL, [(increments, truth)], options=LeastSquares(prior_sigma=sigma)
        ).robot.track_width
        for sigma in (None, 0.01, 1e-4)
    }
    assert abs(track[None] - 0.3) > 0.004  # the data alone move it 1.9 %
    assert abs(track[1e-4] - 0.3) < 0.3 * abs(track[None] - 0.3)
    assert abs(track[1e-4] - 0.3) <= abs(track[0.01] - 0.3) <= abs(track[None] - 0.3)
    with pytest.raises(ValueError, match="prior_sigma must be a finite number > 0"):
        calibrate(NOMINAL, [(increments, truth)], options=LeastSquares(prior_sigma=0.0))
