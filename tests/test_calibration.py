"""Calibration: recovers known parameters, refuses what it cannot identify; real-data checks."""

import csv
import math

import numpy as np
import pytest

import diffdrive as dd
from data import data_folder
from diffdrive.calibration import CalibrationError, calibrate, odometry_of
from diffdrive.datasets import optiodom_robot, read_optiodom_run
from diffdrive.evaluation import run_errors, worst

NOMINAL = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
TRUE = dd.DiffDrive(left_wheel_radius=0.0497, right_wheel_radius=0.0502, track_width=0.306)


def synthetic_run(robot, wheels, dt=0.05):
    """Increments and the exact poses they drive ``robot`` through."""
    increments = np.asarray(wheels, dtype=float) * dt
    truth = odometry_of(robot, increments, np.zeros(3), "exact")
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
    error = np.array([result.robot.left_wheel_radius - 0.0497,
                      result.robot.right_wheel_radius - 0.0502,
                      result.robot.track_width - 0.306])  # fmt: skip
    assert np.all(np.abs(error) < 5 * result.standard_errors), (error, result.standard_errors)


def test_straight_runs_cannot_fix_the_track_width():
    straight = [synthetic_run(TRUE, np.tile([8.0, 8.0 * 0.0497 / 0.0502], (200, 1)))]
    with pytest.raises(CalibrationError, match="least determined is track_width"):
        calibrate(NOMINAL, straight)


def test_bad_runs_are_refused():
    with pytest.raises(CalibrationError, match="run 0: ground truth must be"):
        calibrate(NOMINAL, [(np.zeros((5, 2)), np.zeros((5, 3)))])
    with pytest.raises(CalibrationError, match="umbmark needs square_side"):
        calibrate(NOMINAL, turning_runs(), "umbmark")
    with pytest.raises(CalibrationError, match="0 clockwise and 1 counter-clockwise"):
        calibrate(NOMINAL, turning_runs()[1:], "umbmark", square_side=1.0)


# -- real data ---------------------------------------------------------------------------------

FOLDER = data_folder("optiodom-diffdrive")


def authors(method_prefix):
    with (FOLDER / "reference_results_from_authors.csv").open() as table:
        return [
            row for row in csv.DictReader(table)
            if row["method"].startswith(method_prefix) and (FOLDER / row["experiment"]).is_dir()
        ]  # fmt: skip


def runs_of(experiment):
    runs = [read_optiodom_run(p) for p in sorted((FOLDER / experiment).glob("*_run-*.csv"))]
    return [(np.diff(run.wheel_angles(), axis=0), run.ground_truth) for run in runs]


@pytest.mark.parametrize(
    "row", [r for r in authors("UMBmark") if not r["note"]], ids=lambda r: r["experiment"]
)
def test_umbmark_reproduces_the_authors_parameters(row):
    result = calibrate(
        optiodom_robot(), runs_of(row["experiment"]), "umbmark",
        square_side=float(row["path_param_m"]),
    )  # fmt: skip
    robot = result.robot
    # The spreadsheet keeps 6 significant digits.
    assert robot.track_width == pytest.approx(float(row["calib_L_m"]), abs=5e-7)
    assert 2 * robot.right_wheel_radius == pytest.approx(float(row["calib_Dr_m"]), abs=5e-7)
    assert 2 * robot.left_wheel_radius == pytest.approx(float(row["calib_Dl_m"]), abs=5e-7)


def test_minimax_beats_optiodom_on_every_experiment_with_the_papers_protocol():
    ours, theirs = [], []
    for row in authors("OptiOdom"):
        if row["note"]:
            continue
        runs = runs_of(row["experiment"])
        robot = calibrate(optiodom_robot(), runs, "minimax").robot
        errors = worst([run_errors(odometry_of(robot, i, t[0]), t) for i, t in runs])
        ours.append(errors.max_position)
        theirs.append(float(row["calib_max_pos_err_m"]))
        assert ours[-1] <= theirs[-1], row["experiment"]
    assert len(ours) == 10
    assert np.mean(ours) < np.mean(theirs)
    assert math.isfinite(sum(ours))
