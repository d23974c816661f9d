"""calibration.track_from_gyro: the track width from the wheels' turn against a gyro's, on
synthetic runs with noise on either side, on the TurtleBot3 bag, and its refusal."""

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import sensors
from diffdrive.calibration import track_from_gyro
from diffdrive.estimation import Gyro
from diffdrive.sensor_noise import GyroNoise

TRUE = dd.DiffDrive(wheel_radius=0.05, track_width=0.31)
NOMINAL = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
T = np.arange(3001) * 0.02


def weaving(k, arw, seed=0):
    wheels = np.stack([6 + 4 * np.sin(0.6 * T[:-1]), 6 - 4 * np.sin(0.6 * T[:-1] + 0.5)], -1)
    path = dd.simulate(TRUE, wheels, times=T)
    encoders = sensors.encoder_readings(
        TRUE, T, path.poses, sensors.EncoderModel(wheel_noise=k), seed=seed
    )
    model = sensors.GyroModel(noise=GyroNoise(angle_random_walk=arw), bias=0.01)
    rates = sensors.gyro_readings(TRUE, T, path.poses, model, seed=seed + 1).rates[0]
    return np.diff(encoders.readings[0], axis=0), np.diff(Gyro(T, rates).angles(T))


def test_exact_wheels_and_a_noisy_gyro():
    increments, turned = weaving(k=0.0, arw=5e-3)
    found = track_from_gyro(
        NOMINAL, T, increments, turned, gyro_noise=GyroNoise(angle_random_walk=5e-3)
    )
    assert found.track == pytest.approx(0.31, rel=0.005)
    assert found.bias == pytest.approx(0.01, abs=1e-3)
    # Exact wheels put all the noise on the gyro: the fit is the bracket's end itself, which
    # the two formulas round apart by an ulp or so.
    rounding = 1e-12 * found.track
    assert min(found.bracket) - rounding <= found.track <= max(found.bracket) + rounding


def test_noise_on_both_sides_needs_their_ratio():
    """Very noisy wheels and a quiet gyro: told both noises, the fit finds the track within
    three standard errors (about 2 % each here), where the gyro-on-wheels fit, treating the
    wheels as exact, is off by three quarters."""
    for seed in range(3):
        increments, turned = weaving(k=2e-3, arw=1e-4, seed=seed)
        found = track_from_gyro(
            NOMINAL, T, increments, turned, wheel_noise=2e-3,
            gyro_noise=GyroNoise(angle_random_walk=1e-4),
        )  # fmt: skip
        assert abs(found.track - 0.31) < 3 * found.standard_error
        assert found.standard_error < 0.03 * 0.31
        assert found.bracket[0] > 1.5 * 0.31


@pytest.mark.slow
def test_the_turtlebot3_track_from_its_imu_alone():
    """Given the wheel radii the increments calibration finds, the IMU gives the 0.2955 m that
    calibration finds against /odom, within 1 %; a plain ratio misses by more than 2 %."""
    from data import data_folder
    from diffdrive.io import ros

    bag = data_folder("ros-bags") / "turtlebot3_fuse.bag"
    run = ros.read_joint_states(bag, "wheel_left_joint", "wheel_right_joint")
    imu = ros.read_imu(bag, "/imu")
    gyro = Gyro.from_imu(imu.times, imu.angular_velocity)
    inside = (run.times >= gyro.times[0]) & (run.times <= gyro.times[-1])
    times = run.times[inside]
    increments = run.increments()[inside[1:] & inside[:-1]]
    robot = dd.DiffDrive(left_wheel_radius=0.03256, right_wheel_radius=0.03252, track_width=0.287)
    found = track_from_gyro(robot, times, increments, np.diff(gyro.angles(times)))
    assert found.track == pytest.approx(0.2955, rel=0.01)
    assert abs(found.plain_ratio / 0.2955 - 1) > 0.02


def test_a_log_that_never_turns_is_refused():
    straight = np.full((100, 2), 0.1)
    with pytest.raises(ValueError, match="does not turn enough"):
        track_from_gyro(NOMINAL, np.arange(101) * 0.02, straight, np.zeros(100))
    with pytest.raises(ValueError, match="must agree"):
        track_from_gyro(NOMINAL, np.arange(10) * 0.02, straight, np.zeros(100))


def test_calibrate_finds_the_track_from_a_bag_imu(tmp_path, monkeypatch, capsys):
    from data import data_folder
    from diffdrive.cli import main

    monkeypatch.chdir(tmp_path)
    bag = str(data_folder("ros-bags") / "turtlebot3_fuse.bag")
    joints = ["--joints", "wheel_left_joint", "wheel_right_joint"]
    radii = ["--robot", "left_wheel_radius=0.03256,right_wheel_radius=0.03252"]
    gyro = ["--gyro-topic", "/imu"]  # the track is what it finds
    assert main(["calibrate-gyro", bag, *joints, *radii, *gyro, "-o", "robot.toml"]) == 0
    written = dd.io.read_robot(tmp_path / "robot.toml")
    assert written["track_width"] == pytest.approx(0.2955, rel=0.01)
    assert written["left_wheel_radius"] == 0.03256
    assert "track from the gyro: 0.2954" in capsys.readouterr().out
    with pytest.raises(SystemExit) as usage:
        main(["calibrate-gyro", bag, bag, *joints, *radii, *gyro, "-o", "two.toml"])
    assert usage.value.code == 2
    assert "unrecognized arguments" in capsys.readouterr().err
    argv = ["calibrate-gyro", bag, *joints, *gyro, "--track-width", "0.3", "-o", "x.toml"]
    assert main(argv) == 1
    assert "calibrate-gyro keeps the wheel radii" in capsys.readouterr().err
    # The spelling before 0.9, for one release: the same file, and a note.
    old = ["--left-joint", "wheel_left_joint", "--right-joint", "wheel_right_joint"]
    old += ["--left-wheel-radius", "0.03256", "--right-wheel-radius", "0.03252"]
    assert main(["calibrate", bag, *old, "--track-from-gyro", *gyro, "-o", "old.toml"]) == 0
    assert dd.io.read_robot(tmp_path / "old.toml") == written
    assert '"calibrate" without ground truth is now "calibrate-gyro"' in capsys.readouterr().err


def test_bad_noise_settings_and_a_reversed_gyro_are_refused():
    """NaN or negative k, a tick count of 0 (ZeroDivisionError) or below, and a gyro that
    turns against the wheels (a track of -0.3 m) were taken."""
    t = np.arange(201) * 0.02
    increments = np.stack([0.2 + 0.05 * np.sin(t[:-1]), 0.25 + 0.05 * np.cos(t[:-1])], -1)
    turned = (increments[:, 1] - increments[:, 0]) * 0.05 / 0.3
    robot = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
    assert track_from_gyro(robot, t, increments, turned).track == pytest.approx(0.3)
    for options, message in (
        ({"wheel_noise": float("nan")}, "wheel noise left must be finite"),
        ({"wheel_noise": -1e-4}, "wheel noise left must be a number >= 0"),
        ({"ticks_per_revolution": 0}, "ticks_per_revolution must be > 0"),
        ({"ticks_per_revolution": -5}, "ticks_per_revolution must be > 0"),
    ):
        with pytest.raises(ValueError, match=message):
            track_from_gyro(robot, t, increments, turned, **options)
    with pytest.raises(ValueError, match="the gyro turns against the wheels"):
        track_from_gyro(robot, t, increments, -turned)
