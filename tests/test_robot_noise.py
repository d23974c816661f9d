"""The noise a calibration finds, kept in the robot file and read by the other commands."""

from dataclasses import replace

import pytest

from diffdrive.cli import main
from diffdrive.io import TableError, read_robot, read_robot_noise, write_robot
from diffdrive.sensor_noise import GyroNoise, WheelNoise

GEOMETRY = {"wheel_radius": 0.042, "track_width": 0.2}
WHEELS = WheelNoise(2.5e-4, 3.0e-4)
GYRO = GyroNoise(3e-3, 2e-4, 5e-3, 1e-4, 50.0)


def test_a_robot_files_noise_reads_back_beside_its_geometry(tmp_path):
    path = tmp_path / "robot.toml"
    write_robot(path, GEOMETRY, "a comment", {"wheel_noise": WHEELS, "gyro_noise": GYRO})
    assert read_robot(path) == GEOMETRY
    assert read_robot_noise(path) == {"wheel_noise": WHEELS, "gyro_noise": GYRO}
    write_robot(path, GEOMETRY)
    assert read_robot_noise(path) == {}


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ("[noise.slip]\nthreshold = 3.0\n", "unknown noise part 'slip'"),
        ("[noise.wheel_noise]\nleft = 1e-4\n", "noise.wheel_noise must give each of left, right"),
        ("[noise.wheel_noise]\nleft = -1e-4\nright = 1e-4\n", "noise.wheel_noise: wheel noise"),
        ("[noise.wheel_noise]\nleft = 'a'\nright = 1e-4\n", "noise.wheel_noise.left must be a"),
        ("noise = 3\n", "noise must be a table"),
    ],
)
def test_a_bad_noise_table_is_refused_naming_the_file_and_part(tmp_path, table, message):
    path = tmp_path / "robot.toml"
    path.write_text("wheel_radius = 0.042\ntrack_width = 0.2\n" + table)
    with pytest.raises(TableError, match=f"{path}: {message}"):
        read_robot_noise(path)


def test_write_robot_takes_only_the_noise_parts_it_can_write_back(tmp_path):
    path = tmp_path / "robot.toml"
    with pytest.raises(ValueError, match="not a robot file's noise part: 'gyro_noise'"):
        write_robot(path, GEOMETRY, noise={"gyro_noise": WHEELS})
    assert not path.exists()


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """A synthetic bag (wheels with k = 2e-4 m, a gyro, poses at 5 Hz) calibrated from
    driving: the robot file it writes."""
    folder = tmp_path_factory.mktemp("calibrated")
    bag, robot = folder / "run.mcap", folder / "robot.toml"
    synth = ["synth", "--k", "2e-4", "--gyro", "arw=3e-3", "--pose-sigma", "0.02", "0.02", "0.02"]
    assert main([*synth, "--pose", "period=0.2", "--seed", "3", "-o", str(bag), "-q"]) == 0
    topics = ["--joints", "left_wheel_joint", "right_wheel_joint", "--pose-topic", "/pose"]
    geometry = ["--wheel-radius", "0.042", "--track-width", "0.2", "--hold", "gyro_bias"]
    assert main(["calibrate-driving", str(bag), *topics, "--gyro-topic", "/imu/data", *geometry,
                 "-o", str(robot), "-q"]) == 0  # fmt: skip
    return bag, robot


@pytest.mark.slow
def test_calibrate_driving_keeps_what_it_identified_for_the_other_commands(calibrated, capsys):
    """The wheels' k found (2.3e-4 m against the 2e-4 drawn) is written as a table the other
    commands read; the gyro's angle random walk, which this drive leaves undetermined, is not
    (its figure only weighed the fit)."""
    bag, robot = calibrated
    found = read_robot_noise(robot)
    assert set(found) == {"wheel_noise"}
    k = found["wheel_noise"].left
    assert found["wheel_noise"].right == k
    assert k == pytest.approx(2e-4, rel=0.3)
    assert "# kept for odometry, estimate and export: [noise.wheel_noise]" in robot.read_text()
    wheels = ["--joints", "left_wheel_joint", "right_wheel_joint"]
    capsys.readouterr()
    out = robot.parent / "odometry.csv"
    argv = ["odometry", str(bag), *wheels, "--gyro-topic", "/imu/data", "--robot", str(robot)]
    assert main([*argv, "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert f"wheel noise: k = {k:.3g} m left, {k:.3g} m right (from {robot}" in said


@pytest.mark.slow
def test_export_reads_the_wheels_k_from_the_robot_file(calibrated, tmp_path, capsys):
    """Without runs or --k, export takes the robot file's k: the same alphas as --k of it."""
    _, robot = calibrated
    k = read_robot_noise(robot)["wheel_noise"].left
    from_file, by_hand = tmp_path / "file.yaml", tmp_path / "hand.yaml"
    assert main(["export", "amcl", "--robot", str(robot), "-o", str(from_file), "-q"]) == 0
    assert main(["export", "amcl", "--robot", str(robot), "--k", repr(k), "-o", str(by_hand),
                 "-q"]) == 0  # fmt: skip
    strip = [line for line in from_file.read_text().splitlines() if not line.startswith("#")]
    assert strip == [line for line in by_hand.read_text().splitlines() if not line.startswith("#")]
    assert f"with the wheels' k from {robot}" in from_file.read_text()


def test_odometry_takes_a_robot_files_gyro_noise_and_says_so(tmp_path, capsys):
    """A robot file's gyro noise goes into the estimator's settings, and the report names the
    file: the heading's variance grows by its angle random walk, not the default's; --k over
    the file's wheel noise."""
    log = tmp_path / "log.csv"
    rows = [f"{0.01 * i},{0.1 * i},{0.12 * i},0.2" for i in range(200)]
    log.write_text("t,left_angle,right_angle,gyro_z\n" + "\n".join(rows) + "\n")
    variances = []
    for gyro in (GYRO, replace(GYRO, angle_random_walk=4 * GYRO.angle_random_walk)):
        robot, out = tmp_path / "robot.toml", tmp_path / "odometry.csv"
        write_robot(robot, GEOMETRY, noise={"wheel_noise": WHEELS, "gyro_noise": gyro})
        argv = ["odometry", str(log), "--robot", str(robot), "-o", str(out), "--gyro-bias", "0"]
        assert main([*argv, "--heading", "gyro", "--covariance"]) == 0
        said = capsys.readouterr().out
        assert f"gyro noise: from {robot}" in said
        assert f"(from {robot}; --k to give them)" in said
        last = out.read_text().splitlines()[-1].split(",")
        variances.append(float(last[9]))  # cov_thetatheta
    assert variances[1] > 10 * variances[0]
    assert main([*argv, "--k", "1e-5"]) == 0
    assert "(from" not in capsys.readouterr().out.split("wheel noise")[-1].split("\n")[0]
