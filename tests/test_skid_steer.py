"""Skid-steer robots: the ICR kinematics, the ideal case that is a differential drive, and
simulate, odometry and calibration on robots whose ICRs are wide, asymmetric or ahead."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive.calibration import CalibrationError, calibrate
from diffdrive.simulation import dead_reckon

ASYMMETRIC = dd.SkidSteer(0.11, 0.45, -0.40, icr_x=0.03)
WHEELS = np.random.default_rng(0).normal(8, 3, (300, 2))


def test_the_ideal_case_is_the_differential_drive_exactly():
    skid = dd.SkidSteer(0.05, 0.15, -0.15, icr_x=-0.02)
    drive = dd.DiffDrive(0.05, 0.3, axle_offset=0.02)
    for wheels in ([8.0, 10.0], [-5.0, 5.0], [3.0, 3.0]):
        assert skid.to_twist(wheels) == drive.to_twist(wheels)
        twist = drive.to_twist(wheels)
        assert skid.to_wheel_velocities(twist) == drive.to_wheel_velocities(twist)
    np.testing.assert_array_equal(
        dd.simulate(skid, WHEELS, dt=0.01).poses, dd.simulate(drive, WHEELS, dt=0.01).poses
    )
    a, b = dd.Odometry(skid), dd.Odometry(drive)
    for left, right in (WHEELS * 0.01).tolist():
        a.update_increments(left, right)
        b.update_increments(left, right)
    assert a.pose == b.pose


def test_the_icr_formulas_by_hand():
    """Left ICR 0.45 m, right -0.40 m: spread 0.85 m; side speeds 0.88 and 1.10 m/s."""
    twist = ASYMMETRIC.to_twist([8.0, 10.0])
    assert twist.omega == pytest.approx((1.10 - 0.88) / 0.85)
    assert twist.vx == pytest.approx((1.10 * 0.45 + 0.88 * 0.40) / 0.85)
    assert twist.vy == pytest.approx(-0.03 * twist.omega)
    back = ASYMMETRIC.to_wheel_velocities(twist)
    assert back.to_array() == pytest.approx([8.0, 10.0])
    assert ASYMMETRIC.turning_radius([8.0, 10.0]) == pytest.approx(twist.vx / twist.omega)
    wide = dd.SkidSteer.from_effective_track(0.165, 0.555, multiplier=1.875, wheels_per_side=2)
    assert wide.icr_spread == pytest.approx(0.555 * 1.875)
    assert wide.side_velocities([1.0, 3.0], [2.0, 2.0]) == dd.WheelVelocities(2.0, 2.0)


@given(st.lists(st.floats(-20, 20), min_size=2, max_size=2))
@settings(max_examples=60)
def test_batch_kinematics_equal_the_scalar_icr_formulas(wheels):
    twist = ASYMMETRIC.to_twist(wheels)
    np.testing.assert_allclose(
        dd.batch.to_twist(ASYMMETRIC, np.array(wheels)), twist.to_array(), atol=1e-12
    )
    np.testing.assert_allclose(
        dd.batch.to_wheel_velocities(ASYMMETRIC, twist.to_array()), wheels, atol=1e-9
    )


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_simulate_follows_the_body_origin_of_an_asymmetric_robot(backend):
    pytest.importorskip("numba") if backend == "numba" else None
    trajectory = dd.simulate(
        ASYMMETRIC, WHEELS, dt=0.01, initial_pose=[1.0, 2.0, 0.5], backend=backend
    )
    pose = dd.Pose(1.0, 2.0, 0.5)
    for wheels in WHEELS:
        pose = dd.integrate.step(pose, ASYMMETRIC.to_twist(wheels), 0.01)
    np.testing.assert_allclose(trajectory.final_pose, pose.to_array(), atol=1e-12)
    np.testing.assert_allclose(trajectory.twists[0], ASYMMETRIC.to_twist(WHEELS[0]).to_array())


def test_odometry_of_an_asymmetric_robot_equals_simulate_with_its_covariance_and_jacobians():
    start = dd.Pose(1.0, 2.0, 0.5)
    trajectory = dd.simulate(ASYMMETRIC, WHEELS, dt=0.01, initial_pose=start.to_array())
    odometry = dd.Odometry(ASYMMETRIC, initial_pose=start, wheel_noise=1e-4)
    for left, right in (WHEELS * 0.01).tolist():
        odometry.update_increments(left, right)
    np.testing.assert_allclose(odometry.pose.to_array(), trajectory.final_pose, atol=1e-12)
    batch = dd.Odometry(ASYMMETRIC, initial_pose=start, wheel_noise=1e-4)
    poses, covariances = batch.update_arrays("increments", *(WHEELS * 0.01).T, covariance=True)
    np.testing.assert_allclose(poses, trajectory.poses[1:], atol=1e-12)
    np.testing.assert_allclose(covariances[-1], odometry.covariance, atol=1e-15)
    # The Jacobians of the body pose, against central differences
    pose_jacobian, wheel_jacobian = odometry.jacobians(0.1, 0.3)

    def after(pose, left, right):
        probe = dd.Odometry(ASYMMETRIC, initial_pose=dd.Pose(*pose))
        probe.update_increments(left, right)
        return probe.pose.to_array()

    base, h = odometry.pose.to_array(), 1e-6
    numeric = np.column_stack(
        [
            (after(base + h * e, 0.1, 0.3) - after(base - h * e, 0.1, 0.3)) / (2 * h)
            for e in np.eye(3)
        ]
    )
    np.testing.assert_allclose(pose_jacobian, numeric, atol=1e-8)
    by_left = (after(base, 0.1 + h, 0.3) - after(base, 0.1 - h, 0.3)) / (2 * h)
    by_right = (after(base, 0.1, 0.3 + h) - after(base, 0.1, 0.3 - h)) / (2 * h)
    numeric = np.column_stack([by_left, by_right])
    np.testing.assert_allclose(wheel_jacobian, numeric, atol=1e-8)


def skid_runs(robot):
    t = np.arange(400) * 0.05
    histories = (
        np.stack([5 + 3 * np.sin(0.5 * t), 5 - 3 * np.sin(0.5 * t)], -1),
        np.tile([3.0, 7.0], (300, 1)),
        np.tile([-4.0, 4.0], (100, 1)),
    )
    return [(h * 0.05, dead_reckon(robot, h * 0.05, np.zeros(3))) for h in histories]


@pytest.mark.parametrize("method", ["least_squares", "increments"])
def test_calibration_recovers_a_skid_steer_robots_wide_icrs(method):
    """True ICRs 0.85 m apart (1.55 times the nominal 0.55 m), asymmetric, ahead by 3 cm."""
    nominal = dd.SkidSteer(0.11, 0.30, -0.25, icr_x=0.03)
    robot = calibrate(nominal, skid_runs(ASYMMETRIC), method).robot
    assert isinstance(robot, dd.SkidSteer)
    assert robot.icr_left == pytest.approx(0.45, abs=1e-6)
    assert robot.icr_right == pytest.approx(-0.40, abs=1e-6)
    assert robot.left_wheel_radius == pytest.approx(0.11, abs=1e-6)


def test_calibration_says_when_straight_runs_cannot_find_the_icr_spread():
    straight = [
        (
            np.tile([0.3, 0.3], (200, 1)),
            dead_reckon(ASYMMETRIC, np.tile([0.3, 0.3], (200, 1)), np.zeros(3)),
        )
    ]
    with pytest.raises(CalibrationError, match="too little to identify the track_width"):
        calibrate(dd.SkidSteer(0.11, 0.3, -0.25), straight)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: dd.SkidSteer(0.1, -0.2, 0.2), "icr_left must lie left of icr_right"),
        (lambda: dd.SkidSteer(0.1, 0.2), "give icr_left and icr_right"),
        (lambda: dd.SkidSteer(-0.1, 0.2, -0.2), "wheel_radius must be > 0"),
        (lambda: dd.SkidSteer(0.1, 0.2, -0.2, wheels_per_side=0), "wheels_per_side must be"),
        (lambda: dd.SkidSteer(0.1, 0.2, -0.2, icr_x=math.inf), "icr_x must be finite"),
        (
            lambda: dd.SkidSteer(0.1, 0.2, -0.2, wheels_per_side=2).side_velocities(1.0, [1, 2]),
            "left: 2 wheel velocities a side, got 1",
        ),
    ],
)
def test_bad_skid_steer_geometry_is_refused(make, message):
    with pytest.raises(ValueError, match=message):
        make()


@pytest.mark.slow
def test_the_command_line_takes_a_skid_steer_robot_file(tmp_path, capsys):
    from diffdrive.cli import main

    robot = tmp_path / "robot.toml"
    robot.write_text("wheel_radius = 0.11\nicr_left = 0.45\nicr_right = -0.40\nicr_x = 0.03\n")
    assert main(["fk", "8", "10", "--robot", str(robot), "--json"]) == 0
    assert '"omega": 0.2588' in capsys.readouterr().out
    assert main(["simulate", "--robot", str(robot), "-o", str(tmp_path / "s.csv"), "-q"]) == 0
    # Drawing it: the centre of curvature is the robot's ICR, at x = icr_x (this raised an
    # AttributeError, axle_offset, before).
    assert main(["plot", "--robot", str(robot), "-o", str(tmp_path / "p.png"), "-q"]) == 0
    assert (tmp_path / "p.png").stat().st_size > 10_000
    log = tmp_path / "gyro.csv"
    log.write_text("t,left_angle,right_angle,gyro_z\n0,0,0,0\n0.1,0.5,0.6,0.1\n0.2,1,1.3,0.1\n")
    # The gyro takes any robot model now (it was refused for a skid-steer robot file before).
    assert main(["odometry", str(log), "--robot", str(robot), "-o", str(tmp_path / "o.csv")]) == 0
    assert "fused heading" in capsys.readouterr().out


def test_gyro_odometry_runs_a_skid_steer_as_its_equivalent_drive():
    """The gyro filter runs the model's equivalent drive as Odometry does: with the heading
    from the wheels its poses are Odometry's, and its covariance is the equivalent drive's
    filter's, moved to the body origin."""
    from diffdrive.estimation import EstimatorSettings
    from diffdrive.estimation.gyro import GyroOdometry

    start = dd.Pose(0.3, -0.2, 0.4)
    offset = ASYMMETRIC.reference_offset
    settings = EstimatorSettings("wheels", wheel_noise=(1e-3, 2e-3))
    gyro = GyroOdometry(ASYMMETRIC, settings, initial_pose=start)
    drive = GyroOdometry(
        ASYMMETRIC.equivalent, settings, initial_pose=start.compose(dd.Pose(0, offset))
    )
    odometry = dd.Odometry(ASYMMETRIC, "exact", start)
    for left, right in WHEELS[:40] * 0.05:
        for estimator in (gyro, drive):
            estimator.update(left, right, 0.0, 0.05)
        odometry.update_increments(left, right)
        np.testing.assert_allclose(gyro.pose.to_array(), odometry.pose.to_array(), atol=1e-12)
        moved = ASYMMETRIC.covariance_from_reference(drive.pose.theta, drive.covariance)
        np.testing.assert_allclose(gyro.covariance, moved, rtol=1e-12, atol=1e-18)


@given(st.floats(-5, 5), st.floats(-5, 5), st.floats(-7, 7), st.floats(-3, 3), st.floats(-3, 3))
def test_the_reference_point_shift_is_one_rigid_motion_each_way(x, y, theta, vx, omega):
    """``to_reference`` and ``from_reference`` (poses), ``twist_to_reference`` and
    ``twist_from_reference`` (twists), one or in arrays, against the point ``(0, offset)`` of
    the body worked by hand; a DiffDrive's shift is none."""
    offset = ASYMMETRIC.reference_offset
    body = dd.Pose(x, y, theta)
    ahead = ASYMMETRIC.to_reference(body)
    want = [x - offset * math.sin(theta), y + offset * math.cos(theta), theta]
    np.testing.assert_allclose(ahead.to_array(), want, atol=1e-12)
    np.testing.assert_allclose(
        ASYMMETRIC.from_reference(ahead).to_array(), [x, y, theta], atol=1e-12
    )
    rows = np.array([[x, y, theta], [y, x, -theta]])
    np.testing.assert_allclose(ASYMMETRIC.to_reference(rows)[0], want, atol=1e-12)
    np.testing.assert_allclose(
        ASYMMETRIC.from_reference(ASYMMETRIC.to_reference(rows)), rows, atol=1e-12
    )
    # The body's twist (vx, 0, omega): the point offset m to the left moves at vx - offset omega.
    twist = dd.Twist(vx, 0.0, omega)
    at_point = ASYMMETRIC.twist_to_reference(twist)
    assert at_point.vx == pytest.approx(vx - offset * omega, abs=1e-12)
    assert ASYMMETRIC.twist_from_reference(at_point).vx == pytest.approx(vx, abs=1e-12)
    np.testing.assert_allclose(
        ASYMMETRIC.twist_to_reference(np.array([[vx, 0.0, omega]])), [at_point.to_array()]
    )
    plain = dd.DiffDrive(0.1, 0.5)
    assert plain.to_reference(body) == body
    assert plain.twist_from_reference(twist) == twist
    assert plain.from_reference(rows) is rows


@given(st.floats(-7, 7), st.floats(1e-4, 1.0), st.floats(-0.5, 0.5))
def test_the_covariance_shift_is_the_pose_shifts_jacobian_each_way(theta, spread, correlation):
    """``covariance_to_reference`` is ``J C J^T`` with ``J`` the derivative of
    ``to_reference`` (checked against central differences), ``covariance_from_reference``
    undoes it, arrays of headings move each covariance by its own, and a DiffDrive's is a
    copy of what it was given."""
    covariance = spread * np.array(
        [[1.0, correlation, 0.1], [correlation, 2.0, -0.2], [0.1, -0.2, 0.5]]
    )
    pose, h = np.array([0.3, -0.2, theta]), 1e-6
    numeric = np.column_stack(
        [
            (ASYMMETRIC.to_reference(pose + h * e) - ASYMMETRIC.to_reference(pose - h * e))
            / (2 * h)
            for e in np.eye(3)
        ]
    )
    np.testing.assert_allclose(ASYMMETRIC.jacobian_to_reference(theta), numeric, atol=1e-8)
    moved = ASYMMETRIC.covariance_to_reference(theta, covariance)
    np.testing.assert_allclose(moved, numeric @ covariance @ numeric.T, rtol=1e-6, atol=1e-12)
    back = ASYMMETRIC.covariance_from_reference(theta, moved)
    np.testing.assert_allclose(back, covariance, rtol=1e-9, atol=1e-15)
    many = ASYMMETRIC.covariance_to_reference([theta, -theta], np.stack([covariance] * 2))
    np.testing.assert_allclose(many[0], moved, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(
        many[1], ASYMMETRIC.covariance_to_reference(-theta, covariance), rtol=1e-12, atol=1e-15
    )
    plain = dd.DiffDrive(0.1, 0.5).covariance_from_reference(theta, covariance)
    assert plain is not covariance
    np.testing.assert_array_equal(plain, covariance)
