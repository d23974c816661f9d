"""``diffdrive odometry`` with absolute measurements and the smoother: tables and bags in, the
estimate and its covariance out, and the refusals that name what is wrong."""

import json

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.cli import main
from diffdrive.cli.options import COVARIANCE_COLUMNS, TWIST_COVARIANCE_COLUMNS
from diffdrive.demo import EXAMPLE_TICKS_PER_REVOLUTION, example_encoder_log

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
        (["--turn-scale-sigma", "0.1"], "the turn scale also learns from measurements"),
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
        (["--gate", "0.99"], "--gate: used only with absolute measurements"),
        (
            ["--lever-arm", "0.1", "0", "--gps-sigma", "1"],
            "--gps-sigma, --lever-arm: used only with absolute",
        ),
        (["--imu-rpy", "0", "0", "90"], "--imu-rpy turns a bag's IMU (--gyro-topic)"),
        (["--imu-rpy", "0", "nan", "0"], "--imu-rpy must be three finite angles"),
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
        flat = matrices.reshape(-1, 9)
        for name, index in names.items():
            np.testing.assert_allclose(flat[:, index], table[name], rtol=1e-12, atol=1e-18)
    moving = np.abs(twists[:, 0]) > 0.1
    assert moving.mean() > 0.5  # the built-in path drives: the twist says so
    assert np.all(back.twist_covariances[moving, 0, 0] > 0)
    assert np.all(back.twist_covariances[:, 2, 2] > 0)


def test_no_wheel_noise_is_refused_for_a_bag(synthetic_bag, tmp_path, capsys):
    joints = ["--left-joint", "left_wheel_joint", "--right-joint", "right_wheel_joint"]
    argv = ["odometry", str(synthetic_bag), *joints, "--k-left", "0", "--k-right", "0"]
    assert main([*argv, "-o", str(tmp_path / "o.mcap")]) == 1
    assert "--k-left 0 --k-right 0: the /odom messages would carry zero" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
