"""calibration.calibrate_to_reference: the wheels, a sensor's mount and clock and a gyro's
terms from ordinary driving against a camera's poses or GPS positions, on synthetic drives of
known parameters (``reference_drive``); what a drive cannot show refused by name; bad input
refused before any fit."""

import math
import re
from itertools import pairwise

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import reference_drive as scenario
from diffdrive import batch, sensors
from diffdrive.calibration import ReferenceSettings, calibrate_to_reference
from diffdrive.calibration.reference import UndeterminedError
from diffdrive.sensor_noise import GyroNoise

CAMERA_TRUTH = {
    "left_radius": scenario.TRUE.left_wheel_radius,
    "right_radius": scenario.TRUE.right_wheel_radius,
    "track": scenario.TRUE.track_width,
    "lever_x": scenario.MOUNT[0],
    "lever_y": scenario.MOUNT[1],
    "yaw": scenario.MOUNT[2],
    "offset": scenario.CLOCK,
}
GYRO_NOISE = GyroNoise(angle_random_walk=scenario.GYRO_ARW)


@pytest.fixture(scope="module")
def camera_drive():
    return scenario.drive(3)


@pytest.mark.slow
def test_a_camera_calibrates_the_wheels_its_mount_and_its_clock(camera_drive):
    """A 5-minute mixed drive, a camera at 10 Hz (2 cm, 1 degree): every parameter within the
    issue's targets (radii 0.1 %, track 0.15 %, lever arm 5 mm, yaw 0.2 degree, clock 2 ms)
    and within 3 of its standard errors; the noise as stated (chi-square near 1)."""
    times, increments, stamps, poses = camera_drive
    found = calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
        wheel_noise=scenario.K,
    )  # fmt: skip
    errors = found.standard_errors()
    assert found.estimated == tuple(CAMERA_TRUTH)
    targets = {"left_radius": 1e-3, "right_radius": 1e-3, "track": 1.5e-3}
    for name, true in CAMERA_TRUTH.items():
        value = found.value(name)
        assert abs(value - true) <= 3 * errors[name], name
        if name in targets:
            assert abs(value / true - 1) <= targets[name], name
    assert abs(found.value("lever_x") - CAMERA_TRUTH["lever_x"]) <= 0.005
    assert abs(found.value("lever_y") - CAMERA_TRUTH["lever_y"]) <= 0.005
    assert abs(found.value("yaw") - CAMERA_TRUTH["yaw"]) <= math.radians(0.2)
    assert abs(found.value("offset") - CAMERA_TRUTH["offset"]) <= 0.002
    assert 0.9 < found.chi2 < 1.1
    assert found.robot.track_width == found.value("track")
    assert any(line.startswith("track 0.30") and "known to" in line for line in found.report)
    assert np.allclose(np.diag(found.correlation), 1.0)


@pytest.mark.slow
def test_a_camera_and_a_gyro_calibrate_the_gyro_too():
    """The same drive with a gyro (1 % scale, 5e-3 rad/s bias, its clock 20 ms ahead, 2e-3
    rad/s/sqrt(Hz)): the gyro's terms within 3 of their standard errors, its clock within
    2 ms."""
    times, increments, stamps, poses, rates = scenario.camera_and_gyro(4)
    found = calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
        wheel_noise=scenario.K, gyro=rates, gyro_noise=GYRO_NOISE,
    )  # fmt: skip
    errors = found.standard_errors()
    truth = {
        "gyro_scale": scenario.GYRO["scale"],
        "gyro_bias": scenario.GYRO["bias"],
        "gyro_offset": scenario.GYRO["clock"],
    }
    for name, true in truth.items():
        assert abs(found.value(name) - true) <= 3 * errors[name], name
    assert abs(found.value("gyro_offset") - scenario.GYRO["clock"]) <= 0.002


@pytest.mark.slow
def test_gps_and_a_gyro_calibrate_the_wheels_the_antenna_and_both_clocks():
    """A 5-minute drive, GPS at 2 Hz with 0.5 m of noise: the radii and track within 3 of
    their standard errors, the antenna within 8 cm, the receiver's clock within 0.2 s and the
    gyro's within 5 ms."""
    times, increments, gyro, stamps, positions = scenario.gps_drive(2)
    found = calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, positions, sigma=scenario.GPS_SIGMA,
        gyro=gyro, gyro_noise=GYRO_NOISE, wheel_noise=scenario.K,
    )  # fmt: skip
    errors = found.standard_errors()
    assert "yaw" not in found.estimated
    assert "heading" in found.estimated
    for name, true in (
        ("left_radius", scenario.TRUE.left_wheel_radius),
        ("right_radius", scenario.TRUE.right_wheel_radius),
        ("track", scenario.TRUE.track_width),
    ):
        assert abs(found.value(name) - true) <= 3 * errors[name], name
    assert abs(found.value("lever_x") - scenario.ANTENNA[0]) <= 0.08
    assert abs(found.value("lever_y") - scenario.ANTENNA[1]) <= 0.08
    assert abs(found.value("offset") - scenario.GPS_CLOCK) <= 0.2
    assert abs(found.value("gyro_offset") - scenario.GYRO["clock"]) <= 0.005


@pytest.mark.slow
def test_the_noise_is_identified_from_the_log_from_figures_far_off():
    """The camera-and-gyro drive started from every noise figure wrong (the camera's twice
    over, the wheels' ten times, the gyro's five): REML finds each within 3 of its standard
    errors of the truth (2 cm, 1 degree, k 1e-5 m, 2e-3 rad/s/sqrt(Hz)), the chi-square then
    near 1, and the geometry as well calibrated as with the noise given."""
    times, increments, stamps, poses, rates = scenario.camera_and_gyro(4)
    found = calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, poses, sigma=(0.04, 0.04, 0.035),
        wheel_noise=1e-4, gyro=rates, gyro_noise=GyroNoise(angle_random_walk=1e-2),
        settings=ReferenceSettings(identify_noise=True),
    )  # fmt: skip
    assert found.noise is not None
    truth = {
        "wheels": scenario.K,
        "gyro": scenario.GYRO_ARW,
        "reference": scenario.CAMERA[0],
        "reference_heading": scenario.CAMERA[2],
    }
    assert set(found.noise.values) == set(truth)
    for name, true in truth.items():
        assert abs(found.noise.values[name] - true) <= 3 * found.noise.standard_errors[name], name
    assert found.noise.undetermined == ()
    assert abs(found.noise.values["reference"] / scenario.CAMERA[0] - 1) < 0.03
    assert 0.95 < found.chi2 < 1.05
    errors = found.standard_errors()
    for name, true in CAMERA_TRUTH.items():
        assert abs(found.value(name) - true) <= 3 * errors[name], name
    assert any(re.match(r"the wheels' k [0-9.e-]+ \+- .* identified from the log", line)
               for line in found.report)  # fmt: skip


@pytest.mark.slow
def test_a_log_the_identified_noise_does_not_describe_is_flagged(camera_drive, monkeypatch):
    """Where the fit's residuals stay larger than the identified terms say (the Husky's GPS
    without its gyro: chi-square 2.00), the report says so; here the misfit is made by hand
    on a log that fits, to hold the rule at ``MISFIT``."""
    from dataclasses import replace

    from diffdrive.calibration import reference

    real = reference.identify

    def misfit(*args):
        logs, result, noise = real(*args)
        return logs, replace(result, chi2=reference.MISFIT + 0.5), noise

    times, increments, stamps, poses = camera_drive
    options = dict(
        sigma=scenario.CAMERA,
        wheel_noise=scenario.K,
        settings=ReferenceSettings(identify_noise=("reference",)),
    )
    fits = calibrate_to_reference(scenario.NOMINAL, times, increments, stamps, poses, **options)
    assert not any("do not describe" in line for line in fits.report)
    monkeypatch.setattr(reference, "identify", misfit)
    flagged = calibrate_to_reference(scenario.NOMINAL, times, increments, stamps, poses, **options)
    assert flagged.report[-1].startswith("the residuals' chi-square per degree of freedom is 2.00")
    assert "do not describe this log's errors well" in flagged.report[-1]


@pytest.mark.slow
def test_gps_noise_is_identified_and_a_term_the_drive_cannot_split_is_named():
    """GPS at 2 Hz, started at 1 m of noise and every other figure off: the receiver's 0.5 m
    and the wheels' k found within 3 standard errors; the gyro's noise, seen on this drive
    only beside the wheels' turn noise, is named as not determined (yet weighs the fit)."""
    times, increments, gyro, stamps, positions = scenario.gps_drive(2)
    found = calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, positions, sigma=1.0, gyro=gyro,
        gyro_noise=GyroNoise(angle_random_walk=1e-2), wheel_noise=1e-4,
        settings=ReferenceSettings(identify_noise=True),
    )  # fmt: skip
    assert found.noise is not None
    noise, spread = found.noise.values, found.noise.standard_errors
    assert abs(noise["reference"] - scenario.GPS_SIGMA) <= 3 * spread["reference"]
    assert abs(noise["wheels"] - scenario.K) <= 3 * spread["wheels"]
    assert found.noise.undetermined == ("gyro",)
    assert any("gyro's angle random walk" in line and "not determined by this log" in line
               for line in found.report)  # fmt: skip
    assert abs(found.value("lever_x") - scenario.ANTENNA[0]) <= 0.08
    times, increments, gyro, stamps, positions = scenario.gps_drive(2, seconds=120.0)
    held = calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, positions, sigma=1.0, gyro=gyro,
        gyro_noise=GyroNoise(angle_random_walk=scenario.GYRO_ARW), wheel_noise=1e-4,
        settings=ReferenceSettings(identify_noise=("wheels", "reference")),
    )  # fmt: skip
    assert held.noise is not None
    assert set(held.noise.values) == {"wheels", "reference"}


@pytest.mark.slow
def test_a_drive_that_never_turns_is_refused_naming_what_it_cannot_show():
    """Straights alone: the lever arm cannot be seen, nor each radius apart from the other
    and the track; refused, naming them and the drive that would show them."""
    times, increments, stamps, poses = scenario.drive(5, seconds=60.0, kinds=1)
    with pytest.raises(UndeterminedError, match=r"does not determine lever_x .*: turn") as caught:
        calibrate_to_reference(
            scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
            wheel_noise=scenario.K,
        )  # fmt: skip
    assert {"lever_x", "lever_y"} <= set(caught.value.parameters)
    held = {"lever_x": scenario.MOUNT[0], "lever_y": scenario.MOUNT[1], "yaw": scenario.MOUNT[2]}
    with pytest.raises(ValueError, match=r"does not determine left_radius") as caught:
        calibrate_to_reference(
            scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
            wheel_noise=scenario.K,
            settings=ReferenceSettings(("left_radius", "right_radius", "track"), held),
        )  # fmt: skip
    assert re.search(r"sees least is of left_radius, right_radius.*and turn", str(caught.value))
    found = calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
        wheel_noise=scenario.K,
        settings=ReferenceSettings(
            ("left_radius", "right_radius", "lever_y", "offset"),
            {"track": scenario.TRUE.track_width, "lever_x": scenario.MOUNT[0],
             "yaw": scenario.MOUNT[2]},
        ),
    )  # fmt: skip
    assert found.estimated == ("left_radius", "right_radius", "lever_y", "offset")


@pytest.mark.slow
def test_wheels_counted_backwards_are_refused_not_calibrated_to_negative_radii(camera_drive):
    times, increments, stamps, poses = camera_drive
    with pytest.raises(ValueError, match=r"did not converge: the radii and track went to -0\.0"):
        calibrate_to_reference(
            scenario.NOMINAL, times, -increments, stamps, poses, sigma=scenario.CAMERA
        )


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t, i, s, p: (t, i, s[100:110], p[100:110]), "too short a log: 10 reference"),
        (lambda t, i, s, p: (t, i, s + 1e4, p), "the clocks do not overlap"),
        (lambda t, i, s, p: (t, i, s, p * 0 + [1.0, 2.0, 0.3]), "the reference hardly moves"),
        (lambda t, i, s, p: (t, i, s, np.where(p > 1e9, 0, np.nan)), "must be finite"),
        (lambda t, i, s, p: (t, i[:-1], s, p), r"increments must be \(T, 2\)"),
        (lambda t, i, s, p: (t, i, s[::-1], p), "stamps must be finite and increasing"),
        (lambda t, i, s, p: (t, i, s, p[:, :1]), r"\(K, 3\) poses or \(K, 2\) positions"),
    ],
)
def test_what_no_fit_can_use_is_refused_before_any_fit(camera_drive, change, message):
    times, increments, stamps, poses = change(*camera_drive)
    with pytest.raises(ValueError, match=message):
        calibrate_to_reference(
            scenario.NOMINAL, times, increments, stamps, poses, sigma=(0.02, 0.02, 0.02)
        )


@pytest.mark.parametrize(
    ("positions", "options", "message"),
    [
        (False, {"sigma": 0.02}, r"sigma must be \(x m, y m, theta rad\)"),
        (True, {"sigma": (0.1, 0.1, 0.1)}, "sigma must be one position noise"),
        (True, {"sigma": 0.5, "estimate": ("yaw",)}, "estimate must name some of .* for this"),
        (False, {"sigma": scenario.CAMERA, "gyro": "a gyro"}, "a gyro needs its noise"),
        (False, {"sigma": scenario.CAMERA, "initial": {"wheelbase": 1.0}}, "initial names 'wh"),
        (False, {"sigma": scenario.CAMERA, "identify_noise": ("slip",)}, "identify_noise must"),
        (False, {"sigma": scenario.CAMERA, "identify_noise": "wheels"}, "identify_noise must"),
        (False, {"sigma": scenario.CAMERA, "identify_noise": ("gyro",)}, "has none of them"),
    ],
)
def test_settings_that_do_not_fit_the_reference_are_refused(
    camera_drive, positions, options, message
):
    times, increments, stamps, poses = camera_drive
    if options.get("gyro") == "a gyro":
        options = {**options, "gyro": scenario.camera_and_gyro(3, seconds=30.0)[4]}
    reference = poses[:, :2] if positions else poses
    names = ("estimate", "initial", "identify_noise")
    fit = {name: options.pop(name) for name in names if name in options}
    with pytest.raises(ValueError, match=message):  # from the settings, or the calibration
        calibrate_to_reference(
            scenario.NOMINAL, times, increments, stamps, reference,
            settings=ReferenceSettings(**fit), **options,
        )  # fmt: skip


def test_an_absolute_sensor_measures_its_own_pose_on_its_own_clock():
    """``mount`` composes the robot's pose with the sensor's place; ``clock_offset`` shifts
    the stamps, not what was measured."""
    times = np.arange(101) * 0.1
    poses = np.column_stack([0.5 * times, np.zeros(101), 0.2 * times])
    model = sensors.AbsoluteModel(mount=(0.3, -0.1, 0.5), clock_offset=0.25)
    read = sensors.absolute_readings(scenario.NOMINAL, times, poses, model)
    np.testing.assert_allclose(read.times, times + 0.25)
    np.testing.assert_allclose(read.truth[0], batch.compose(poses, np.array([0.3, -0.1, 0.5])))
    with pytest.raises(ValueError, match=r"mount must be \(x, y, yaw\)"):
        sensors.AbsoluteModel(mount=(0.1, 0.2))
    with pytest.raises(ValueError, match="clock_offset must be finite"):
        sensors.AbsoluteModel(clock_offset=float("nan"))


angles = st.floats(-math.pi, math.pi)
coordinates = st.floats(-10, 10)


@settings(max_examples=50, deadline=None)
@given(st.tuples(coordinates, coordinates, angles), st.tuples(coordinates, coordinates, angles))
def test_relative_jacobians_are_the_derivatives_of_relative_to(pose, reference):
    """Against central differences of ``relative_to`` in each of the six inputs."""
    pose, reference = np.array(pose), np.array(reference)
    at_reference, at_pose = batch.relative_jacobians(pose, reference)
    step = 1e-6
    for column in range(3):
        shift = np.zeros(3)
        shift[column] = step
        by_reference = (
            batch.relative_to(pose, reference + shift) - batch.relative_to(pose, reference - shift)
        ) / (2 * step)
        by_pose = (
            batch.relative_to(pose + shift, reference) - batch.relative_to(pose - shift, reference)
        ) / (2 * step)
        np.testing.assert_allclose(at_reference[:, column], by_reference, atol=1e-6)
        np.testing.assert_allclose(at_pose[:, column], by_pose, atol=1e-6)


def test_diffdrive_calibrate_refuses_holding_what_the_reference_does_not_calibrate(
    tmp_path, capsys
):
    """``--hold yaw`` against GPS: refused before any fit, naming what GPS calibrates; nothing
    written. (The Husky's calibration itself is the calibration guide's shell block, which
    the tests run and whose printed lines they hold.)"""
    from data import data_folder
    from diffdrive.cli import main

    bag = data_folder("ros-bags") / "husky_robot_localization_test1.bag"
    held = tmp_path / "held.toml"
    argv = [
        "calibrate", str(bag), "--wheel-topic", "/husky_velocity_controller/odom",
        "--wheel-radius", "0.165", "--track-width", "0.555", "--gps-topic", "/fix",
        "--gyro-topic", "/imu/data", "--imu-mount", "1.5707963", "0", "0", "--hold", "yaw",
        "-o", str(held),
    ]  # fmt: skip
    assert main(argv) == 1
    assert "--hold yaw: not calibrated against this reference" in capsys.readouterr().err
    assert not held.exists()


@pytest.mark.parametrize("kind", ["gps", "poses"])
def test_a_reference_that_reports_no_covariance_has_its_noise_identified_from_a_start(
    kind, monkeypatch
):
    """Fixes or poses without a covariance are no longer refused: the noise is identified from
    the drive, starting at ``START_GPS`` or ``START_POSE``, and the line says so."""
    import argparse

    from diffdrive.cli import calibrate_driving
    from diffdrive.io import ros
    from diffdrive.io.ros.reader import OdometryTopic

    times, positions = np.arange(5.0), np.zeros((5, 2))
    fixes = argparse.Namespace(times=times, positions=positions, variance=np.zeros(5))
    poses = OdometryTopic(
        times, np.zeros((5, 3)), np.zeros((5, 3)), np.zeros((5, 3, 3)), np.zeros((5, 3, 3)),
        "map", "", "header", 0,
    )  # fmt: skip
    monkeypatch.setattr(ros, "read_navsatfix", lambda *args: fixes)
    monkeypatch.setattr(ros, "read_odometry", lambda *args: poses)
    args = argparse.Namespace(
        gps_topic="/fix" if kind == "gps" else None,
        pose_topic="/pose" if kind == "poses" else None, reference_noise=None, datum=None,
    )  # fmt: skip
    _, _, sigma, said = calibrate_driving._reference(args, "log.bag")
    if kind == "gps":
        assert sigma == calibrate_driving.START_GPS
        assert "noise 1 m (most fixes report no covariance: identified from the drive" in said
    else:
        start = calibrate_driving.START_POSE
        assert sigma == pytest.approx((start[0], start[0], math.radians(start[1])))
        assert "noise 0.05 m and 2 deg (most poses report no covariance: identified" in said


def test_diffdrive_calibrate_names_the_hold_that_leaves_out_what_a_drive_cannot_show(
    tmp_path, capsys, monkeypatch
):
    """A calibration refused for parameters the drive did not determine: the command exits 1,
    writes nothing, and ends the library's message with the --hold that leaves them out."""
    from data import data_folder
    from diffdrive.calibration.reference import UndeterminedError
    from diffdrive.cli import calibrate_driving, main

    def refuse(*args, **options):
        raise UndeterminedError("this log does not determine offset (...)", ("offset",))

    monkeypatch.setattr(calibrate_driving, "calibrate_to_reference", refuse)
    bag = data_folder("ros-bags") / "husky_robot_localization_test1.bag"
    written = tmp_path / "robot.toml"
    argv = [
        "calibrate", str(bag), "--wheel-topic", "/husky_velocity_controller/odom",
        "--wheel-radius", "0.165", "--track-width", "0.555", "--gps-topic", "/fix",
        "-o", str(written),
    ]  # fmt: skip
    assert main(argv) == 1
    assert "does not determine offset (...) (here: --hold offset)" in capsys.readouterr().err
    assert not written.exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["calibrate", "LOG", "--reference-sigma", "0.5"],
        ["calibrate-driving", "LOG", "--gps-topic", "/fix", "--track-from-gyro"],
        ["calibrate-driving", "LOG", "--gps-topic", "/fix", "--cv", "3"],
        ["calibrate", "LOG", "--gps-topic", "/fix", "--cv", "3"],
    ],
)
def test_diffdrive_calibrate_knows_only_its_own_jobs_options(tmp_path, capsys, argv):
    from diffdrive.cli import main

    log = tmp_path / "log.csv"
    log.write_text("t,left_angle,right_angle\n0,0,0\n1,1,1\n")
    out = tmp_path / "robot.toml"
    argv = [str(log) if a == "LOG" else a for a in argv]
    robot = ["--wheel-radius", "0.1", "--track-width", "0.3", "-o", str(out)]
    with pytest.raises(SystemExit) as usage:
        main([*argv, *robot])
    assert usage.value.code == 2
    assert "unrecognized arguments" in capsys.readouterr().err
    assert not out.exists()


def test_diffdrive_calibrate_from_driving_takes_one_bag(tmp_path, capsys):
    from diffdrive.cli import main

    log = tmp_path / "log.csv"
    log.write_text("t,left_angle,right_angle\n0,0,0\n1,1,1\n")
    out = tmp_path / "robot.toml"
    argv = [str(log), "--wheel-radius", "0.1", "--track-width", "0.3"]
    assert main(["calibrate-driving", *argv, "--gps-topic", "/fix", "-o", str(out)]) == 1
    assert "calibrate-driving calibrates a bag's drive; this is no bag" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["calibrate-driving", *argv, str(log), "--gps-topic", "/fix", "-o", str(out)])
    assert "unrecognized arguments" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow
def test_several_runs_of_poses_calibrate_together(camera_drive):
    """The drive cut in two runs (each re-started, their poses in frames of their own):
    together they find what the whole drive finds, within a standard error; GPS runs, each
    with a frame heading of its own, are refused together."""
    times, increments, stamps, poses = camera_drive
    whole = calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
        wheel_noise=scenario.K,
    )  # fmt: skip
    cut = len(times) // 2
    at = np.searchsorted(stamps, times[cut])
    moved = batch.compose(np.array([3.0, -1.0, 0.7]), poses[at:])  # another frame
    parts = calibrate_to_reference(
        scenario.NOMINAL, [times[: cut + 1], times[cut:]], [increments[:cut], increments[cut:]],
        [stamps[:at], stamps[at:]], [poses[:at], moved], sigma=scenario.CAMERA,
        wheel_noise=scenario.K,
    )  # fmt: skip
    errors = whole.standard_errors()
    for name in CAMERA_TRUTH:
        assert abs(parts.value(name) - whole.value(name)) <= errors[name], name
    assert parts.readings == whole.readings - 20  # 1 s off each run's new end, at 10 Hz
    with pytest.raises(ValueError, match="GPS positions need each run's own frame heading"):
        calibrate_to_reference(
            scenario.NOMINAL, [times[: cut + 1], times[cut:]],
            [increments[:cut], increments[cut:]], [stamps[:at], stamps[at:]],
            [poses[:at, :2], poses[at:, :2]], sigma=0.5,
        )  # fmt: skip
    with pytest.raises(ValueError, match="lists of one length"):
        calibrate_to_reference(
            scenario.NOMINAL, [times], [increments, increments], [stamps], [poses],
            sigma=scenario.CAMERA,
        )  # fmt: skip


def test_every_calibration_refuses_wheels_that_cannot_be_the_robots(tmp_path, capsys):
    """Wheel angles in milliradians read as radians (1,000 times too large, a wrong unit):
    the ground-truth calibration, the track from a gyro and the export refuse them, naming the
    speed at the rim, and write nothing (they took them as read before)."""
    from diffdrive.cli import main

    t = np.arange(101) * 0.1
    angles = 1000.0 * np.column_stack([t, 1.1 * t])  # mrad: 0.1 m/s at a 0.1 m rim
    log = tmp_path / "log.csv"
    rows = ["t,left_angle,right_angle,x,y,theta,gyro_z"] + [
        f"{ti},{a},{b},{0.1 * ti},0,{0.02 * ti},0.02" for ti, (a, b) in zip(t, angles, strict=True)
    ]
    log.write_text("\n".join(rows) + "\n")
    robot = ["--wheel-radius", "0.1", "--track-width", "0.3"]
    out = tmp_path / "robot.toml"
    for extra in ([], ["--track-from-gyro"]):
        assert main(["calibrate", str(log), *robot, *extra, "-o", str(out)]) == 1
        assert "faster than any wheeled robot drives" in capsys.readouterr().err
        assert not out.exists()
    written = tmp_path / "w.json"
    argv = ["export", "--to", "wpilib", str(log), *robot, "-o", str(written)]
    assert main(argv) == 1
    assert "faster than any wheeled robot drives" in capsys.readouterr().err
    assert not written.exists()


@pytest.fixture(scope="module")
def short_drive():
    """A 2-minute camera-and-gyro drive."""
    return scenario.camera_and_gyro(8, seconds=120.0)


@pytest.mark.parametrize(
    ("factor", "cause"),
    [
        (-1.0, r"turns -0\.99\d times .*: it turns the other way: its z axis points down"),
        (180 / math.pi, r"turns 57\.\d times .*: degrees per second read as radians\?"),
        (0.0, r"turns -?0 times .*: it sees almost none of the turn: the wrong axis"),
    ],
    ids=["reversed", "degrees", "another axis"],
)
def test_a_gyro_that_is_not_the_wheels_is_refused_by_its_cause(short_drive, factor, cause):
    """A reversed gyro was refused for a clock offset of -21 s (the fit had gone anywhere):
    the gyro's turn against the wheels' before any fit names the cause."""
    from diffdrive.estimation.imu import Gyro

    times, increments, stamps, poses, gyro = short_drive
    wrong = Gyro(gyro.times, factor * gyro.rates)
    with pytest.raises(ValueError, match=cause):
        calibrate_to_reference(
            scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
            wheel_noise=scenario.K, gyro=wrong, gyro_noise=GYRO_NOISE,
        )  # fmt: skip


@pytest.mark.slow
def test_a_fit_that_diverges_from_a_given_start_names_the_start(short_drive):
    """An initial lever arm of 50 m was refused as wheels counting backwards."""
    times, increments, stamps, poses, _ = short_drive
    with pytest.raises(ValueError, match=r"did not converge from the initial values given "
                       r"\(lever_x 50\): the radii and track went to .* Start nearer"):  # fmt: skip
        calibrate_to_reference(
            scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
            wheel_noise=scenario.K, settings=ReferenceSettings(initial={"lever_x": 50.0}),
        )  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("runs", [2, 3])
def test_a_run_that_fits_none_is_named_among_several(short_drive, runs):
    """Run 2's poses from another drive (its positions run backwards) was refused as a
    track the drive did not determine (with two runs) or passed into the others' fit: the
    run that misfits even alone is named; the same runs with their own poses calibrate."""
    times, increments, stamps, poses, _ = short_drive
    cuts = [len(times) * i // runs for i in range(runs + 1)]
    cuts[-1] = len(times) - 1
    ats = [int(np.searchsorted(stamps, times[c])) for c in cuts]
    ats[-1] = len(stamps)
    parts = {
        "times": [times[a : b + 1] for a, b in pairwise(cuts)],
        "increments": [increments[a:b] for a, b in pairwise(cuts)],
        "stamps": [stamps[a:b] for a, b in pairwise(ats)],
    }
    own = [poses[a:b] for a, b in pairwise(ats)]
    found = calibrate_to_reference(
        scenario.NOMINAL, *parts.values(), own, sigma=scenario.CAMERA, wheel_noise=scenario.K
    )
    assert found.chi2 < 1.5
    other = [p.copy() for p in own]
    other[1][:, :2] = other[1][::-1, :2]
    with pytest.raises(ValueError, match=rf"run 2 of {runs} does not fit, even alone"):
        calibrate_to_reference(
            scenario.NOMINAL, *parts.values(), other, sigma=scenario.CAMERA, wheel_noise=scenario.K
        )


def test_the_turn_variances_are_the_odometrys_heading_variance_and_the_gyros():
    """``turn_variances`` (the wheels-against-gyro rows' variance the fit's weights move
    with) is, over each stretch, ``Odometry``'s heading variance from the same increments
    (an independent propagation) plus the gyro's angle random walk over it."""
    from diffdrive.calibration._reference_model import Log, turn_variances
    from diffdrive.estimation import Odometry
    from diffdrive.sensor_noise import WheelNoise
    from diffdrive.types import Pose

    times, increments, stamps, poses, gyro = scenario.camera_and_gyro(1, seconds=20.0)
    wheels = WheelNoise(2e-5, 3e-5)
    log = Log(scenario.NOMINAL, times, increments, stamps, poses, np.array(scenario.CAMERA),
              wheels, gyro, 2e-3, "exact")  # fmt: skip
    values = np.zeros(11)
    values[:3] = 0.0502, 0.0499, 0.304
    values[7] = 0.01  # the gyro's scale
    found = turn_variances(log, values)
    drive = scenario.NOMINAL.with_geometry(*values[:3])
    cut = np.clip(np.searchsorted(times, stamps), 0, len(times) - 1)
    for k in (0, 7, len(stamps) - 2):
        odometry = Odometry(drive, "exact", Pose(), wheel_noise=wheels)
        rows = increments[cut[k] : cut[k + 1]]
        odometry.update_arrays("increments", rows[:, 0], rows[:, 1])
        gyro_part = 2e-3**2 * (stamps[k + 1] - stamps[k]) / 1.01**2
        assert found[k] == pytest.approx(odometry.covariance[2, 2] + gyro_part, rel=1e-9)


@pytest.mark.slow
def test_the_track_beside_a_gyro_has_no_errors_in_variables_bias(monkeypatch):
    """Wheels four times noisier than the scenario's (k = 4e-5 m), a camera and a gyro, four
    seeds: with the wheels-against-gyro rows' weights moving with the track, its error
    averages within 1.2 of its standard errors; held where they were taken (their variances
    made constant), the same seeds' track comes out more than 2.5 of them high on average
    (``benchmarks/bench_reference_calibration.py`` runs 40 seeds at three noises)."""
    from diffdrive.calibration import _reference_model as model

    def track_errors() -> list[float]:
        errors = []
        for seed in range(4):
            monkeypatch.setattr(scenario, "K", 4e-5)
            times, increments, stamps, poses, gyro = scenario.camera_and_gyro(seed)
            found = calibrate_to_reference(
                scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
                wheel_noise=4e-5, gyro=gyro, gyro_noise=GYRO_NOISE,
            )  # fmt: skip
            error = found.value("track") - scenario.TRUE.track_width
            errors.append(error / found.standard_errors()["track"])
        return errors

    moving = track_errors()
    monkeypatch.setattr(
        model, "turn_variances", lambda log, values, angles_at=None: np.ones(len(log.stamps) - 1)
    )
    held = track_errors()
    assert abs(np.mean(moving)) < 1.2, moving
    assert np.mean(held) > 2.5, held
