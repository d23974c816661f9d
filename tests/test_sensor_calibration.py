"""The estimator started from a calibration: ``ReferenceCalibration.estimator_settings`` (the
wheels' scales against the robot the estimator runs, the gyro's bias, clock and scale, the
reference sensor's clock, lever arm and yaw in one ``EstimatorSettings``), the
``SensorCalibration`` part that carries the sensors' terms, and ``Gyro.calibrated``."""

import math

import numpy as np
import pytest

import diffdrive as dd
import reference_drive as scenario
from diffdrive.calibration import calibrate_to_reference
from diffdrive.calibration.reference import ReferenceCalibration
from diffdrive.estimation import (
    EstimatorSettings,
    Gyro,
    Measurement,
    PoseEstimator,
    Prior,
    SensorCalibration,
    estimate_trajectory,
    measurements_of,
)
from diffdrive.evaluation import ate
from diffdrive.sensor_noise import GyroNoise

NOMINAL = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)


def made(values: dict[str, float], errors: dict[str, float]) -> ReferenceCalibration:
    """A calibration of the ``values`` given (the rest 0), its covariance diagonal with
    ``errors``, as ``calibrate_to_reference`` would report it."""
    from diffdrive.calibration.reference import PARAMETERS

    row = np.zeros(len(PARAMETERS))
    for name, value in values.items():
        row[PARAMETERS.index(name)] = value
    names = tuple(name for name in PARAMETERS if name in values)
    covariance = np.diag([errors.get(name, 1e-6) ** 2 for name in names])
    robot = NOMINAL.with_geometry(*row[:3])
    return ReferenceCalibration(robot, names, row, covariance, covariance, 1.0, 100, ())


def test_the_scales_are_the_calibrated_geometry_against_the_robot_run():
    """Radii 1 % over and the track 0.31 m: against the nominal robot, the distance scale
    1.01 and the turn scale (0.101 / 0.31) / (0.1 / 0.3), each with the standard error the
    covariance carries (a central difference of the same ratio); against the calibrated robot
    both 1 with the same spread. The gyro's clock and the lever arm go into ``sensors``, what
    the calibration did not estimate stays as given."""
    errors = {"left_radius": 1e-4, "right_radius": 2e-4, "track": 1e-3}
    geometry = {"left_radius": 0.0505, "right_radius": 0.0505, "track": 0.31}
    found = made({**geometry, "lever_x": -0.2, "lever_y": 0.1, "gyro_offset": 0.02}, errors)
    given = EstimatorSettings(sensors=SensorCalibration(offset=0.3))
    settings = found.estimator_settings(NOMINAL, given)
    turn = (0.101 / 0.31) / (0.1 / 0.3)
    assert settings.distance_scale.start == pytest.approx(1.01, rel=1e-12)
    assert settings.turn_scale.start == pytest.approx(turn, rel=1e-12)
    distance_error = math.hypot(errors["left_radius"], errors["right_radius"]) / 0.1
    assert settings.distance_scale.sigma == pytest.approx(distance_error, rel=1e-9)
    parts = [
        (turn_of(0.0505 + h, 0.0505, 0.31) - turn_of(0.0505 - h, 0.0505, 0.31)) / (2 * h) * e
        for h, e in [(1e-7, errors["left_radius"])]
    ]
    parts.append(
        (turn_of(0.0505, 0.0505 + 1e-7, 0.31) - turn_of(0.0505, 0.0505 - 1e-7, 0.31))
        / 2e-7
        * errors["right_radius"]
    )
    parts.append(
        (turn_of(0.0505, 0.0505, 0.31 + 1e-7) - turn_of(0.0505, 0.0505, 0.31 - 1e-7))
        / 2e-7
        * errors["track"]
    )
    assert settings.turn_scale.sigma == pytest.approx(math.hypot(*parts), rel=1e-5)
    assert settings.sensors == SensorCalibration(
        gyro_offset=0.02, offset=0.3, lever_arm=(-0.2, 0.1)
    )
    assert settings.bias is None  # no gyro bias estimated: the log's own
    own = found.estimator_settings(found.robot)
    assert own.distance_scale.start == pytest.approx(1.0, rel=1e-12)
    assert own.turn_scale.start == pytest.approx(1.0, rel=1e-12)
    assert own.distance_scale.sigma == pytest.approx(settings.distance_scale.sigma / 1.01)


def turn_of(left: float, right: float, track: float) -> float:
    """The turn scale of a geometry against the nominal robot's."""
    return ((left + right) / track) / (0.1 / 0.3)


def test_wheels_that_differ_left_from_right_are_refused_against_a_robot_whose_do_not():
    """Calibrated radii 0.8 % apart (errors 0.1 %): no scale carries that onto the nominal
    robot, so it is refused, naming the difference and what to run with; against the
    calibrated robot it is taken."""
    found = made(
        {"left_radius": 0.05025, "right_radius": 0.04985, "track": 0.303},
        {"left_radius": 5e-5, "right_radius": 5e-5, "track": 1e-4},
    )
    refused = r"differ right from left by -0\.796% .*calibration's robot"
    with pytest.raises(ValueError, match=refused):
        found.estimator_settings(NOMINAL)
    assert found.estimator_settings(found.robot).distance_scale.start == pytest.approx(1.0)


@pytest.fixture(scope="module")
def calibrated_drive():
    """The camera-and-gyro drive (a camera at 10 Hz on a mount with a 50 ms clock, a gyro
    with a 1 % scale, a bias and a 20 ms clock), calibrated."""
    times, increments, stamps, poses, gyro = scenario.camera_and_gyro(4)
    found = calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
        wheel_noise=scenario.K, gyro=gyro, gyro_noise=GyroNoise(angle_random_walk=2e-3),
    )  # fmt: skip
    return times, increments, stamps, poses, gyro, found


@pytest.mark.slow
def test_the_settings_from_a_calibration_are_what_moving_the_sensors_by_hand_gives(
    calibrated_drive,
):
    """The whole calibration in one call, for the calibrated robot: the smoothed estimate
    with the camera's poses as they were stamped and read is the estimate with the gyro moved
    onto the wheels' clock and scale and each pose moved by hand (its stamp back by the clock,
    its heading back by the yaw, the mount's lever arm), to 1e-9; and it lies nearer the
    camera than the nominal robot with the raw streams (the camera's poses moved onto the
    body by the true mount)."""
    times, increments, stamps, poses, gyro, found = calibrated_drive
    times, increments = times[2:], increments[2:]  # inside the raw gyro and the moved one
    settings = found.estimator_settings(found.robot)
    sensors = settings.sensors
    assert sensors.gyro_offset == found.value("gyro_offset")
    assert sensors.gyro_scale == found.value("gyro_scale")
    assert sensors.lever_arm == (found.value("lever_x"), found.value("lever_y"))
    assert (sensors.offset, sensors.yaw) == (found.value("offset"), found.value("yaw"))
    inside = (stamps - sensors.offset >= times[0]) & (stamps - sensors.offset <= times[-1])
    raw = measurements_of("pose", stamps[inside], poses[inside], scenario.CAMERA)
    run = estimate_trajectory(
        found.robot, times, increments, gyro=gyro, measurements=raw, settings=settings
    )
    moved = poses[inside].copy()
    moved[:, 2] -= sensors.yaw
    by_hand = measurements_of(
        "pose", stamps[inside] - sensors.offset, moved, scenario.CAMERA, sensors.lever_arm
    )
    oracle = estimate_trajectory(
        found.robot, times, increments, measurements=by_hand,
        gyro=gyro.calibrated(sensors.gyro_offset, sensors.gyro_scale),
        settings=settings.replace(sensors=SensorCalibration()),
    )  # fmt: skip
    np.testing.assert_allclose(run.poses, oracle.poses, atol=1e-9)
    assert any(line.startswith("sensors, as given") for line in run.settings)
    assert run.used.sensors == sensors

    # Dead reckoning (no camera): the calibration's against the nominal robot's.
    body = camera_on_body(stamps[inside] - scenario.CLOCK, poses[inside])
    started = estimate_trajectory(
        found.robot, times, increments, gyro=gyro, settings=settings, smooth=False
    )
    plain = estimate_trajectory(scenario.NOMINAL, times, increments, gyro=gyro, smooth=False)
    errors = [
        ate(dd.evaluation.interpolate(times, e.poses, stamps[inside] - scenario.CLOCK), body)
        for e in (started, plain)
    ]
    assert errors[0] < 0.5 * errors[1]


def camera_on_body(stamps: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """The body's poses ``(K, 3)`` under the camera's, by the true mount."""
    mount = np.array(scenario.MOUNT)
    return dd.batch.compose(poses, dd.batch.inverse(np.broadcast_to(mount, poses.shape)))


def test_a_streaming_estimator_refuses_a_gyro_it_cannot_move_and_places_each_fix():
    """A streaming estimator takes each interval's gyro angle as given: a gyro offset or
    scale is refused, naming what to do. A lever arm in the settings is every position's
    without its own (the same estimate as one given with the fix), and one with another
    is refused, naming both."""
    with pytest.raises(ValueError, match=r"cannot move the gyro .* Gyro\.calibrated"):
        PoseEstimator(NOMINAL, EstimatorSettings(sensors=SensorCalibration(gyro_offset=0.1)))
    arm = (0.2, -0.1)
    placed = SensorCalibration(lever_arm=arm)
    start = {"initial_pose": (0, 0, 0), "initial_time": 0.0}
    estimators = [
        PoseEstimator(NOMINAL, EstimatorSettings("wheels", sensors=sensors), **start)
        for sensors in (placed, SensorCalibration())
    ]
    for step in range(1, 11):
        for estimator in estimators:
            estimator.update_increments(0.4, 0.6, 0.1 * step)
    estimators[0].add_position(1.0, (0.5, 0.3), 0.1)
    estimators[1].add_position(1.0, (0.5, 0.3), 0.1, lever_arm=arm)
    np.testing.assert_allclose(estimators[0].state, estimators[1].state, atol=1e-15)
    other = r"carries the lever arm \(0\.5, 0\.0\) m and the settings"
    with pytest.raises(ValueError, match=other):
        estimators[0].add_position(1.0, (0.5, 0.3), 0.1, lever_arm=(0.5, 0.0))
    moved = placed.placed(Measurement.make("heading", 2.0, [0.1], 0.01))
    assert moved.lever_arm == (0.0, 0.0)


def test_sensor_calibration_checks_itself_and_is_set_by_name():
    """Each field is checked where it is made, and the command line's ``--settings`` names
    reach it."""
    with pytest.raises(ValueError, match=r"gyro_scale must be > -1"):
        SensorCalibration(gyro_scale=-1.0)
    with pytest.raises(ValueError, match=r"lever_arm must be two finite numbers"):
        SensorCalibration(lever_arm=(1.0, math.nan))
    with pytest.raises(ValueError, match=r"SensorCalibration\.offset"):
        SensorCalibration(offset=math.inf)
    changed = EstimatorSettings().changed({"sensors.gyro_offset": 0.1, "sensors.yaw": 0.05})
    assert changed.sensors == SensorCalibration(gyro_offset=0.1, yaw=0.05)
    assert EstimatorSettings(distance_scale=Prior(0.97)).sensors == SensorCalibration()


def test_a_calibrated_gyro_is_the_stream_on_the_wheels_clock_and_scale():
    """``Gyro.calibrated(offset, scale)``: the angle over any stretch of the wheels' clock is
    the raw gyro's over the same stretch ``offset`` later, over ``1 + scale``; a wheel log
    the moved gyro no longer covers is refused naming the offset."""
    t = np.linspace(0.0, 10.0, 1001)
    raw = Gyro(t, 0.3 + 0.1 * np.sin(t))
    moved = raw.calibrated(0.05, 0.02)
    at = np.array([1.0, 4.5, 9.0])
    turned = np.diff(moved.angles(at))
    expected = np.diff(raw.angles(at + 0.05)) / 1.02
    np.testing.assert_allclose(turned, expected, rtol=1e-12)
    times = t[t <= 9.99]
    increments = np.zeros((len(times) - 1, 2))
    settings = EstimatorSettings("gyro", bias=0.0, sensors=SensorCalibration(gyro_offset=0.05))
    with pytest.raises(ValueError, match=r"moved by -0\.05 s onto the wheels' clock"):
        estimate_trajectory(NOMINAL, times, increments, gyro=raw, settings=settings)
