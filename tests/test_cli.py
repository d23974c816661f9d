"""The command line: the main job in-process and as a real subprocess."""

import math
import subprocess
import sys

import pytest

from diffdrive.cli import build_parser, kinematics_report, main
from diffdrive.demo import example_robot


@pytest.mark.slow
def test_main_job_prints_the_example_robot_and_says_where_the_outputs_went(
    capsys, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    assert main([]) == 0
    out = capsys.readouterr().out
    assert "track_width=0.2" in out
    assert "spin in place" in out
    assert out.rstrip().endswith("outputs: out/trajectory.csv, out/trajectory.png")
    assert (tmp_path / "out" / "trajectory.png").stat().st_size > 10_000


def test_report_rows_follow_the_model():
    robot = example_robot()
    report = kinematics_report(robot)
    # straight: 10 rad/s on 42 mm wheels is 0.42 m/s and an infinite radius.
    straight = next(line for line in report.splitlines() if line.startswith("straight"))
    assert "0.4200" in straight
    assert "inf" in straight


def test_unknown_option_is_a_usage_error():
    with pytest.raises(SystemExit) as exit_info:
        main(["--no-such-option"])
    assert exit_info.value.code == 2


@pytest.mark.slow
def test_runs_as_a_subprocess(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "diffdrive"],
        capture_output=True,
        text=True,
        check=True,
        cwd=tmp_path,
    )
    assert "Modern Robotics" in result.stdout
    assert result.stderr == ""


def test_simulation_report_lists_each_method_with_the_same_distance():
    from diffdrive.cli import simulation_report

    rows = simulation_report(example_robot(), steps=400).splitlines()[2:]
    assert [row.split()[0] for row in rows] == ["euler", "rk2", "exact"]
    distances = {row.split()[-1] for row in rows}
    assert len(distances) == 1  # the distance does not depend on the heading


# -- subcommands ---------------------------------------------------------------------------

import json  # noqa: E402

import numpy as np  # noqa: E402

import diffdrive as dd  # noqa: E402
from diffdrive.io import atomic_write  # noqa: E402


def run(argv, capsys):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_simulate_with_no_input_runs_the_built_in_example(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, _ = run(["simulate"], capsys)
    assert code == 0
    assert "wrote 2001 poses to trajectory.csv" in out
    table = np.loadtxt(tmp_path / "trajectory.csv", delimiter=",", skiprows=1)
    assert table.shape == (2001, 4)


@pytest.mark.parametrize("fmt", ["csv", "jsonl", "tum"])
def test_simulate_a_velocity_history_to_each_format(tmp_path, capsys, fmt):
    history = tmp_path / "drive.csv"
    history.write_text("t,left_velocity,right_velocity\n0,8,10\n0.5,10,8\n1.0,0,0\n")
    output = tmp_path / f"out.{fmt}"
    code, _, _ = run(["simulate", history, "-o", output, "--quiet"], capsys)
    assert code == 0
    robot = dd.demo.example_robot()
    expected = dd.simulate(robot, [[8, 10], [10, 8]], times=[0, 0.5, 1.0])
    lines = output.read_text().splitlines()
    if fmt == "csv":
        assert lines[0] == "t,x,y,theta"
        got = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
        np.testing.assert_allclose(got[:, 1:], expected.poses)
    elif fmt == "jsonl":
        rows = [json.loads(line) for line in lines]
        np.testing.assert_allclose([[r["x"], r["y"], r["theta"]] for r in rows], expected.poses)
    else:
        rows = np.array([[float(v) for v in line.split()] for line in lines[1:]])
        assert rows.shape == (3, 8)
        np.testing.assert_allclose(rows[:, 1:3], expected.poses[:, :2])
        np.testing.assert_allclose(2 * np.arctan2(rows[:, 6], rows[:, 7]), expected.poses[:, 2])


def test_simulate_wheel_angles_with_a_robot_file(tmp_path, capsys):
    (tmp_path / "robot.toml").write_text("wheel_radius = 0.05\ntrack_width = 0.3\n")
    history = tmp_path / "angles.csv"
    history.write_text("t,left_angle,right_angle\n0,0,0\n1,8,10\n")
    output = tmp_path / "out.csv"
    code, _, _ = run(
        ["simulate", history, "--robot", tmp_path / "robot.toml", "-o", output, "-q"], capsys
    )
    assert code == 0
    expected = dd.simulate(dd.DiffDrive(0.05, 0.3), wheel_positions=[[0, 0], [8, 10]], dt=1.0)
    got = np.loadtxt(output, delimiter=",", skiprows=1)
    np.testing.assert_allclose(got[-1, 1:], expected.final_pose)


def test_odometry_of_a_tick_log_with_ground_truth(tmp_path, capsys):
    log = tmp_path / "log.csv"
    log.write_text(
        "t,left_ticks,right_ticks,x,y,theta\n0,100,100,0,0,0\n0.1,600,600,0.2,0.01,0\n"
        "0.2,1100,1100,0.4,0.0,0.01\n"
    )
    output = tmp_path / "odo.csv"
    code, out, _ = run(
        [
            "odometry",
            log,
            "--ticks-per-revolution",
            1000,
            "--wheel-radius",
            0.05,
            "--track-width",
            0.3,
            "-o",
            output,
        ],
        capsys,
    )
    assert code == 0
    got = np.loadtxt(output, delimiter=",", skiprows=1)
    np.testing.assert_allclose(got[:, 1], [0, 0.05 * np.pi, 0.1 * np.pi])
    # Errors: at 0.1 s (0.05 pi - 0.2, -0.01), at 0.2 s (0.1 pi - 0.4, 0) and 0.01 rad.
    final = abs(0.1 * np.pi - 0.4)
    assert f"position error max {final:.4f} m, final {final:.4f} m" in out
    assert "heading error max 0.573 deg, final 0.573 deg" in out


def test_fk_and_ik_as_a_table_and_as_json(capsys):
    code, out, _ = run(["fk", 8, 10, "--json"], capsys)
    assert code == 0
    assert json.loads(out) == pytest.approx(
        {"vx": 0.378, "vy": 0.0, "omega": 0.42, "turning_radius": 0.9}
    )
    code, out, _ = run(["ik", 0.5, 1.0], capsys)
    assert code == 0
    assert out.splitlines()[0].split() == ["left", "9.52381", "rad/s"]


HEAD = "t,left_velocity,right_velocity\n"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("t,left_velocity\n0,1\n", r"drive\.csv:1: missing column 'right_velocity'"),
        (HEAD + "0,1,x\n", r"drive\.csv:2: column 'right_velocity': not a number: 'x'"),
        (HEAD + "0,1,1\n1,nan,1\n", r"drive\.csv:3: column 'left_velocity': not finite"),
        (HEAD + "0,1,1\n0,1,1\n", r"drive\.csv:3: column 't': 0 does not increase"),
        ("", r"drive\.csv: the file is empty"),
    ],
)
def test_a_bad_file_is_one_line_naming_file_line_and_column(tmp_path, capsys, text, message):
    history = tmp_path / "drive.csv"
    history.write_text(text)
    output = tmp_path / "out.csv"
    code, out, err = run(["simulate", history, "-o", output], capsys)
    assert code == 1
    assert out == ""
    assert len(err.strip().splitlines()) == 1
    assert err.startswith("diffdrive simulate: error: ")
    assert __import__("re").search(message, err), err
    assert not output.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["drive.csv"]  # no temporary left


def test_a_bad_robot_file_is_named(tmp_path, capsys):
    robot = tmp_path / "robot.toml"
    robot.write_text("wheel_radius = 0.05\nwheels = 2\n")
    code, _, err = run(["fk", 1, 2, "--robot", robot], capsys)
    assert code == 1
    assert "robot.toml: unknown setting 'wheels'" in err


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.csv"

    def interrupted():
        with atomic_write(target) as stream:
            stream.write("half")
            raise RuntimeError("interrupted")

    with pytest.raises(RuntimeError):
        interrupted()
    assert list(tmp_path.iterdir()) == []


def test_a_usage_error_exits_2(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["fk", "eight", "10"])
    assert exit_info.value.code == 2


@pytest.mark.slow
@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "-o", "t.tum"],
        ["fk", "8", "10"],
        ["ik", "0.5", "1", "--json"],
        ["simulate", "--help"],
    ],
)
def test_each_subcommand_runs_as_a_subprocess(tmp_path, argv):
    result = subprocess.run(
        [sys.executable, "-m", "diffdrive", *argv], capture_output=True, text=True, cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert result.stdout


@pytest.mark.slow
def test_a_runtime_error_exits_1_without_a_traceback(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "diffdrive", "simulate", "missing.csv"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert result.returncode == 1
    assert "Traceback" not in result.stderr
    assert result.stderr.strip() == (
        "diffdrive simulate: error: missing.csv: cannot read: No such file or directory"
    )


# -- pictures --------------------------------------------------------------------------------


def rendered(path):
    import matplotlib.image

    return matplotlib.image.imread(path)


@pytest.mark.slow
def test_plot_draws_a_non_blank_figure_of_the_expected_size(tmp_path, capsys):
    trajectory, picture = tmp_path / "t.csv", tmp_path / "t.png"
    assert run(["simulate", "-o", trajectory, "-q"], capsys)[0] == 0
    code, out, _ = run(["plot", trajectory, "--truth", trajectory, "-o", picture], capsys)
    assert code == 0
    assert f"plotted {trajectory} to {picture}" in out
    pixels = rendered(picture)
    assert pixels.shape[:2] == (500, 1200)
    assert pixels[..., :3].std() > 0.05


def test_plot_writes_svg_by_its_suffix(tmp_path, capsys):
    picture = tmp_path / "t.svg"
    assert run(["plot", "-o", picture, "-q"], capsys)[0] == 0
    assert picture.read_text().lstrip().startswith("<?xml")


@pytest.mark.slow
def test_animate_writes_a_gif_of_many_frames(tmp_path, capsys):
    from PIL import Image

    movie = tmp_path / "drive.mp4"  # no ffmpeg needed: it falls back to a GIF
    code, out, _ = run(["animate", "-o", movie, "--fps", "10", "--frames", "15"], capsys)
    assert code == 0
    written = movie.with_suffix(".gif") if "pillow" in out else movie
    assert str(written) in out
    if written.suffix == ".gif":
        with Image.open(written) as image:
            assert image.n_frames == 15
            assert image.size == (600, 600)


def test_plot_of_a_bad_trajectory_file_writes_nothing(tmp_path, capsys):
    trajectory = tmp_path / "t.csv"
    trajectory.write_text("t,x,y\n0,0,0\n")
    code, _, err = run(["plot", trajectory, "-o", tmp_path / "t.png"], capsys)
    assert code == 1
    assert "t.csv:1: missing column 'theta'" in err
    assert [p.name for p in tmp_path.iterdir()] == ["t.csv"]


@pytest.mark.slow
def test_plot_runs_as_a_subprocess(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "diffdrive", "plot"], capture_output=True, text=True, cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "trajectory.png").stat().st_size > 10_000


@pytest.mark.slow
def test_odometry_runs_as_a_subprocess_and_is_quiet_when_piped(tmp_path):
    rows = "\n".join(f"{k * 0.01},{k * 0.1},{k * 0.12}" for k in range(20_000))
    (tmp_path / "log.csv").write_text("t,left_angle,right_angle\n" + rows + "\n")
    result = subprocess.run(
        [sys.executable, "-m", "diffdrive", "odometry", "log.csv", "-o", "odo.jsonl"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert len((tmp_path / "odo.jsonl").read_text().splitlines()) == 20_000


def test_odometry_with_no_log_runs_the_built_in_one(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, _ = run(["odometry"], capsys)
    assert code == 0
    assert "odometry of the built-in encoder log: wrote 401 poses to odometry.csv" in out
    # 20 Hz counters of 2796.8 counts a turn: within a millimetre over 20 s.
    error = float(out.split("position error max ")[1].split()[0])
    assert error < 1e-3


# -- calibrate and evaluate --------------------------------------------------------------------


@pytest.mark.slow
def test_calibrate_the_built_in_runs_to_a_robot_file_that_reads_back(tmp_path, capsys):
    from diffdrive.io import read_robot

    output = tmp_path / "robot.toml"
    code, out, _ = run(["calibrate", "-o", output, "--integration", "exact"], capsys)
    assert code == 0
    assert f"calibrate: wrote the robot to {output}" in out
    settings = read_robot(output)
    # The built-in runs were driven by (0.04166, 0.04163, 0.2019).
    assert settings["left_wheel_radius"] == pytest.approx(0.04166, abs=1e-7)
    assert settings["right_wheel_radius"] == pytest.approx(0.04163, abs=1e-7)
    assert settings["track_width"] == pytest.approx(0.2019, abs=1e-6)


@pytest.mark.parametrize(
    ("folds", "code", "message"),
    [("3", 1, "--cv 3: more folds than the 2 runs"), ("1", 2, "number of folds >= 2, got 1")],
)
@pytest.mark.parametrize("quiet", [[], ["-q"]])
def test_calibrate_refuses_folds_it_cannot_make_and_writes_nothing(
    tmp_path, capsys, folds, code, message, quiet
):
    output = tmp_path / "robot.toml"
    try:
        got = main(["calibrate", "--cv", folds, *quiet, "-o", str(output)])
    except SystemExit as refused:  # argparse's refusal of the option itself
        got = refused.code
    assert got == code
    assert message in capsys.readouterr().err
    assert not output.exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["calibrate-gyro", "LOG", "--fix", "track_width"],
        ["calibrate", "--gyro-arw", "0.01"],
        ["calibrate-driving", "LOG", "--gps-topic", "/fix", "--cv", "none"],
        ["odometry", "--pose-topic", "/pose", "--k-left", "1e-4"],
        ["follow", "WP", "--tracker", "mppi", "--obstacles", "map.yaml", "0.2", "--predict"],
    ],
)
def test_each_job_knows_only_its_own_options(tmp_path, capsys, argv):
    """A subcommand does one thing: another job's option is argparse's usage error (exit 2),
    before anything is read or written, whichever spelling it came in."""
    output = tmp_path / "out.csv"
    with pytest.raises(SystemExit) as usage:
        main([*argv, "-o", str(output)])
    assert usage.value.code == 2
    err = capsys.readouterr().err
    assert "unrecognized arguments" in err or "--k-left without --k-right" in err
    assert not output.exists()


def test_every_subcommand_carries_at_most_30_options():
    """No subcommand (export's targets each one) over 30 options, -h among them."""
    import argparse

    def counts(parser, prefix=""):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    yield prefix + name, sum(bool(a.option_strings) for a in sub._actions)
                    yield from counts(sub, prefix + name + " ")

    found = dict(counts(build_parser()))
    assert {"odometry", "estimate", "calibrate-gyro", "mppi", "export amcl"} <= found.keys()
    assert {name: n for name, n in found.items() if n > 30} == {}


ROBOT = ["--wheel-radius", "0.05", "--track-width", "0.3"]
OPTIODOM = ["--wheel-radius", "0.042", "--track-width", "0.2"]  # the platform's nominal robot


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["simulate", "LOG", "--dt", "0.5", *ROBOT], "--dt sets the built-in history's step"),
        (["simulate", "--frames", "map", "base_link", *ROBOT], "--frames names a bag's frames"),
        (["odometry", "LOG", "--counter-bits", "12", *ROBOT], "the log holds wheel angles"),
        (["evaluate", "LOG", "--truth-topic", "/odom"], "--truth-topic names the truth's topic"),
        (["plot", "LOG", "--truth-topic", "/odom"], "--truth-topic names the truth's topic"),
        (["animate", "LOG", "--truth-topic", "/odom"], "animate draws the trajectory alone"),
    ],
)
def test_options_that_would_change_nothing_are_named(tmp_path, capsys, argv, message):
    log = tmp_path / "log.csv"
    log.write_text("t,left_angle,right_angle\n0,0,0\n0.1,0.5,0.6\n0.2,1.0,1.2\n")
    output = tmp_path / "out.csv"
    argv = [str(log) if a == "LOG" else a for a in argv]
    writes = [] if argv[0] == "evaluate" else ["-o", str(output)]  # evaluate only prints
    assert main([*argv, *writes]) == 1
    assert message in capsys.readouterr().err
    assert not output.exists()


def test_calibrate_real_square_runs_with_umbmark(tmp_path, capsys):
    from data import data_folder
    from diffdrive.io import read_robot

    runs = sorted((data_folder("optiodom-diffdrive") / "square" / "230620202042").glob("*run*"))
    output = tmp_path / "robot.toml"
    code, _, _ = run(
        ["calibrate", *runs, *OPTIODOM, "--method", "umbmark", "--square-side", 0.75, "-o", output],
        capsys,
    )
    assert code == 0
    assert read_robot(output)["track_width"] == pytest.approx(0.201458, abs=5e-7)


def test_calibrate_increments_a_window_at_a_time(tmp_path, capsys):
    from data import data_folder
    from diffdrive.io import read_robot

    runs = sorted((data_folder("optiodom-diffdrive") / "circular" / "250620202345").glob("*run*"))
    output = tmp_path / "robot.toml"
    argv = ["calibrate", *runs, *OPTIODOM, "--method", "increments", "--cv", "none", "-o", output]
    code, _, _ = run([*argv, "--window", 20], capsys)
    assert code == 0
    windowed = read_robot(output)
    # The same as the library's fit, which the calibration guide's table scores (12.3 mm in-sample).
    nominal, read = dd.io.optiodom_robot(), [dd.io.read_run(path) for path in runs]
    robot = dd.calibration.calibrate(
        nominal, read, "increments", dd.calibration.Increments(20)
    ).robot
    assert windowed["track_width"] == pytest.approx(robot.track_width, rel=1e-12)
    code, _, err = run([*argv, "--window", 20, "--method", "minimax"], capsys)
    assert code == 1
    assert "window is for the increments method only; got 20 with minimax" in err
    code, _, err = run([*argv, "--square-side", 1.0], capsys)  # was silently ignored
    assert code == 1
    assert "square_side is for the umbmark method only; got it with increments" in err
    with pytest.raises(SystemExit, match="2"):
        run([*argv, "--window", 0], capsys)
    assert "argument --window: must be at least 1, got 0" in capsys.readouterr().err


def test_calibrate_refuses_runs_that_cannot_fix_the_track(tmp_path, capsys):
    rows = "\n".join(f"{k * 0.05},{k * 0.5},{k * 0.5},{k * 0.021},0,0" for k in range(50))
    log = tmp_path / "straight.csv"
    log.write_text("t,left_angle,right_angle,x,y,theta\n" + rows + "\n")
    code, _, err = run(["calibrate", log, *OPTIODOM, "-o", tmp_path / "robot.toml"], capsys)
    assert code == 1
    assert "too little to identify the track_width" in err
    assert not (tmp_path / "robot.toml").exists()


def test_evaluate_a_trajectory_against_ground_truth(tmp_path, capsys):
    truth, estimate = tmp_path / "truth.csv", tmp_path / "estimate.csv"
    truth.write_text("t,x,y,theta\n0,0,0,0\n1,1,0,0\n2,2,0,0\n")
    estimate.write_text("t,x,y,theta\n0,0,0,0\n1,1,0.1,0\n2,2,0.2,0\n")
    code, out, _ = run(["evaluate", estimate, "--truth", truth, "--json"], capsys)
    assert code == 0
    metrics = json.loads(out)
    assert metrics["max_position_error_m"] == pytest.approx(0.2)
    assert metrics["ate_m"] == pytest.approx(np.sqrt((0.01 + 0.04) / 3))
    # evo's default pairs, consecutive along the estimate: (0, 1) and (1, 2)
    assert metrics["rpe_1m_consecutive_m"] == pytest.approx(0.1)


def test_evaluate_needs_times_that_pair(tmp_path, capsys):
    truth, estimate = tmp_path / "truth.csv", tmp_path / "estimate.csv"
    truth.write_text("t,x,y,theta\n0,0,0,0\n1,1,0,0\n")
    estimate.write_text("t,x,y,theta\n0,0,0,0\n2,1,0,0\n")
    code, _, err = run(["evaluate", estimate, "--truth", truth], capsys)
    assert code == 1
    assert "truth.csv: 1 of its times are within --t-max-diff 0.01 s" in err


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--t-max-diff", "-1"], "--t-max-diff must be finite and >= 0, got -1.0"),
        (["--t-offset", "nan"], "--t-offset must be finite, got nan"),
        (["--rpe", "0"], "--rpe must be finite and > 0, got 0.0"),
    ],
)
def test_evaluate_names_the_option_it_refuses(tmp_path, capsys, option, message):
    truth = tmp_path / "truth.csv"
    truth.write_text("t,x,y,theta\n0,0,0,0\n1,1,0,0\n")
    code, _, err = run(["evaluate", truth, "--truth", truth, *option], capsys)
    assert code == 1
    assert message in err


@pytest.mark.slow
def test_calibrate_and_evaluate_run_as_subprocesses(tmp_path):
    for argv in (["calibrate", "-q"], ["evaluate"]):
        result = subprocess.run(
            [sys.executable, "-m", "diffdrive", *argv],
            capture_output=True,
            text=True,
            cwd=tmp_path,
        )
        assert result.returncode == 0, result.stderr
    assert (tmp_path / "robot.toml").exists()
    assert "ate_aligned_m" in result.stdout


@pytest.mark.slow
def test_what_calibrate_reports_is_what_its_robot_file_gives(tmp_path, capsys):
    """The largest error calibrate prints is the one odometry gets with the file it wrote, even
    with a heading offset fitted (the reference's, which the file does not carry)."""
    from data import data_folder

    runs = sorted((data_folder("optiodom-diffdrive") / "free" / "030120210006").glob("*run*"))
    robot = tmp_path / "robot.toml"
    argv = ["calibrate", *runs, *OPTIODOM, "--integration", "rk2", "--cv", "none", "-o", robot]
    code, out, _ = run([*argv, "--extra", "axle_offset", "heading_offset"], capsys)
    assert code == 0
    assert "heading offset of the reference" in out
    assert "not in the robot file" in out
    claimed = float(out.split("m nominal, ")[1].split(" m calibrated")[0])
    worst = 0.0
    for path in runs:
        argv = ["odometry", path, "--robot", robot, "--method", "rk2", "-o", tmp_path / "o.csv"]
        code, printed, _ = run(argv, capsys)
        assert code == 0
        worst = max(worst, float(printed.split("position error max ")[1].split()[0]))
    assert worst == pytest.approx(claimed, abs=1e-4)


def test_a_long_evaluation_says_what_it_is_doing_on_a_terminal(tmp_path, capsys, monkeypatch):
    """A 10^6-pose evaluate was silent for 23 s; on a terminal each stage is named."""
    import sys

    from diffdrive.cli import evaluate

    truth = tmp_path / "truth.csv"
    truth.write_text("t,x,y,theta\n0,0,0,0\n1,1,0,0\n2,2,0,0\n")
    monkeypatch.setattr(evaluate, "_LARGE_FILE", 0)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["evaluate", str(truth), "--truth", str(truth), "--json"]) == 0
    err = capsys.readouterr().err
    assert "evaluate: reading the trajectory" in err
    assert "evaluate: pairing and measuring 3 poses" in err


# -- the robot: only its geometry counts as given ----------------------------------------------


@pytest.mark.parametrize(
    "argv",
    [
        ["export", "--to", "ros2", "--k", "1e-4"],
        ["plan", "WAYPOINTS", "--max-velocity", "1"],
        ["calibrate", "RUN"],
    ],
    ids=["export", "plan", "calibrate"],
)
def test_ticks_per_revolution_alone_is_not_a_robot(tmp_path, capsys, argv):
    """The encoders' resolution says nothing of the geometry: a command that writes the
    geometry (or what follows from it) refuses, naming the flags, and writes nothing."""
    waypoints, run_file = tmp_path / "w.csv", tmp_path / "run.csv"
    waypoints.write_text("x,y\n0,0\n1,0\n")
    run_file.write_text("t,left_ticks,right_ticks,x,y,theta\n0,0,0,0,0,0\n1,100,120,0.1,0,0\n")
    argv = [{"WAYPOINTS": waypoints, "RUN": run_file}.get(a, a) for a in argv]
    out = tmp_path / "out.yaml"
    code, _, err = run([*argv, "--ticks-per-revolution", "4096", "-o", out], capsys)
    assert code == 1
    assert "give --robot FILE, or --wheel-radius and --track-width" in err
    assert "(--ticks-per-revolution is the encoders', not the geometry)" in err
    robot = tmp_path / "ticks.toml"  # a robot file that holds only the encoders' resolution
    robot.write_text("ticks_per_revolution = 4096\n")
    code, _, err = run([*argv, "--robot", robot, "-o", out], capsys)
    assert code == 1
    assert "is the encoders', not the geometry" in err
    assert not out.exists()


def test_odometry_says_it_assumed_the_robot_when_told_only_the_ticks(tmp_path, capsys):
    log = tmp_path / "log.csv"
    log.write_text("t,left_ticks,right_ticks\n0,0,0\n0.1,100,120\n0.2,200,240\n")
    code, out, _ = run(
        ["odometry", log, "--ticks-per-revolution", "4096", "-o", tmp_path / "o.csv"], capsys
    )
    assert code == 0
    assert "robot: the built-in robot (42 mm wheels, track 0.2 m; assumed: give --robot)" in out
    code, out, _ = run(
        ["odometry", log, "--ticks-per-revolution", "4096", *ROBOT, "-o", tmp_path / "o.csv"],
        capsys,
    )
    assert code == 0
    assert "robot:" not in out


# -- what a new user trips over (issue 43) -----------------------------------------------------


def test_version_and_no_negative_zero(tmp_path, capsys):
    with pytest.raises(SystemExit, match="0"):
        main(["--version"])
    assert capsys.readouterr().out.strip() == f"diffdrive {dd.__version__}"
    code, out, _ = run(["fk", "1", "-1e-3"], capsys)
    assert code == 0
    assert "-0 " not in out  # vy was printed as -0 m/s
    waypoints = tmp_path / "w.csv"
    waypoints.write_text("x,y\n0,0\n1,0\n2,1\n3,1\n")
    plan = tmp_path / "p.csv"
    code, _, _ = run(["plan", waypoints, *ROBOT, "--max-velocity", "1", "-o", plan, "-q"], capsys)
    assert code == 0
    cells = plan.read_text().replace("\n", ",").split(",")
    assert "-0.0" not in cells


def test_a_path_shorter_than_the_rpe_window_still_gets_its_other_measures(tmp_path, capsys):
    short = tmp_path / "short.csv"
    short.write_text("t,x,y,theta\n0,0,0,0\n0.1,0.05,0,0\n0.2,0.1,0,0\n")
    code, out, err = run(["evaluate", short, "--truth", short, "--json"], capsys)
    assert code == 0
    metrics = json.loads(out)
    assert metrics["ate_m"] == 0.0
    assert metrics["rpe_1m_consecutive_m"] is None
    assert "the RPE over 1 m is not computed: no pair of poses is 1.0 m apart" in err


def test_option_errors_name_the_option(tmp_path, capsys):
    waypoints = tmp_path / "w.csv"
    waypoints.write_text("x,y\n0,0\n1,0\n2,1\n3,1\n")
    code = main(["plan", str(waypoints), *ROBOT, "--max-velocity", "1", "--stops", "1.5"])
    assert code == 1  # one line, as every value the command reads (argparse's usage, 2, before)
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "--stops takes waypoint indices (whole numbers from 0) separated by commas" in err
    code, _, err = run(["synth", "--time-offset", "0", "-o", tmp_path / "x.mcap"], capsys)
    assert code == 1
    assert "--time-offset 0: the bag's first stamp would be 0 s" in err
    with pytest.raises(SystemExit, match="0"):
        main(["plan", "--help"])
    helped = capsys.readouterr().out
    assert "robot (required: a robot file or the geometry flags" in helped
    assert "built-in example robot" not in helped


def test_a_folder_that_cannot_be_written_is_named_not_the_hidden_file(
    tmp_path, capsys, monkeypatch
):
    import tempfile

    def refused(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(tmp_path / ".x.abc123.csv"))

    monkeypatch.setattr(tempfile, "mkstemp", refused)
    code, _, err = run(["simulate", "-o", tmp_path / "x.csv"], capsys)
    assert code == 1
    assert f"cannot write {tmp_path / 'x.csv'}: Permission denied (in {tmp_path})" in err
    assert ".x.abc123" not in err


def test_a_missing_extra_is_one_line_naming_it(tmp_path, capsys, monkeypatch):
    """After make demo alone (no scipy, no rosbags) the commands that need them said so in a
    traceback."""
    import sys

    for module in ("scipy", "scipy.optimize", "scipy.linalg"):
        monkeypatch.setitem(sys.modules, module, None)
    waypoints = tmp_path / "w.csv"
    waypoints.write_text("x,y\n0,0\n2,0\n")
    argv = ["follow", waypoints, *ROBOT, "--max-velocity", "1", "--tracker", "ltv"]
    code, _, err = run([*argv, "-o", tmp_path / "f.csv"], capsys)
    assert code == 1
    assert "LTVUnicycle (the Riccati equation) needs scipy: pip install 'diffdrive[control]'" in err
    assert "Traceback" not in err
    code, _, err = run(["calibrate", "-o", tmp_path / "r.toml", "--cv", "none"], capsys)
    assert code == 1
    assert "calibration needs scipy: pip install 'diffdrive[calibration]'" in err


def test_the_first_plan_says_it_compiles(tmp_path, capsys, monkeypatch):
    import diffdrive.cli.plan as cli_plan

    monkeypatch.setattr(cli_plan, "compiles_first", lambda: True)
    waypoints = tmp_path / "w.csv"
    waypoints.write_text("x,y\n0,0\n2,0\n")
    code, _, err = run(
        ["plan", waypoints, *ROBOT, "--max-velocity", "1", "-o", tmp_path / "p.csv"], capsys
    )
    assert code == 0
    assert "compiling the path-timing kernel with numba, once" in err


@pytest.mark.slow
def test_a_closed_pipe_ends_quietly(tmp_path):
    """``diffdrive info BAG | head -1`` printed 'Broken pipe': a reader that goes away ends
    the command quietly, whenever it goes."""
    import subprocess
    import sys

    python = f"{sys.executable} -m diffdrive"
    commands = [f"{python} fk 1 2 | true", f"{python} fk 1 2 --json | true"]
    commands += [f"{python} simulate -o t.csv && {python} evaluate t.csv --truth t.csv | true"]
    for command in commands * 2:
        result = subprocess.run(command, shell=True, capture_output=True, text=True, cwd=tmp_path)
        assert "Broken pipe" not in result.stderr, command
        assert "Traceback" not in result.stderr, command
        assert "Exception ignored" not in result.stderr, command


@pytest.mark.slow
def test_gps_as_the_estimate_compares_positions(tmp_path, capsys):
    """evaluate with a NavSatFix topic as the estimate failed on its NaN heading."""
    pytest.importorskip("rosbags")
    bag = tmp_path / "run.mcap"
    gps = ["--gps", "48.1", "11.6", "520", "--pose-sigma", "0.3", "0.3", "0", "--seed", "1"]
    assert main(["synth", *gps, "-o", str(bag), "-q"]) == 0
    truth = ["--truth", bag, "--truth-topic", "/ground_truth", "--interpolate", "--json"]
    code, out, err = run(["evaluate", bag, "--topic", "/fix", *truth], capsys)
    assert code == 0, err
    metrics = json.loads(out)
    assert metrics["max_heading_error_deg"] is None
    assert 0.05 < metrics["ate_aligned_m"] < 1.0


def test_a_cusp_in_reverse_says_theta_is_the_robots_heading(tmp_path, capsys):
    waypoints = tmp_path / "w.csv"
    waypoints.write_text("x,y,theta\n0,0,0\n1,0,0\n")
    argv = ["plan", waypoints, *ROBOT, "--max-velocity", "1", "--reverse", "-o", tmp_path / "p.csv"]
    code, _, err = run(argv, capsys)
    assert code == 1
    assert "theta is the robot's heading: driving in reverse, the path leaves against it" in err


@pytest.mark.parametrize(
    ("old", "new"),
    [
        (["odometry", "--half-track=0.1"], ["odometry", "--robot", "half_track=0.1"]),
        (["odometry", "--frame", "map"], ["odometry", "--frames", "map", "base_link"]),
        (["animate", "t.csv", "--frame", "5"], ["animate", "t.csv", "--frame", "5"]),
        (
            ["odometry", "b.bag", "--gps-topic", "/fix", "--gate", "0.9", "--twist"],
            [
                "estimate",
                "b.bag",
                "--gps-topic",
                "/fix",
                "--settings",
                "gate.probability=0.9",
                "-o",
                "odometry.csv",
            ],
        ),
        (
            ["export", "--to", "ros2", "--left-joint", "l", "--right-joint", "r"],
            ["export", "ros2", "--joints", "l", "r"],
        ),
        (["synth", "--gyro-rrw", "1e-4"], ["synth", "--gyro", "rrw=1e-4"]),
        (["plan", "w.csv", "--method", "rk2"], ["plan", "w.csv"]),
        (["fk", "1", "2", "--json"], ["fk", "1", "2", "--json"]),
        # degrees then, radians now: renamed, the figures converted
        (
            ["odometry", "b.mcap", "--imu-rpy", "90", "-45", "0", "-q"],
            [
                "odometry",
                "b.mcap",
                "--imu-mount",
                repr(math.pi / 2),
                repr(-math.pi / 4),
                "0.0",
                "-q",
            ],
        ),
        (
            ["calibrate-driving", "b.mcap", "--reference-sigma", "0.02", "2"],
            ["calibrate-driving", "b.mcap", "--reference-noise", "0.02", repr(math.radians(2))],
        ),
        (
            ["calibrate-driving", "b.mcap", "--reference-sigma", "0.5", "--gps-topic", "/fix"],
            ["calibrate-driving", "b.mcap", "--reference-noise", "0.5", "--gps-topic", "/fix"],
        ),
    ],
)
def test_the_spellings_before_0_9_are_rewritten_to_todays(old, new):
    """Each old spelling becomes today's, with a note; one today's command still takes, or
    another meaning of the same letters (animate's --frame, argparse's short --frames), is
    left alone."""
    from diffdrive.cli import _options_of, renamed

    parser = build_parser()
    rewritten = renamed.today(old, lambda name: _options_of(parser, name))
    assert rewritten.argv == new
    assert bool(rewritten.notes) == (old != new)
    assert all("the old spelling goes in the next release" in n for n in rewritten.notes)
