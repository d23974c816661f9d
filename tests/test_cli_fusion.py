"""``diffdrive odometry`` with absolute measurements and the smoother: tables and bags in, the
estimate and its covariance out, and the refusals that name what is wrong."""

import json
import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import batch
from diffdrive.cli import main
from diffdrive.cli.options import COVARIANCE_COLUMNS, TWIST_COVARIANCE_COLUMNS
from diffdrive.demo import EXAMPLE_TICKS_PER_REVOLUTION, example_encoder_log
from diffdrive.io.ros.covariance import FLOOR, floored

TICKS = ["--ticks-per-revolution", str(EXAMPLE_TICKS_PER_REVOLUTION)]


def write_table(path, columns):
    names = list(columns)
    rows = np.column_stack([columns[name] for name in names])
    path.write_text(
        ",".join(names) + "\n" + "\n".join(",".join(map(repr, r)) for r in rows.tolist())
    )


@pytest.fixture
def log_and_fixes(tmp_path, monkeypatch):
    """The built-in encoder log with its truth, and GPS-like fixes of the truth every 1 s with
    0.05 m noise; the odometry is told a ticks-per-revolution 3 % off, so it drifts."""
    monkeypatch.chdir(tmp_path)
    log = example_encoder_log()
    write_table(tmp_path / "log.csv", log)
    rng = np.random.default_rng(0)
    every = slice(0, None, 20)
    noise = rng.normal(size=(len(log["t"][every]), 2)) * 0.05
    fixes = {
        "t": log["t"][every],
        "x": log["x"][every] + noise[:, 0],
        "y": log["y"][every] + noise[:, 1],
        "sigma_x": np.full(len(noise), 0.05),
        "sigma_y": np.full(len(noise), 0.05),
    }
    write_table(tmp_path / "fixes.csv", fixes)
    return tmp_path, log


def final_error(path, log):
    table = np.genfromtxt(path, delimiter=",", names=True)
    return float(np.hypot(table["x"][-1] - log["x"][-1], table["y"][-1] - log["y"][-1])), table


def test_fixes_from_a_table_pull_a_drifting_odometry_back(log_and_fixes, capsys):
    folder, log = log_and_fixes
    wrong = ["--ticks-per-revolution", str(EXAMPLE_TICKS_PER_REVOLUTION * 1.03)]
    assert main(["odometry", "log.csv", *wrong, "-o", "plain.csv"]) == 0
    assert main(["odometry", "log.csv", *wrong, "--measurements", "fixes.csv", "-o", "f.csv"]) == 0
    printed = capsys.readouterr().out
    assert "refused by the gate" in printed
    assert "start pose in the measurements' frame" in printed
    smoothed = ["--measurements", "fixes.csv", "--smooth", "-o", "s.csv"]
    assert main(["odometry", "log.csv", *wrong, *smoothed]) == 0
    plain, _ = final_error(folder / "plain.csv", log)
    filtered, table = final_error(folder / "f.csv", log)
    smooth, _ = final_error(folder / "s.csv", log)
    assert filtered < 0.5 * plain
    assert smooth <= filtered + 1e-9
    assert {"cov_xx", "cov_yy", "cov_thetatheta"} <= set(table.dtype.names)
    assert np.all(table["cov_xx"] > 0)


def test_a_bag_pose_topic_is_fused(tmp_path, monkeypatch, capsys):
    pytest.importorskip("rosbags")
    monkeypatch.chdir(tmp_path)
    synth = ["synth", "--k-left", "1e-4", "--k-right", "1e-4", "--pose-sigma", "0.1", "0.1"]
    synth += ["0.05", "--pose-period", "0.5", "--pose-latency", "0.2", "--seed", "1"]
    assert main([*synth, "-o", "run.mcap"]) == 0
    joints = ["--left-joint", "left_wheel_joint", "--right-joint", "right_wheel_joint"]
    code = main(["odometry", "run.mcap", *joints, "--pose-topic", "/pose", "--smooth", "-q"])
    assert code == 0
    table = np.genfromtxt(tmp_path / "odometry.csv", delimiter=",", names=True)
    assert np.all(np.isfinite(table["cov_xx"]))


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--pose-topic", "/pose"], "--pose-topic and --gps-topic need a bag"),
        (["--measurements", "bad.csv"], "bad.csv:3"),
        (["--measurements", "nosigma.csv"], "give --gps-sigma M"),
        (["--measurements", "negative.csv"], "negative.csv:2: position measurement at t = 0"),
        (["--command-topic", "/cmd_vel"], "--command-topic: used only with a gyro"),
        (
            ["--gyro-bias", "0.01", "--slip-test", "interval"],
            "--gyro-bias, --slip-test: used only with a gyro",
        ),
        (["--turn-scale-sigma", "0.1"], "the turn scale learns from a gyro or absolute"),
        (["--measurements", "halfsigma.csv"], "gives all of sigma_x, sigma_y, sigma_theta or"),
        (
            ["--measurements", "unix.csv", "--gps-sigma", "0.1"],
            "none of the 2 measurements lies inside the log's",
        ),
    ],
)
def test_bad_measurements_are_refused_by_name_and_nothing_is_written(
    log_and_fixes, capsys, extra, message
):
    folder, _ = log_and_fixes
    (folder / "bad.csv").write_text("t,x,y,sigma_x,sigma_y\n0,0,0,1,1\n1,0,nan,1,1\n")
    (folder / "nosigma.csv").write_text("t,x,y\n0,0,0\n1,0,0\n")
    (folder / "negative.csv").write_text("t,x,y,sigma_x,sigma_y\n0,0,0,-0.1,0.1\n")
    (folder / "halfsigma.csv").write_text("t,x,y,theta,sigma_x,sigma_y\n0,0,0,0,1,1\n")
    (folder / "unix.csv").write_text("t,x,y\n1764630000,0,0\n1764630001,0,0\n")
    assert main(["odometry", "log.csv", *TICKS, *extra, "-o", "out.csv"]) != 0
    assert message in capsys.readouterr().err
    assert not (folder / "out.csv").exists()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--gate", "0.99"], "--settings gate: used only with absolute measurements"),
        (
            ["--lever-arm", "0.1", "0", "--gps-sigma", "1"],
            "--gps-sigma, --lever-arm: used only with absolute",
        ),
        (["--imu-mount", "0", "0", "1.5708"], "--imu-mount turns a bag's IMU (--gyro-topic)"),
        (["--imu-mount", "0", "nan", "0"], "--imu-mount must be three finite angles"),
    ],
)
def test_options_that_would_change_nothing_are_refused(log_and_fixes, capsys, extra, message):
    log = example_encoder_log()
    gyro = np.gradient(np.unwrap(log["theta"]), log["t"])
    write_table(log_and_fixes[0] / "gyro.csv", {**log, "gyro_z": gyro})
    assert main(["odometry", "gyro.csv", *TICKS, *extra, "-o", "out.csv"]) != 0
    assert message in capsys.readouterr().err
    assert not (log_and_fixes[0] / "out.csv").exists()


def test_the_turn_scale_option_reports_its_estimate(log_and_fixes, capsys):
    log = example_encoder_log()
    gyro = np.gradient(np.unwrap(log["theta"]), log["t"])
    write_table(log_and_fixes[0] / "gyro.csv", {**log, "gyro_z": gyro})
    code = main(["odometry", "gyro.csv", *TICKS, "--turn-scale-sigma", "0.1", "-o", "t.csv"])
    assert code == 0
    printed = capsys.readouterr().out
    scale = float(printed.split("turn scale at the end: ")[1].split()[0])
    assert scale == pytest.approx(1.0, abs=0.02)
    assert dd.DiffDrive  # the robot is the built-in one: its wheels turn as the robot does


def test_evaluate_says_how_honest_the_written_covariance_is(log_and_fixes, capsys):
    folder, log = log_and_fixes
    write_table(folder / "truth.csv", {k: log[k] for k in ("t", "x", "y", "theta")})
    noisy = ["--k-left", "1e-6", "--k-right", "1e-6", "--covariance", "-o", "odo.csv"]
    assert main(["odometry", "log.csv", *TICKS, *noisy]) == 0
    fused = ["--measurements", "fixes.csv", "--smooth", "-o", "fused.csv"]
    assert main(["odometry", "log.csv", *TICKS, *fused]) == 0
    capsys.readouterr()
    for name in ("odo.csv", "fused.csv"):
        assert main(["evaluate", name, "--truth", "truth.csv", "--consistency", "--json"]) == 0
        metrics = json.loads(capsys.readouterr().out)
        # the start (and any pose before the wheels first move) is known exactly: left out
        assert len(log["t"]) - 5 <= metrics["consistency_poses"] <= len(log["t"])
        assert metrics["consistency_dof"] == 3
        assert 0.0 < metrics["anees"] < 100.0
        assert 0.0 <= metrics["inside_50_percent"] <= metrics["inside_95_percent"] <= 1.0
    assert main(["evaluate", "truth.csv", "--truth", "truth.csv", "--consistency"]) != 0
    assert "a covariance is needed here" in capsys.readouterr().err


def test_plot_draws_the_errors_within_their_bands(log_and_fixes, capsys):
    folder, log = log_and_fixes
    write_table(folder / "truth.csv", {k: log[k] for k in ("t", "x", "y", "theta")})
    fused = ["--measurements", "fixes.csv", "--smooth", "-o", "fused.csv"]
    assert main(["odometry", "log.csv", *TICKS, *fused]) == 0
    capsys.readouterr()
    code = main(["plot", "fused.csv", "--truth", "truth.csv", "--errors", "-o", "bands.png"])
    assert code == 0
    share = float(capsys.readouterr().out.split(": ")[-1].split("%")[0])
    assert 0.0 <= share <= 100.0
    assert (folder / "bands.png").stat().st_size > 10_000
    assert main(["plot", "truth.csv", "--truth", "truth.csv", "--errors", "-o", "x.png"]) != 0
    assert "a covariance is needed here" in capsys.readouterr().err


# -- /odom: the twist and both covariances on every path ------------------------------------

PATHS = {
    "wheels": [],
    "gyro": ["--gyro-topic", "/imu/data", "--heading", "gyro", "--gyro-bias", "0.003"],
    "fused": ["--gyro-topic", "/imu/data"],
    "estimator": ["--gyro-topic", "/imu/data", "--pose-topic", "/pose"],
    "smoother": ["--pose-topic", "/pose", "--smooth"],
}


@pytest.fixture(scope="module")
def synthetic_bag(tmp_path_factory):
    """A bag of the built-in path: wheels with noise, a gyro with a bias, poses at 2 Hz."""
    pytest.importorskip("rosbags")
    folder = tmp_path_factory.mktemp("odom")
    synth = ["synth", "--k-left", "1e-5", "--k-right", "1e-5", "--gyro-bias", "0.003"]
    synth += ["--gyro-arw", "1e-3", "--pose-sigma", "0.05", "0.05", "0.02", "--pose-period"]
    synth += ["0.5", "--seed", "3", "-q", "-o", str(folder / "run.mcap")]
    assert main(synth) == 0
    return folder / "run.mcap"


@pytest.mark.slow
@pytest.mark.parametrize("path", list(PATHS))
@pytest.mark.parametrize("format", ["mcap", "ros2"])
def test_odom_carries_the_twist_and_both_covariances_of_the_csv(synthetic_bag, path, format):
    """Each bag written reads back (rosbags) with the twist, the pose covariance and the twist
    covariance of the CSV the same run writes; the twist is the robot's, not zero."""
    from diffdrive.io import ros

    folder = synthetic_bag.parent / f"{path}-{format}"
    folder.mkdir()
    joints = ["--left-joint", "left_wheel_joint", "--right-joint", "right_wheel_joint"]
    base = ["odometry", str(synthetic_bag), *joints, *PATHS[path], "-q"]
    bag = folder / ("odom.mcap" if format == "mcap" else "odom")
    assert main([*base, "-o", str(bag), "--format", format]) == 0
    table_path = folder / "odom.csv"
    assert main([*base, "-o", str(table_path), "--twist", "--covariance"]) == 0
    table = np.genfromtxt(table_path, delimiter=",", names=True)
    back = ros.read_odometry(bag, "/odom")
    np.testing.assert_allclose(back.times, table["t"], atol=2e-9)
    twists = np.column_stack([table[name] for name in ("vx", "vy", "omega")])
    np.testing.assert_allclose(back.twists, twists, rtol=1e-12, atol=1e-15)
    pairs = (
        (back.covariances, COVARIANCE_COLUMNS),
        (back.twist_covariances, TWIST_COVARIANCE_COLUMNS),
    )
    for matrices, names in pairs:
        written = np.zeros((len(table), 9))
        for name, index in names.items():  # the upper triangle, mirrored
            written[:, index] = written[:, 3 * (index % 3) + index // 3] = table[name]
        # The CSV's covariances as written; the bag's floored, so that a fuser can invert them.
        expected = floored(written.reshape(-1, 3, 3))
        np.testing.assert_allclose(matrices, expected, rtol=1e-12, atol=1e-18)
        assert np.all(np.linalg.eigvalsh(matrices)[:, 0] >= 0.999 * FLOOR)
    # vy: known zero, written as the floor rather than exactly 0
    np.testing.assert_allclose(back.twist_covariances[:, 1, 1], FLOOR, rtol=1e-6)
    moving = np.abs(twists[:, 0]) > 0.1
    assert moving.mean() > 0.5  # the built-in path drives: the twist says so
    assert np.all(back.twist_covariances[moving, 0, 0] > 0)
    assert np.all(back.twist_covariances[:, 2, 2] > 0)


@pytest.mark.slow
@pytest.mark.parametrize("path", ["wheels", "fused", "smoother"])
def test_every_odom_message_holds_covariances_a_fuser_can_invert(synthetic_bag, path):
    """Read back as robot_localization reads them, whole 6x6 matrices: each message's pose and
    twist covariance is positive definite (the twist's vy variance was exactly 0)."""
    pytest.importorskip("rosbags")
    from rosbags.highlevel import AnyReader

    bag = synthetic_bag.parent / f"pd-{path}.mcap"
    joints = ["--joints", "left_wheel_joint", "right_wheel_joint"]
    command = "odometry" if path == "wheels" else "estimate"
    assert main([command, str(synthetic_bag), *joints, *PATHS[path], "-q", "-o", str(bag)]) == 0
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == "/odom"]
        messages = [
            reader.deserialize(raw, connection.msgtype)
            for connection, _, raw in reader.messages(connections=connections)
        ]
    assert len(messages) > 100
    for message in messages:
        for covariance in (message.pose.covariance, message.twist.covariance):
            np.linalg.cholesky(np.asarray(covariance).reshape(6, 6))  # raises if not PD


def test_no_wheel_noise_is_refused_for_a_bag(synthetic_bag, tmp_path, capsys):
    joints = ["--joints", "left_wheel_joint", "right_wheel_joint"]
    argv = ["odometry", str(synthetic_bag), *joints, "--k", "0"]
    assert main([*argv, "-o", str(tmp_path / "o.mcap")]) == 1
    assert "--k 0: the /odom messages would carry zero" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


# -- time bases and frames ----------------------------------------------------------------------


@pytest.mark.slow
def test_a_synth_bag_holds_the_truth_on_its_own_clock(tmp_path, monkeypatch, capsys):
    """/ground_truth: the trajectory with its twists, stamped as the joints; a GPS fix with
    the covariance synth knows. A synth run's table and bag share one clock: the bag's
    estimate pairs pose for pose with the table's truth. Against the trajectory file (1 s
    earlier) evaluate refuses, naming the move and the --t-offset that undoes it."""
    pytest.importorskip("rosbags")
    from diffdrive.io import ros

    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--dt", "0.02", "-o", "traj.csv", "-q"]) == 0
    gps = ["--gps", "48.1", "11.6", "520", "--pose-sigma", "0.5", "0.4", "0", "--seed", "2"]
    assert main(["synth", "traj.csv", *gps, "-o", "run.mcap"]) == 0
    assert "the stamps are the trajectory's plus 1 s, in a table as in a bag" in (
        capsys.readouterr().out
    )
    assert main(["synth", "traj.csv", "--seed", "2", "-o", "run.csv", "-q"]) == 0
    table = np.genfromtxt("traj.csv", delimiter=",", names=True)
    run_table = np.genfromtxt("run.csv", delimiter=",", names=True)
    truth = ros.read_odometry("run.mcap", "/ground_truth")
    np.testing.assert_allclose(run_table["t"], truth.times, atol=2e-9)  # one clock
    joints = ros.read_joint_states("run.mcap", "left_wheel_joint", "right_wheel_joint")
    np.testing.assert_allclose(truth.times, joints.times, atol=2e-9)
    np.testing.assert_allclose(truth.times, table["t"] + 1.0, atol=2e-9)
    poses = np.column_stack([table["x"], table["y"], table["theta"]])
    np.testing.assert_allclose(truth.poses, poses, atol=1e-12)
    robot = dd.demo.example_robot()
    moving = np.abs(truth.twists[:, 0]) > 0.05
    assert moving.mean() > 0.5
    assert truth.frame == "world"
    assert np.all(
        np.abs(
            batch.to_twist(robot, robot.to_wheel_velocities(dd.Twist(*truth.twists[5])))
            - truth.twists[5]
        )
        < 1e-9
    )
    from rosbags.highlevel import AnyReader

    with AnyReader([tmp_path / "run.mcap"]) as reader:
        fixes = [c for c in reader.connections if c.topic == "/fix"]
        _, _, raw = next(reader.messages(connections=fixes))
        fix = reader.deserialize(raw, fixes[0].msgtype)
    assert fix.position_covariance_type == 2  # COVARIANCE_TYPE_DIAGONAL_KNOWN
    # the height synth does not vary: known, at the floor a reader can invert
    np.testing.assert_allclose(fix.position_covariance, np.diag([0.25, 0.16, FLOOR]).ravel())
    odometry = ["odometry", "run.mcap", "--left-joint", "left_wheel_joint", "--right-joint"]
    assert main([*odometry, "right_wheel_joint", "-o", "odo.csv", "-q"]) == 0
    assert main(["evaluate", "odo.csv", "--truth", "traj.csv", "--json"]) == 1
    captured = capsys.readouterr()
    assert "start +1 s and end +1 s apart, the same span moved by more than a period (0.02 s)" in (
        captured.err
    )
    assert "Give --t-offset -1" in captured.err
    assert captured.out == ""
    for truth_file in (["traj.csv", "--t-offset", "-1"], ["run.csv"]):
        assert main(["evaluate", "odo.csv", "--truth", *truth_file, "--json"]) == 0
        captured = capsys.readouterr()
        assert "warning" not in captured.err
        assert json.loads(captured.out)["max_heading_error_deg"] < 1e-6
    code = main(["evaluate", "odo.csv", "--truth", "run.mcap", "--truth-topic", "/ground_truth",
                 "--json"])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0
    assert "warning" not in captured.err
    assert json.loads(captured.out)["max_heading_error_deg"] < 1e-6


@pytest.mark.slow
def test_gps_fixes_without_a_covariance_are_identified_or_refused_by_name(
    tmp_path, monkeypatch, capsys
):
    """Fixes that come without a covariance (a NavSatFix with none): identified from
    themselves, and the command says so; too few to identify, or given, it names what to give
    and writes nothing. Six fixes 4 s apart are enough, their white noise held at its prior;
    two are not."""
    pytest.importorskip("rosbags")
    monkeypatch.chdir(tmp_path)
    joints = ["--left-joint", "left_wheel_joint", "--right-joint", "right_wheel_joint"]
    assert (
        main(["synth", "--gps", "48.1", "11.6", "520", "--seed", "4", "-o", "run.mcap", "-q"]) == 0
    )
    base = ["odometry", "run.mcap", *joints, "--gps-topic", "/fix", "--datum", "48.1", "11.6"]
    assert main([*base, "520", "-o", "est.csv"]) == 0
    printed = capsys.readouterr().out
    assert (
        "1001 of the 1001 fixes from /fix have no covariance: their noise is identified" in printed
    )
    assert "fixes identified" in printed
    assert main([*base, "520", "--fixes", "given", "-o", "given.csv"]) == 1
    assert "has no positive definite covariance: give --gps-sigma M" in capsys.readouterr().err
    synth = ["synth", "--gps", "48.1", "11.6", "520", "--seed", "4"]
    assert main([*synth, "--pose-period", "4", "-o", "sparse.mcap", "-q"]) == 0
    sparse = ["odometry", "sparse.mcap", *joints, "--gps-topic", "/fix", "-o", "sparse.csv"]
    assert main(sparse) == 0  # 6 fixes 4 s apart: identified, their white noise at its prior
    assert "white noise held at its prior: 6 fixes 4 s apart" in capsys.readouterr().out
    assert main([*synth, "--pose-period", "15", "-o", "few.mcap", "-q"]) == 0
    few = ["odometry", "few.mcap", *joints, "--gps-topic", "/fix", "-o", "few.csv"]
    assert main(few) == 1
    assert "2 fixes are too few to identify their noise from (at least 3): give --gps-sigma" in (
        capsys.readouterr().err
    )
    assert not (tmp_path / "few.csv").exists()
    assert not (tmp_path / "given.csv").exists()


@pytest.mark.slow
def test_gps_in_the_datums_frame_and_the_consistency_of_frames_apart(tmp_path, monkeypatch, capsys):
    """The GPS estimate in east-north at --datum lies in the truth's frame (at the first fix it
    is that fix's error off); --consistency in frames apart is named, and --align scores it."""
    pytest.importorskip("rosbags")
    monkeypatch.chdir(tmp_path)
    gps = ["--gps", "48.1", "11.6", "520", "--pose-sigma", "0.5", "0.5", "0", "--seed", "4"]
    assert (
        main(["synth", *gps, "--k-left", "1e-5", "--k-right", "1e-5", "-o", "run.mcap", "-q"]) == 0
    )
    joints = ["--left-joint", "left_wheel_joint", "--right-joint", "right_wheel_joint"]
    base = ["odometry", "run.mcap", *joints, "--gps-topic", "/fix", "--smooth", "-q"]
    assert main([*base, "-o", "first.csv"]) == 0
    assert main([*base, "--datum", "48.1", "11.6", "520", "-o", "datum.csv"]) == 0
    truth = ["--truth", "run.mcap", "--truth-topic", "/ground_truth", "--json"]
    errors = {}
    for name in ("first", "datum"):
        assert main(["evaluate", f"{name}.csv", *truth]) == 0
        errors[name] = json.loads(capsys.readouterr().out)
    assert errors["datum"]["ate_m"] < 0.1
    assert errors["first"]["ate_m"] > 3 * errors["datum"]["ate_m"]  # the first fix's error
    assert main(["odometry", "run.mcap", *joints, "--datum", "48", "11", "0", "-q"]) == 1
    assert "--datum: used only with --gps-topic" in capsys.readouterr().err
    # Wheel odometry (its own frame, turned) against the fixes (east-north): frames apart.
    odometry = ["odometry", "run.mcap", *joints, "--covariance", "-o", "odo.csv", "-q"]
    assert main([*odometry, "--k-left", "1e-3", "--k-right", "1e-3"]) == 0
    turned = np.genfromtxt("odo.csv", delimiter=",", names=True)
    rows = np.column_stack([turned[name] for name in turned.dtype.names])
    c, s = math.cos(0.5), math.sin(0.5)
    rows[:, 1], rows[:, 2] = c * turned["x"] - s * turned["y"], s * turned["x"] + c * turned["y"]
    rows[:, 3] += 0.5  # the same estimate in a frame turned by 0.5 rad
    with open("turned.csv", "w") as out:
        out.write(",".join(turned.dtype.names) + "\n")
        out.writelines(",".join(map(repr, row)) + "\n" for row in rows.tolist())
    truth = ["--truth", "run.mcap", "--truth-topic", "/ground_truth", "--consistency"]
    assert main(["evaluate", "odo.csv", *truth, "--json"]) == 0
    assert "warning" not in capsys.readouterr().err  # one frame
    assert main(["evaluate", "turned.csv", *truth, "--json"]) == 0
    captured = capsys.readouterr()
    assert "onto the truth by a rigid motion (turned -28.7 deg" in captured.err
    assert "--align scores the covariance" in captured.err
    assert json.loads(captured.out)["inside_95_percent"] < 0.1
    assert main(["evaluate", "turned.csv", *truth, "--align", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["inside_95_percent"] > 0.9


def test_the_start_pose_fit_puts_the_sensor_where_its_lever_arm_says(log_and_fixes, capsys):
    """Fixes of a sensor 0.3 m ahead and 0.1 m left of the body origin, exact: the start pose
    fitted from them is the truth's, not 0.3 m off."""
    folder, log = log_and_fixes
    theta = log["theta"]
    fixes = {
        "t": log["t"],
        "x": log["x"] + 0.3 * np.cos(theta) - 0.1 * np.sin(theta),
        "y": log["y"] + 0.3 * np.sin(theta) + 0.1 * np.cos(theta),
        "sigma_x": np.full(len(theta), 0.01),
        "sigma_y": np.full(len(theta), 0.01),
    }
    write_table(folder / "arm.csv", fixes)
    argv = ["odometry", "log.csv", *TICKS, "--measurements", "arm.csv", "-o", "a.csv"]
    assert main([*argv, "--lever-arm", "0.3", "0.1"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("start pose"))
    x, y = (float(v.strip(" (m")) for v in line.split(": ")[1].split(",")[:2])
    assert math.hypot(x - log["x"][0], y - log["y"][0]) < 0.005


# -- wheels from a drive controller's odometry or from twists ----------------------------------


def test_the_wheels_from_an_odometry_or_a_twist_topic(synthetic_bag, tmp_path, capsys):
    """A bag without joints gives its wheels as a controller's Odometry (the motion between its
    poses) or as Twist commands (each held): both drive the robot along the truth."""
    from diffdrive.io import ros

    truth = ros.read_odometry(synthetic_bag, "/ground_truth")
    robot = ["--wheel-radius", "0.042", "--track-width", "0.2"]  # the built-in robot's
    for topic, tolerance in (("/ground_truth", 1e-9), ("/cmd_vel", 1e-6)):
        out = tmp_path / f"{topic.strip('/')}.csv"
        argv = ["odometry", str(synthetic_bag), "--wheel-topic", topic, *robot, "-o", str(out)]
        assert main(argv) == 0
        assert f"{topic} (" in capsys.readouterr().out  # the report names what was read
        table = np.genfromtxt(out, delimiter=",", names=True)
        poses = np.column_stack([table["x"], table["y"], table["theta"]])
        at = np.searchsorted(truth.times, table["t"][-1])
        np.testing.assert_allclose(poses[-1], truth.poses[at] - truth.poses[0], atol=tolerance)
    argv = ["odometry", str(synthetic_bag), "--wheel-topic", "/imu/data", *robot]
    assert main(argv) == 1
    assert "/imu/data holds sensor_msgs/msg/Imu; a wheel topic is one of" in capsys.readouterr().err
    joints = ["--left-joint", "left_wheel_joint", "--right-joint", "right_wheel_joint"]
    assert main([*argv[:2], "--wheel-topic", "/cmd_vel", *joints, *robot]) == 1
    assert "the wheels come from joints or from /cmd_vel, not both" in capsys.readouterr().err


@pytest.mark.slow
def test_align_on_an_estimate_in_the_truths_frame_says_why_the_anees_jumps(
    tmp_path, monkeypatch, capsys
):
    """On synth's noise-free log ``evaluate --consistency --align`` printed an ANEES of about
    1e5 (1e10 on other runs) with no word of why: the alignment moves the exactly known start
    by its own residual. It says so, with the ANEES as the trajectory is."""
    pytest.importorskip("rosbags")
    monkeypatch.chdir(tmp_path)
    assert main(["synth", "-q", "-o", "run.mcap"]) == 0
    joints = ["--joints", "left_wheel_joint", "right_wheel_joint"]
    estimate = ["estimate", "run.mcap", *joints, "--gyro-topic", "/imu/data", "-q"]
    assert main([*estimate, "-o", "est.csv"]) == 0
    truth = ["--truth", "run.mcap", "--truth-topic", "/ground_truth", "--consistency"]
    assert main(["evaluate", "est.csv", *truth, "--align", "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["anees"] > 1e3
    assert "it is in the truth's frame already" in captured.err
    assert "leave --align out" in captured.err
    assert main(["evaluate", "est.csv", *truth, "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["anees"] < 1.0
    assert "warning" not in captured.err
