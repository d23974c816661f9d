"""diffdrive.io: one ``Run`` type from every source, and what takes it (calibration, the CLI)."""

from dataclasses import replace

import numpy as np
import pytest

import diffdrive as dd
from data import data_folder
from diffdrive.calibration import CalibrationError, calibrate
from diffdrive.calibration.cross_validation import cross_validate
from diffdrive.io import Run, TableError, read_run, write_trajectory

NOMINAL = dd.DiffDrive(wheel_radius=0.042, track_width=0.2)
TRUE = dd.DiffDrive(left_wheel_radius=0.0418, right_wheel_radius=0.0423, track_width=0.205)


def simulated(wheels: np.ndarray, dt: float = 0.05) -> Run:
    trajectory = dd.simulate(TRUE, wheels, dt=dt)
    return Run.from_increments(
        np.diff(trajectory.wheel_positions, axis=0),
        trajectory.poses,
        trajectory.times,
        source="simulated",
    )


def turning() -> list[Run]:
    t = np.arange(300) * 0.05
    weave = np.stack([8 + 3 * np.sin(0.5 * t), 8 - 3 * np.sin(0.5 * t)], axis=-1)
    return [simulated(weave), simulated(np.tile([6.0, 9.0], (300, 1)))]


def test_from_increments_accumulates_and_gives_them_back():
    steps = np.array([[0.1, 0.2], [-0.05, 0.3], [0.0, 0.0]])
    run = Run.from_increments(steps, np.zeros((4, 3)), [0.0, 0.1, 0.3, 0.4])
    assert run.kind == "angle"
    np.testing.assert_array_equal(run.wheels[0], [0.0, 0.0])
    np.testing.assert_allclose(run.wheels[-1], [0.05, 0.5])
    np.testing.assert_allclose(run.increments(), steps, atol=1e-17)
    assert run.where(2) == "increments, row 3"


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ((np.zeros((3, 3)),), r"increments must be \(T, 2\), got \(3, 3\)"),
        ((np.zeros((3, 2)), np.zeros((3, 3))), r"ground truth must be \(T\+1, 3\) = \(4, 3\)"),
        ((np.zeros((3, 2)), None, np.zeros(3)), r"times must be \(T\+1,\) = \(4,\), got \(3,\)"),
    ],
)
def test_from_increments_refuses_shapes_that_do_not_fit(arguments, message):
    with pytest.raises(ValueError, match=message):
        Run.from_increments(*arguments)


def test_rows_cuts_every_per_row_field_alike(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text(
        "t,left_ticks,right_ticks,x,y,theta,gyro_z\n"
        + "".join(f"{k * 0.1},{k},{2 * k},{k},0,0,{k / 10}\n" for k in range(6))
    )
    run = read_run(path).rows(np.arange(6) >= 2)
    np.testing.assert_allclose(run.times, [0.2, 0.3, 0.4, 0.5])
    np.testing.assert_array_equal(run.wheels[:, 1], [4, 6, 8, 10])
    np.testing.assert_array_equal(run.truth[:, 0], [2, 3, 4, 5])
    np.testing.assert_allclose(run.gyro_rates, [0.2, 0.3, 0.4, 0.5])
    assert run.where(0) == f"{path}:4"  # the line of the row kept first


def test_calibrate_takes_runs_and_pairs_alike():
    runs = turning()
    pairs = [(run.increments(), run.truth) for run in runs]
    from_runs = calibrate(NOMINAL, runs, integration="exact").robot
    from_pairs = calibrate(NOMINAL, pairs, integration="exact").robot
    assert from_runs.track_width == pytest.approx(0.205, abs=1e-6)
    assert from_runs.left_wheel_radius == from_pairs.left_wheel_radius
    assert from_runs.track_width == from_pairs.track_width
    fold = cross_validate(NOMINAL, runs, scheme="loo", integration="exact")
    assert fold.in_sample.max_position < 1e-6


def test_a_run_without_ground_truth_is_refused_by_its_source(tmp_path):
    path = tmp_path / "bare.csv"
    path.write_text("t,left_angle,right_angle\n0,0,0\n0.1,1,1.2\n0.2,2,2.6\n")
    with pytest.raises(CalibrationError, match=r"bare\.csv: the run has no ground truth"):
        calibrate(NOMINAL, [read_run(path)])


def test_a_ticks_run_without_its_resolution_is_refused():
    run = dd.demo.example_log()
    with pytest.raises(TableError, match="ticks need the counts per wheel revolution"):
        calibrate(NOMINAL, [replace(run, ticks_per_revolution=None)])


def test_the_same_run_from_a_table_and_an_optiodom_file_reads_alike(tmp_path):
    """An OptiOdom file (per-cycle counts, right first) and a table of the same counter
    readings give the same Run."""
    folder = data_folder("optiodom-diffdrive") / "circular" / "231220200141"
    optiodom = read_run(sorted(folder.glob("*_run-*.csv"))[0])
    table = tmp_path / "same.csv"
    rows = zip(optiodom.times, *optiodom.wheels.T, *optiodom.truth.T, strict=True)
    table.write_text(
        "t,left_ticks,right_ticks,x,y,theta\n"
        + "".join(
            ",".join(map(repr, map(float, row[:1])))
            + f",{int(row[1])},{int(row[2])},"
            + ",".join(map(repr, map(float, row[3:])))
            + "\n"
            for row in rows
        )
    )
    again = read_run(table)
    assert (optiodom.kind, again.kind) == ("ticks", "ticks")
    np.testing.assert_array_equal(again.wheels, optiodom.wheels)
    np.testing.assert_array_equal(again.truth, optiodom.truth)
    ticks = optiodom.ticks_per_revolution
    np.testing.assert_array_equal(again.increments(ticks), optiodom.increments())


@pytest.mark.slow
def test_a_bag_gives_a_run_with_its_reference_as_truth():
    pytest.importorskip("rosbags")
    bag = data_folder("ros-bags") / "turtlebot3_fuse.bag"
    run = read_run(
        bag, left_joint="wheel_left_joint", right_joint="wheel_right_joint", reference_topic="/odom"
    )
    assert isinstance(run, Run)
    assert run.kind == "angle"
    assert run.truth is not None
    assert run.truth.shape == (len(run.times), 3)
    assert "against /odom" in run.source
    result = calibrate(dd.DiffDrive(wheel_radius=0.033, track_width=0.287), [run], "increments")
    assert 0.25 < result.robot.track_width < 0.33


def test_a_topic_of_a_file_and_a_reference_of_a_log_are_refused(tmp_path):
    path = tmp_path / "t.csv"
    write_trajectory(path, [0.0, 1.0], np.zeros((2, 3)))
    with pytest.raises(TableError, match="a topic needs a bag"):
        dd.io.read_trajectory(path, topic="/odom")
    with pytest.raises(TableError, match="a reference topic needs a bag"):
        read_run(path, reference_topic="/odom")


@pytest.mark.slow
def test_evaluate_and_plot_read_an_optiodom_run_file_as_its_ground_truth(tmp_path, capsys):
    """odometry and calibrate read OptiOdom files; evaluate and plot refused them (no 't')."""
    from diffdrive.cli import main

    folder = data_folder("optiodom-diffdrive") / "free" / "030120210006"
    run_file = sorted(folder.glob("*_run-*.csv"))[0]
    times, poses = dd.io.read_trajectory(run_file)
    run = dd.io.read_run(run_file)
    np.testing.assert_array_equal(times, run.times)
    np.testing.assert_array_equal(poses, run.truth)
    estimate = tmp_path / "o.csv"
    assert main(["odometry", str(run_file), "--method", "rk2", "-o", str(estimate), "-q"]) == 0
    assert main(["evaluate", str(estimate), "--truth", str(run_file), "--json"]) == 0
    assert '"poses_compared": 2157' in capsys.readouterr().out
    assert main(["plot", str(run_file), "-o", str(tmp_path / "p.png"), "-q"]) == 0


def test_a_plain_tum_file_reads_as_fast_as_csv_and_a_bad_one_names_its_line(tmp_path):
    """TUM files went through a Python loop a line (10^6 poses: 15.5 s against 3.3 s for
    CSV); a plain one now goes through NumPy's parser, giving the same poses."""
    times = np.arange(2000) * 0.01
    poses = np.column_stack([np.cos(times), np.sin(times), 0.3 * times])
    write_trajectory(tmp_path / "p.tum", times, poses, "tum")
    from diffdrive.io import trajectories

    plain = trajectories._plain_tum(tmp_path / "p.tum")
    assert plain is not None
    careful = trajectories._careful_tum(tmp_path / "p.tum")
    np.testing.assert_array_equal(plain, careful)
    read = dd.io.read_trajectory(tmp_path / "p.tum")
    np.testing.assert_allclose(read[1], poses, atol=1e-12)
    bad = tmp_path / "bad.tum"
    lines = (tmp_path / "p.tum").read_text().splitlines()
    lines[5] = lines[5].replace(" 0.0 ", " x ", 1)
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(TableError, match=r"bad\.tum:6"):
        dd.io.read_trajectory(bad)
