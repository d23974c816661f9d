"""What a fuzz campaign found ending in a traceback or an internal message: each is refused
with its name (or, where it is a sensible input, accepted), and nothing is half-done."""

import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.calibration import OnlineCalibrator, calibrate
from diffdrive.estimation.gyro import Gyro, GyroOdometry, gyro_odometry
from diffdrive.evaluation import worst

ROBOT = dd.DiffDrive(0.05, 0.3)
QUIET = Gyro([0.0, 3.0], [0.0, 0.0])


@pytest.mark.parametrize(
    ("call", "error", "message"),
    [
        (lambda: GyroOdometry(ROBOT, noise=3), TypeError, "noise must be a GyroNoise, got int"),
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
            lambda: GyroOdometry(ROBOT, noise=dd.estimation.GyroNoise(angle_random_walk=1e200)),
            ValueError,
            "angle_random_walk 1e\\+200 squares past the largest float",  # an OverflowError
        ),
        (
            lambda: GyroOdometry(ROBOT, command_sigma=1e-200),
            ValueError,
            "command_sigma 1e-200 squares to 0",
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


@pytest.mark.parametrize("odometry", [dd.Odometry, dd.estimation.PythonOdometry])
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
