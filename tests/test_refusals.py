"""What a fuzz campaign found ending in a traceback or an internal message: each is refused
with its name (or, where it is a sensible input, accepted), and nothing is half-done."""

import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import export
from diffdrive.calibration import OnlineCalibrator, calibrate
from diffdrive.calibration.noise import NoiseModel
from diffdrive.estimation import EstimatorSettings as S
from diffdrive.estimation import SlipTest
from diffdrive.estimation.gyro import Gyro, GyroOdometry, gyro_odometry
from diffdrive.evaluation import worst

ROBOT = dd.DiffDrive(0.05, 0.3)
QUIET = Gyro([0.0, 3.0], [0.0, 0.0])


@pytest.mark.parametrize(
    ("call", "error", "message"),
    [
        (
            lambda: GyroOdometry(ROBOT, S(gyro_noise=3)),  # type: ignore[arg-type]
            TypeError,
            "EstimatorSettings.gyro_noise must be a GyroNoise, got 3",
        ),
        (
            lambda: GyroOdometry(ROBOT, "fused"),  # type: ignore[arg-type]
            TypeError,
            "settings must be an EstimatorSettings, got str",
        ),
        (lambda: Gyro([0, 1], [0, 0], max_gap="a"), TypeError, "max_gap must be a real number"),
        (lambda: Gyro([0, 1], [0, 0], max_gap=None), TypeError, "max_gap must be a real number"),
        (lambda: Gyro([0, 1], [0, 0], max_gap=math.nan), ValueError, "max_gap must be finite"),
        (lambda: gyro_odometry(ROBOT, 1.0, [[0, 0]], QUIET), ValueError, "times must be"),
        (lambda: gyro_odometry(ROBOT, None, None, QUIET), ValueError, "times must be"),
        (
            lambda: gyro_odometry(ROBOT, [0.0, math.nan, 2.0], np.zeros((2, 2)), QUIET),
            ValueError,
            "times must be finite and increase",  # was reported as a NaN "bias"
        ),
        (
            lambda: OnlineCalibrator(ROBOT, window=1).update(0.1, 0.1, "abc"),
            ValueError,
            "relative_pose must be 3 finite numbers",
        ),
        (
            lambda: OnlineCalibrator(ROBOT, window=1).update(0.1, 0.1, (10**400, 0, 0)),
            ValueError,
            "relative_pose must be 3 finite numbers",
        ),
        (
            lambda: dd.SkidSteer(0.05, 1e308, -1e308),
            ValueError,
            "icr_left - icr_right .* overflows",  # later errors named track_width before
        ),
        (
            lambda: S(gyro_noise=dd.estimation.GyroNoise(angle_random_walk=1e200)),
            ValueError,
            "angle_random_walk 1e\\+200 squares past the largest float",  # an OverflowError
        ),
        (
            lambda: SlipTest(command_sigma=1e-200),
            ValueError,
            "SlipTest.command_sigma 1e-200 squares to 0",
        ),
        (
            lambda: dd.simulate(ROBOT, lambda t: np.ones((len(t), 2)), dt=1e-320, duration=1.0),
            ValueError,
            "is inf steps",
        ),
        (lambda: dd.batch.to_twist("robot", [1.0, 2.0]), TypeError, "robot must be a robot"),
        (
            lambda: dd.batch.to_wheel_velocities(None, [1.0, 0.0, 2.0]),
            TypeError,
            "robot must be a robot model",
        ),
        (
            lambda: calibrate("robot", [(np.zeros((3, 2)), np.zeros((4, 3)))]),
            TypeError,
            "nominal_robot must be a robot model",
        ),
        (
            lambda: dd.desaturate([1.0, 2.0], 1.0, keep="omega", robot="r"),
            TypeError,
            "robot must be a robot model",
        ),
        (lambda: worst([None]), TypeError, r"errors\[0\] must be RunErrors"),
        (lambda: dd.wrap_angle(10**400), ValueError, "angle must be finite"),
        (lambda: dd.se2.sinc(10**400), ValueError, "u must be finite, got an integer too large"),
        (
            lambda: dd.simulate(ROBOT, lambda t: np.ones((len(t), 2)), dt=1e-12, duration=1e6),
            ValueError,
            "1e\\+18 steps, .* GiB of poses",  # a MemoryError before
        ),
        (
            lambda: dd.io.write_trajectory("x.csv", np.arange(3.0), np.zeros((4, 3))),
            ValueError,
            r"times must broadcast to \(4,\) for poses \(4, 3\), got \(3,\)",
        ),
        (
            lambda: dd.io.write_trajectory("x.csv", [0.0, math.nan, 2.0], np.zeros((3, 3))),
            ValueError,
            "times must be finite",
        ),
        (
            lambda: dd.io.write_trajectory("x.csv", [0.0, 1.0, 1.0], np.zeros((3, 3))),
            ValueError,
            "times must increase strictly",
        ),
    ],
)
def test_is_refused_by_name(call, error, message, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(error, match=message):
        call()
    assert not (tmp_path / "x.csv").exists()


def test_writing_over_a_folder_names_the_folder(tmp_path):
    with pytest.raises(dd.io.TableError, match="it is a folder"):
        dd.io.write_trajectory(tmp_path, np.arange(3.0), np.zeros((3, 3)))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("odometry", [dd.Odometry, dd.estimation.odometry._PythonOdometry])
def test_an_infinite_wheel_speed_is_refused_and_twist_still_reads(odometry):
    """A wheel turning 1e308 rad in 1e-300 s was accepted, and .twist raised until the
    velocity window moved on."""
    o = odometry(ROBOT)
    o.update_positions(0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="a speed past the largest float"):
        o.update_positions(1e308, 1e308, 1e-300)
    assert o.pose == dd.Pose()
    o.update_positions(0.1, 0.1, 0.1)
    assert o.twist.vx == pytest.approx(0.05)


def test_sensible_inputs_that_were_refused_are_taken():
    assert dd.SkidSteer(0.05, 0.3, -0.3, wheels_per_side=np.int64(2)).wheels_per_side == 2
    online = OnlineCalibrator(ROBOT, window=1)
    assert online.update(0.1, 0.1, dd.Pose(0.005, 0.0, 0.0))  # a Pose as the relative pose
    assert Gyro([0.0, 1.0], [0.0, 0.0]).angles([]).shape == (0,)
    torch = pytest.importorskip("torch", reason="torch is in the test group")
    path = dd.simulate(
        ROBOT, torch.ones((3, 2), dtype=torch.float64), dt=0.1, initial_pose=dd.Pose(1, 2, 0)
    )
    assert float(path.poses[0, 0]) == 1.0
    empty = dd.simulate(ROBOT, np.zeros((0, 10, 2)), dt=0.1, backend="numba")  # 0 robots
    assert empty.poses.shape == (0, 11, 3)


def test_cr_only_line_endings_are_read(tmp_path):
    log = tmp_path / "cr.csv"
    log.write_bytes(b"t,left_angle,right_angle\r0,0,0\r1,1,1\r2,2,2\r")
    run = dd.io.read_run(log)
    np.testing.assert_array_equal(run.wheels, [[0, 0], [1, 1], [2, 2]])
    assert run.where(2) == f"{log}:4"  # the header is line 1
    path = tmp_path / "cr_path.csv"
    path.write_bytes(b"t,x,y,theta\r0,0,0,0\r1,1,0,0\r")
    times, poses = dd.io.read_trajectory(path)
    np.testing.assert_array_equal(times, [0.0, 1.0])
    np.testing.assert_array_equal(poses[:, 0], [0.0, 1.0])


def test_joint_state_arguments_are_checked(tmp_path):
    pytest.importorskip("rosbags", reason="rosbags is in the test group")
    from diffdrive.io import ros

    bag = tmp_path / "b.mcap"
    ros.write_streams(bag, [ros.Stream("joints", "/joint_states", [1.0, 2.0], np.zeros((2, 2)))])
    with pytest.raises(ValueError, match="field must be 'position', 'velocity' or None"):
        ros.read_joint_states(bag, "left_wheel_joint", "right_wheel_joint", field="effort")
    with pytest.raises(ValueError, match="the left and right wheels are one joint"):
        ros.read_joint_states(bag, "left_wheel_joint", "left_wheel_joint")


@pytest.mark.slow
def test_writing_a_long_trajectory_takes_memory_by_the_block_not_by_the_log(tmp_path):
    """A 6-million-row log peaked at 3.6 GiB in `diffdrive simulate`, nearly all of it the
    text of the whole output at once; the text is now made a block of rows at a time."""
    import tracemalloc

    def peak(rows: int) -> int:
        times = np.arange(rows) * 0.01
        poses = np.random.default_rng(0).normal(size=(rows, 3))
        tracemalloc.start()
        try:
            dd.io.write_trajectory(tmp_path / f"{rows}.csv", times, poses)
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    assert peak(400_000) < 1.5 * peak(140_000)  # three times the rows: was three times the peak


def test_a_robot_file_with_a_number_of_hundreds_of_digits_is_named(tmp_path):
    robot = tmp_path / "robot.toml"
    robot.write_text("wheel_radius = 0.05\ntrack_width = 1" + "0" * 400 + "\n")
    with pytest.raises(dd.io.TableError, match="track_width must be finite, got a number of 401"):
        dd.io.read_robot(robot)


# -- the fourth campaign (issue 43): silent wrong answers, crashes, messages ----------------


def _estimator(core):
    """E() of the campaign: a wheels-heading estimator two readings in."""
    e = core(dd.DiffDrive(wheel_radius=0.1, track_width=1.0), S("wheels"))
    e.update_positions(0.0, 0.0, t=0.0)
    e.update_positions(0.19, 0.21, t=0.02)
    return e


@pytest.mark.parametrize(
    "core", [dd.estimation.PoseEstimator, dd.estimation.fusion._PythonPoseEstimator]
)
@pytest.mark.parametrize(
    ("add", "message"),
    [
        (lambda e, p: e.add_position(0.02, (p.x + 0.003, p.y), math.nan), "must be > 0"),
        (lambda e, p: e.add_heading(0.02, 0.1, math.nan), "must be > 0"),
        (
            lambda e, p: e.add_position(0.02, (p.x, p.y), [[0.01, 0.01], [0.01, 0.01]]),
            "not positive definite|singular",
        ),
        (
            lambda e, p: e.add_position(0.02, (p.x, p.y), [[1.0, 1 - 1e-15], [1 - 1e-15, 1.0]]),
            "singular",  # Cholesky passes on rounding; a pivot of 2e-15 is refused
        ),
    ],
)
def test_a_nan_or_singular_covariance_is_refused_by_both_cores(core, add, message):
    """The compiled estimator took a NaN standard deviation as an exact measurement (NaN was
    its 'a matrix was given' marker): the pose jumped onto the fix and the covariance lost
    its positive semi-definiteness. Both cores now refuse it, and a singular covariance."""
    e = _estimator(core)
    before, covariance = e.pose, e.covariance
    with pytest.raises(ValueError, match=message):
        add(e, before)
    assert e.pose == before
    np.testing.assert_array_equal(e.covariance, covariance)


@pytest.mark.parametrize(
    "core", [dd.estimation.PoseEstimator, dd.estimation.fusion._PythonPoseEstimator]
)
def test_a_queued_fix_with_a_huge_lever_arm_is_gated_out_and_the_estimator_goes_on(core):
    """The pure-Python core jammed for good: every later reading 'would overflow'."""
    e = _estimator(core)
    assert e.add_position(0.05, (0.1, 0.0), 0.1, lever_arm=(1e300, 0.0)) is False  # waits
    for k in (3, 4, 5):
        e.update_positions(0.095 * k, 0.105 * k, t=0.02 * (k - 1))
    assert (e.accepted, e.rejected) == (0, 1)
    assert np.isfinite(e.pose.x)


@pytest.mark.parametrize(
    ("call", "error", "message"),
    [
        (
            lambda: dd.dynamics.DriveModel(time_constant=0.1).wheel_velocities(
                [0.0, 0.1, 0.2], [0.0], [[1.0, 1.0]], initial=[math.nan, 0.0]
            ),
            ValueError,
            r"initial must be finite",  # NaN rows before
        ),
        (
            lambda: dd.dynamics.simulate_commands(
                ROBOT, dd.dynamics.DriveModel(), [0.0], [[1.0, 1.0]], dt=0.01, duration=-5
            ),
            ValueError,
            "duration must be > 0",  # a one-step trajectory before
        ),
        (
            lambda: dd.dynamics.simulate_commands(
                ROBOT, dd.dynamics.DriveModel(), [0.0], [[1.0, 1.0]], dt=1e-7, duration=1e7
            ),
            ValueError,
            "would take 1e\\+14 samples",  # a MemoryError before
        ),
        (
            lambda: dd.dynamics.simulate_commands(
                ROBOT,
                dd.dynamics.DriveModel(),
                [0.0],
                [[1.0, 1.0]],
                dt=0.01,
                duration=1.0,
                initial_wheels=[math.nan, 0.0],
            ),
            ValueError,
            "initial_wheels must be finite",  # named an argument the caller never gave
        ),
        (
            lambda: dd.evaluation.consistency(
                np.zeros((3, 3)),
                np.array([np.eye(3), np.diag([1.0, -1.0, 1.0]), np.eye(3)]),
                np.full((3, 3), 0.1),
            ),
            ValueError,
            "covariance 1 is not positive semi-definite",  # skipped as known exactly
        ),
        (lambda: dd.SkidSteer(0.05, 5e-324, 0.0), ValueError, "divides to a finite number"),
        (
            lambda: dd.DiffDrive(wheel_radius=1e-320, track_width=0.3),
            ValueError,
            "wheel_radius must be a length that divides",
        ),
        (
            lambda: dd.control.plan(
                np.array([[0, 0], [1, 0], [2, 1], [3, 1.0]]),
                ROBOT,
                dd.control.PathLimits(max_velocity=1),
                stops=[1.5],
            ),
            ValueError,
            "stops must be a whole number from 1, got 1.5",
        ),
        (
            lambda: dd.estimation.estimate_trajectory(
                ROBOT,
                [0.0, 1.0],
                [[0.1, 0.1]],
                settings=S("wheels"),
                measurements=[(1.0, (0, 0, 0))],
            ),
            TypeError,
            "measurements must be Measurements",  # AttributeError before
        ),
        (
            lambda: gyro_odometry(ROBOT, [0.0, 1.0], [[0.1, 0.1]], None),
            TypeError,
            "gyro must be a Gyro",  # AttributeError before
        ),
        (lambda: dd.control.Ramsete(zeta="0.5"), TypeError, "zeta must be a real number"),
        (
            lambda: dd.dynamics.DriveModel(max_acceleration="1"),
            TypeError,
            "max_acceleration must be a number",
        ),
        (
            lambda: dd.io.sample_times(np.arange(100) * 0.01, tick="1e-3"),
            TypeError,
            "tick must be a real number",
        ),
        (lambda: dd.se2.sinc("a"), TypeError, "u must be a real number"),
        (lambda: dd.wrap_angle("a"), TypeError, "angle must be a real number"),
        (lambda: dd.se2.from_matrix("a"), TypeError, "matrix must be numbers"),
        (lambda: dd.evaluation.rpe("a", np.zeros((2, 3)), 1.0), TypeError, "estimate must be"),
        (
            lambda: dd.evaluation.rpe(np.zeros((2, 3)), np.zeros((2, 3)), 1.0, "s", times="a"),
            TypeError,
            "times must be numbers",
        ),
        (lambda: dd.Odometry(ROBOT).reset(None, "a"), TypeError, "covariance must be numbers"),
        # the round of probes of issue 55
        (
            lambda: dd.evaluation.consistency(
                np.zeros((3, 3)), np.tile(np.eye(3) * 1e-2, (3, 1, 1)), np.full((3, 3), 1e200)
            ),
            ValueError,
            "pose 0: its error .* overflows the NEES",  # an ANEES of inf before
        ),
        (
            lambda: dd.control.Predictive(dd.control.Ramsete(), delay="0.1", dt=0.02),
            TypeError,
            "Predictive delay must be a real number",  # str / float inside before
        ),
        (
            lambda: dd.control.Predictive(dd.control.Ramsete(), delay=0.04, dt=0.02, lag=-1),
            ValueError,
            "Predictive lag must be >= 0",
        ),
        (
            lambda: dd.io.sample_times(np.arange(100) * 0.01, share="0.8"),
            TypeError,
            "share must be a real number",  # float < str inside before
        ),
        # a fuzzer's round on the entry points added since (NaN, inf, text, wrong types)
        (lambda: dd.control.MPPI(delay="0.1"), TypeError, "delay must be a real number"),
        (
            lambda: dd.control.FollowSettings(wheel_noise=math.nan),
            ValueError,
            "FollowSettings.wheel_noise: wheel noise left must be finite",  # unnamed before
        ),
        (
            lambda: S().changed(0.5),
            TypeError,
            "changes must be a mapping of setting names",  # AttributeError before
        ),
        (
            lambda: export.parameters(
                "ros2", ROBOT, ROBOT, 1e-4, export.Reference(), wheel_names=("l", "r")
            ),
            TypeError,
            "model must be a NoiseModel",  # AttributeError before
        ),
        (
            lambda: export.parameters(
                "ros2",
                ROBOT,
                ROBOT,
                NoiseModel.symmetric(1e-4),
                export.Reference(),
                wheel_names="lr",
            ),
            TypeError,
            "wheel_names must be two joint names",  # IndexError before
        ),
        (
            lambda: dd.control.plan(
                np.array([[0, 0], [1, 0], [2, 1.0]]), ROBOT, dd.control.PathLimits(max_velocity=1)
            ).sample(math.nan),
            ValueError,
            "t must be times",  # NaN poses and twists before
        ),
    ],
)
def test_the_campaigns_findings_are_refused_by_name(call, error, message):
    with pytest.raises(error, match=message):
        call()


@pytest.mark.parametrize("sigma", ["nan", "-1", "0"])
def test_calibrate_driving_refuses_a_reference_noise_that_is_none(tmp_path, sigma, capsys):
    """``--reference-noise nan`` or ``-1`` (``--reference-sigma`` before) was taken (and
    held); refused by name before any
    file is read, nothing written."""
    from diffdrive.cli import main

    argv = ["calibrate-driving", str(tmp_path / "drive.mcap"), "--robot", "wheel_radius=0.1"]
    argv += ["--robot", "track_width=0.5", "--gps-topic", "/fix", "--reference-noise", sigma]
    assert main([*argv, "-o", str(tmp_path / "robot.toml")]) == 1
    assert "--reference-noise (m, and rad for poses) must be" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_integers_fractions_numpy_scalars_and_lists_of_rows():
    """What the campaign found taken without a word, or refused though sensible."""
    from diffdrive.calibration import noise

    increments = np.tile([0.2, 0.25], (50, 1))
    runs = [(increments, dd.simulate(ROBOT, increments / 0.02, dt=0.02).poses)] * 3
    with pytest.raises(ValueError, match=r"windows must be a whole number from 1, got 2\.5"):
        noise.identify(ROBOT, runs, windows=2.5)
    with pytest.raises(TypeError, match="windows must be a real number, not text"):
        noise.identify(ROBOT, runs, windows="3")
    limits = dd.control.PathLimits(max_velocity=np.float32(1.5))  # a NumPy scalar: a number
    assert limits.max_velocity == 1.5
    planned = dd.control.plan([[0, 0], [1, 0], [1, 1]], ROBOT, limits)  # a list of rows
    fleet = dd.control.FollowSettings(robots=np.int64(2))
    follow = dd.control.follow(planned, dd.control.Ramsete(), settings=fleet)
    assert follow.poses.shape[0] == 2
    model = noise.NoiseModel.symmetric(1e-4, 0.0, 0.0, 0.0, 0.0)
    drawn = noise.draw_reference(ROBOT, increments, np.zeros(3), model, 5)  # an int seed
    again = noise.draw_reference(ROBOT, increments, np.zeros(3), model, 5)
    np.testing.assert_array_equal(drawn, again)
    with pytest.raises(ValueError, match=r"start must be one pose \(x, y, theta\) or one per"):
        dd.control.follow(
            planned, dd.control.Ramsete(), settings=dd.control.FollowSettings(start=[0, 0])
        )
    with pytest.raises(ValueError, match=r"delay must be one number or one per robot \(3\)"):
        dd.control.follow(
            planned,
            dd.control.Ramsete(),
            delay=[0, 0.02],
            settings=dd.control.FollowSettings(robots=3),
        )


def test_huge_poses_give_finite_measures():
    """ATE of a pose 1e200 m off was inf (its square overflowed), and the alignment of poses
    of 1e300 m raised LinAlgError."""
    error = dd.evaluation.ate(np.array([[1e200, 0, 0], [0, 0, 0]]), np.zeros((2, 3)))
    assert error == pytest.approx(1e200 / math.sqrt(2))
    far = np.array([[1e300, 0, 0], [0, 1e300, 0], [1, 1, 0]])
    aligned = dd.evaluation.align(far, far)
    np.testing.assert_allclose(aligned[:, :2], far[:, :2], rtol=0, atol=1e300 * 1e-12)
