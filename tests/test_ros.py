"""ROS bags and MCAP: reading real robots' bags, writing what ROS tools read, and the command
line on bags. The bags are in ../shared/data/ros-bags (see its README)."""

import json
import math
import shutil

import numpy as np
import pytest

import diffdrive as dd
from data import DATA, data_folder
from diffdrive.cli import main
from diffdrive.evaluation import ate
from diffdrive.io import ros

pytest.importorskip("rosbags")
BAGS = DATA / "ros-bags"


@pytest.fixture(autouse=True)
def _bags():
    """Every test here reads the bags: fails in CI, skips elsewhere, when they are missing."""
    data_folder("ros-bags")


TB3 = BAGS / "turtlebot3_fuse.bag"
HUSKY = BAGS / "husky_robot_localization_test1.bag"
JOINTS = ["--left-joint", "wheel_left_joint", "--right-joint", "wheel_right_joint"]


def run(argv, capsys):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


# -- reading ---------------------------------------------------------------------------------


def test_topics_say_what_diffdrive_can_use():
    found = {t.name: t for t in ros.topics(TB3)}
    assert found["/joint_states"].count == 2741
    assert found["/joint_states"].rate == pytest.approx(30.0, rel=1e-3)
    assert "--joint-topic" in found["/joint_states"].use
    assert found["/scan"].use == ""


@pytest.mark.slow
def test_joints_are_looked_up_by_name_not_by_index():
    """The TurtleBot3 bag lists the right wheel first."""
    log = ros.read_joint_states(TB3, "wheel_left_joint", "wheel_right_joint")
    assert log.kind == "angle"
    assert log.wheels[0].tolist() == pytest.approx([9.00880971, -4.23206781])
    assert log.times[0] == pytest.approx(112.54)
    assert "header stamps" in log.source
    swapped = ros.read_joint_states(TB3, "wheel_right_joint", "wheel_left_joint")
    np.testing.assert_array_equal(swapped.wheels, log.wheels[:, ::-1])


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda: ros.read_joint_states(TB3, "left", "wheel_right_joint"),
            "no joint 'left' \\(its joints: wheel_right_joint, wheel_left_joint\\)",
        ),
        (
            lambda: ros.read_odometry(TB3, "/nope"),
            "no topic '/nope' \\(the bag has: /cmd_vel, /imu, /joint_states, /odom, /scan\\)",
        ),
        (lambda: ros.read_odometry(TB3, "/imu"), "/imu holds sensor_msgs/msg/Imu, not nav_msgs"),
        (lambda: ros.read_tf(TB3, "odom", "base_footprint"), "no /tf or /tf_static topic"),
        (lambda: ros.read_odometry(BAGS / "missing.bag", "/odom"), "missing.bag: no such bag"),
    ],
)
def test_what_a_bag_cannot_give_is_named(call, message):
    with pytest.raises(ros.BagError, match=message):
        call()


@pytest.mark.parametrize("size", [0, 100, 700_000])
def test_empty_and_truncated_bags_are_refused(tmp_path, size):
    broken = tmp_path / "broken.bag"
    broken.write_bytes(TB3.read_bytes()[:size])
    with pytest.raises(ros.BagError, match=r"broken\.bag"):
        ros.read_odometry(broken, "/odom")


def test_messages_out_of_order_are_sorted_and_repeated_stamps_dropped(tmp_path):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    t = store.types
    path = tmp_path / "shuffled"
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection("/js", "sensor_msgs/msg/JointState", typestore=store)
        for k, stamp in enumerate([3, 1, 2, 2, 4]):
            message = t["sensor_msgs/msg/JointState"](
                header=t["std_msgs/msg/Header"](
                    stamp=t["builtin_interfaces/msg/Time"](sec=stamp, nanosec=0), frame_id=""
                ),
                name=["r", "l"],
                position=np.array([10.0 * stamp, float(k)]),
                velocity=np.array([]),
                effort=np.array([]),
            )
            writer.write(connection, k, store.serialize_cdr(message, message.__msgtype__))
    log = ros.read_joint_states(path, "l", "r", "/js")
    assert log.times.tolist() == [1.0, 2.0, 3.0, 4.0]
    assert log.wheels[:, 1].tolist() == [10.0, 20.0, 30.0, 40.0]
    assert log.wheels[:, 0].tolist() == [1.0, 2.0, 0.0, 4.0]  # of stamp 2, the first kept


def test_joint_states_that_mix_header_stamps_and_record_times_use_record_times(tmp_path, capsys):
    """Two of 40 messages without a header stamp took their record time (1.7e9 s), sorted to
    the end, and odometry exited 0 with the robot driving back: one clock for all, named."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    t = store.types
    path = tmp_path / "mixed"
    recorded = 1_700_000_000 * 10**9  # record times (ns), 0.05 s apart
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection("/js", "sensor_msgs/msg/JointState", typestore=store)
        for k in range(40):
            empty = k in (7, 23)
            seconds = 0 if empty else 100 + k // 20
            nanoseconds = 0 if empty else (k % 20) * 50_000_000
            message = t["sensor_msgs/msg/JointState"](
                header=t["std_msgs/msg/Header"](
                    stamp=t["builtin_interfaces/msg/Time"](sec=seconds, nanosec=nanoseconds),
                    frame_id="",
                ),
                name=["l", "r"],
                position=np.array([0.5 * k, 0.5 * k]),
                velocity=np.array([]),
                effort=np.array([]),
            )
            raw = store.serialize_cdr(message, message.__msgtype__)
            writer.write(connection, recorded + k * 50_000_000, raw)
    log = ros.read_joint_states(path, "l", "r", "/js")
    assert "record (as 2 of 40 messages have no header stamp) stamps" in log.source
    assert np.all(np.diff(log.times) > 0)
    assert np.all(np.diff(log.wheels[:, 0]) > 0)  # the wheels only ever turn forward
    robot = ["--wheel-radius", "0.05", "--track-width", "0.3"]
    argv = ["odometry", path, "--left-joint", "l", "--right-joint", "r", "--joint-topic", "/js"]
    assert main([*map(str, argv), *robot, "-o", str(tmp_path / "o.csv")]) == 0
    x = np.genfromtxt(tmp_path / "o.csv", delimiter=",", names=True)["x"]
    assert np.all(np.diff(x) > 0)  # it never drives back


@pytest.mark.slow
def test_husky_odometry_imu_and_gps():
    odometry = ros.read_odometry(HUSKY, "/husky_velocity_controller/odom")
    assert len(odometry.times) == 3952
    assert (odometry.frame, odometry.child_frame) == ("odom", "base_link")
    assert odometry.covariances[0, 0, 0] == pytest.approx(0.001)
    imu = ros.read_imu(HUSKY, "/imu/data")
    assert imu.frame == "imu_link"
    assert imu.angular_velocity.shape == (11865, 3)
    # The trap: the IMU is not z-up; its y axis, not z, follows the wheels' yaw rate.
    yaw_rate = np.interp(imu.times, odometry.times, odometry.twists[:, 2])
    correlation = [np.corrcoef(imu.angular_velocity[:, k], yaw_rate)[0, 1] for k in range(3)]
    assert abs(correlation[1]) > 0.8
    assert abs(correlation[2]) < 0.1
    gps = ros.read_navsatfix(HUSKY, "/fix")
    assert len(gps.times) == 989
    assert gps.positions[0].tolist() == [0.0, 0.0]
    assert float(np.hypot(*gps.positions[-1])) == pytest.approx(13.4, abs=0.1)
    assert gps.variance[0] == pytest.approx(0.81)


@pytest.mark.slow
def test_husky_wheel_odometry_against_gps_positions_aligned():
    odometry = ros.read_odometry(HUSKY, "/husky_velocity_controller/odom")
    gps = ros.read_navsatfix(HUSKY, "/fix")
    inside = (gps.times >= odometry.times[0]) & (gps.times <= odometry.times[-1])
    at = gps.times[inside]
    estimate = dd.evaluation.interpolate(odometry.times, odometry.poses, at)
    truth = np.column_stack([gps.positions[inside], np.zeros(len(at))])
    estimate[:, 2] = 0.0
    raw, aligned = ate(estimate, truth), ate(estimate, truth, aligned=True)
    assert aligned < raw
    assert 1.0 < aligned < 10.0  # drift over 359 m; figures in the README


@pytest.mark.slow
def test_husky_gyro_heading_from_the_command_line(tmp_path, capsys):
    """The Husky has no joint states: its wheels come from the controller's odometry
    (--wheel-topic), and the gyro heading against GPS is the example's 2.77 m."""
    robot = ["--wheel-radius", "0.165", "--track-width", "0.555"]
    imu = ["--gyro-topic", "/imu/data", "--imu-mount", "1.5707963", "0", "0", "--heading", "gyro"]
    out = tmp_path / "gyro.csv"
    argv = ["odometry", HUSKY, "--wheel-topic", "/husky_velocity_controller/odom", *robot, *imu]
    code, printed, err = run([*argv, "--k-left", "1e-3", "--k-right", "1e-3", "-o", out], capsys)
    assert code == 0, err
    assert "/husky_velocity_controller/odom (the controller's poses, header stamps)" in printed
    code, printed, _ = run(
        ["evaluate", out, "--truth", HUSKY, "--truth-topic", "/fix", "--interpolate", "--json"],
        capsys,
    )
    assert code == 0
    assert json.loads(printed)["ate_aligned_m"] == pytest.approx(2.77, abs=0.005)


@pytest.mark.slow
def test_husky_gps_fixes_identified_from_the_command_line(tmp_path, capsys):
    """Every Husky fix fused with no setting given: the fixes' noise identified (all 989
    taken), the poses 2.83 m from the fixes (aligned ATE) and the poses plus the offset on
    them; given as white noise of the receiver's covariance, the gate refuses 378 of them."""
    robot = ["--wheel-radius", "0.165", "--track-width", "0.555"]
    imu = ["--gyro-topic", "/imu/data", "--imu-mount", "1.5707963", "0", "0", "--gps-topic", "/fix"]
    argv = ["odometry", HUSKY, "--wheel-topic", "/husky_velocity_controller/odom", *robot, *imu]
    out = tmp_path / "fused.csv"
    code, printed, err = run([*argv, "--smooth", "-o", out], capsys)
    assert code == 0, err
    assert "measurements: 989 taken, 0 refused by the gate (0.999999999), fixes identified" in (
        printed
    )
    assert "fixes: white noise" in printed
    code, scored, _ = run(
        ["evaluate", out, "--truth", HUSKY, "--truth-topic", "/fix", "--interpolate", "--json"],
        capsys,
    )
    assert code == 0
    assert json.loads(scored)["ate_aligned_m"] == pytest.approx(2.83, abs=0.005)
    table = np.genfromtxt(out, delimiter=",", names=True)
    gps = ros.read_navsatfix(HUSKY, "/fix")
    placed = np.column_stack(
        [np.interp(gps.times, table["t"], table[a] + table[f"fix_offset_{a}"]) for a in "xy"]
    )
    inside = (gps.times >= table["t"][0]) & (gps.times <= table["t"][-1])
    assert np.median(np.hypot(*(placed - gps.positions)[inside].T)) < 0.01
    code, printed, err = run([*argv, "--smooth", "--fixes", "given", "-o", out], capsys)
    assert code == 0, err
    assert "611 taken, 378 refused by the gate (0.999), fixes given" in printed


# -- writing ---------------------------------------------------------------------------------


@pytest.mark.parametrize("format", ["mcap", "ros2"])
def test_odometry_written_reads_back_with_rosbags(tmp_path, format):
    times = 1700000000.0 + np.arange(200) * 0.05
    poses = np.column_stack([np.cos(times), np.sin(times), np.linspace(0, 3, 200)])
    covariances = np.einsum("k,ij->kij", np.linspace(1e-4, 1e-2, 200), np.diag([1.0, 2.0, 0.5]))
    twists = np.column_stack([np.full(200, 0.5), np.zeros(200), np.full(200, 0.3)])
    path = tmp_path / ("odom.mcap" if format == "mcap" else "odom_bag")
    ros.write_odometry(path, times, poses, covariances, twists, frame="map", child_frame="robot")
    back = ros.read_odometry(path, "/odom")
    np.testing.assert_allclose(back.times, times, rtol=0, atol=2e-9)  # nanosecond stamps
    np.testing.assert_allclose(back.poses, poses, atol=1e-12)
    np.testing.assert_allclose(back.covariances, covariances, atol=1e-15)
    np.testing.assert_allclose(back.twists, twists)
    assert (back.frame, back.child_frame, back.stamp_source) == ("map", "robot", "header")
    _tf_times, tf_poses = ros.read_tf(path, "map", "robot")
    np.testing.assert_allclose(tf_poses, poses, atol=1e-12)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # nothing else left behind


def test_mcap_written_reads_back_with_the_mcap_package(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    times = 10.0 + np.arange(5) * 0.1
    poses = np.column_stack([np.arange(5.0), np.zeros(5), np.full(5, math.pi / 2)])
    covariances = np.tile(np.diag([1e-4, 2e-4, 3e-5]), (5, 1, 1))
    path = ros.write_odometry(tmp_path / "o.mcap", times, poses, covariances)
    with path.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        seen = {}
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            seen.setdefault(channel.topic, []).append((schema.name, message.log_time, decoded))
    assert sorted(seen) == ["/odom", "/tf"]
    name, log_time, odometry = seen["/odom"][3]
    assert name == "nav_msgs/msg/Odometry"
    assert log_time == 10_300_000_000
    assert (odometry.header.stamp.sec, odometry.header.stamp.nanosec) == (10, 300_000_000)
    assert odometry.header.frame_id == "odom"
    assert odometry.child_frame_id == "base_link"
    assert odometry.pose.pose.position.x == 3.0
    assert odometry.pose.pose.orientation.z == pytest.approx(math.sin(math.pi / 4))
    covariance = np.array(odometry.pose.covariance).reshape(6, 6)
    assert covariance[0, 0] == 1e-4
    assert covariance[5, 5] == 3e-5
    assert covariance[2, 2] == 1e6  # z, roll, pitch: not estimated
    transform = seen["/tf"][3][2].transforms[0]
    assert (transform.header.frame_id, transform.child_frame_id) == ("odom", "base_link")


def test_an_existing_bag_folder_is_not_replaced(tmp_path):
    (tmp_path / "bag").mkdir()
    with pytest.raises(ValueError, match="it exists"):
        ros.write_odometry(tmp_path / "bag", [0.0, 1.0], np.zeros((2, 3)), format="ros2")


# -- TurtleBot3: dead reckoning and calibration against /odom ---------------------------------


@pytest.mark.slow
def test_turtlebot3_calibration_from_joint_states_against_odom(tmp_path, capsys):
    robot_file = tmp_path / "tb3.toml"
    argv = [
        "calibrate",
        TB3,
        *JOINTS,
        "--reference-topic",
        "/odom",
        "--method",
        "increments",
        "--wheel-radius",
        "0.033",
        "--track-width",
        "0.287",
        "-o",
        robot_file,
    ]
    code, out, err = run(argv, capsys)
    assert code == 0, err
    settings = dd.io.read_robot(robot_file)
    # The data README: a plain fit finds about 0.0325 m and 0.300 m.
    assert settings["left_wheel_radius"] == pytest.approx(0.0325, abs=2e-4)
    assert settings["right_wheel_radius"] == pytest.approx(0.0325, abs=2e-4)
    assert settings["track_width"] == pytest.approx(0.2955, abs=2e-3)
    odometry = tmp_path / "tb3.mcap"
    argv = [
        "odometry",
        TB3,
        *JOINTS,
        "--robot",
        robot_file,
        "--k-left",
        "1e-5",
        "--k-right",
        "1e-5",
        "-o",
        odometry,
    ]
    assert run(argv, capsys)[0] == 0
    back = ros.read_odometry(odometry, "/odom")
    assert len(back.times) == 2741
    assert back.covariances[-1, 0, 0] > back.covariances[10, 0, 0] > 0  # propagated, growing
    code, out, _ = run(
        [
            "evaluate",
            odometry,
            "--topic",
            "/odom",
            "--truth",
            TB3,
            "--truth-topic",
            "/odom",
            "--json",
        ],
        capsys,
    )
    assert code == 0
    metrics = json.loads(out)
    assert metrics["poses_compared"] == 2741
    # /odom turns the other way from the wheels for a few seconds early on (see README)
    assert 1.0 < metrics["max_position_error_m"] < 6.0


@pytest.mark.slow
def test_the_cli_takes_a_bag_wherever_it_takes_a_log(tmp_path, capsys):
    code, out, _ = run(["info", TB3], capsys)
    assert code == 0
    assert "/joint_states" in out
    assert "sensor_msgs/msg/JointState" in out
    code, _, err = run(["odometry", TB3, "-o", tmp_path / "o.csv"], capsys)
    assert code == 1
    assert "--joints LEFT RIGHT" in err
    code, out, err = run(["simulate", TB3, *JOINTS, "-o", tmp_path / "s.csv"], capsys)
    assert code == 0, err
    code, _, err = run(["plot", TB3, "--topic", "/odom", "-o", tmp_path / "p.png"], capsys)
    assert code == 0, err
    code, _, err = run(["plot", TB3, "-o", tmp_path / "p.png"], capsys)
    assert code == 1
    assert "give the topic of a trajectory" in err
    assert "/odom" in err


@pytest.mark.slow
def test_evaluate_wheel_odometry_against_gps_from_the_command_line(capsys):
    argv = [
        "evaluate",
        HUSKY,
        "--topic",
        "/husky_velocity_controller/odom",
        "--truth",
        HUSKY,
        "--truth-topic",
        "/fix",
        "--interpolate",
        "--json",
    ]
    code, out, err = run(argv, capsys)
    assert code == 0, err
    metrics = json.loads(out)
    assert metrics["max_heading_error_deg"] is None  # GPS has no heading
    assert metrics["ate_aligned_m"] < metrics["ate_m"]


def test_a_bag_output_of_simulate_and_a_missing_rosbags_message(tmp_path, capsys, monkeypatch):
    code, _, err = run(["simulate", "-o", tmp_path / "s.mcap"], capsys)
    assert code == 0, err
    written = ros.read_odometry(tmp_path / "s.mcap", "/odom")
    assert len(written.times) == 2001
    truth = dd.simulate(dd.demo.example_robot(), dd.demo.example_wheel_velocities, dt=0.01,
                        duration=dd.demo.EXAMPLE_DURATION)  # fmt: skip
    np.testing.assert_allclose(written.twists[1:], truth.twists, atol=1e-12)  # not zero
    log = tmp_path / "log.csv"
    log.write_text("t,left_velocity,right_velocity\n0,1,1\n0.1,1,1\n0.2,1,1\n")
    code, _, err = run(["simulate", log, "-o", tmp_path / "log.mcap"], capsys)
    assert code == 1
    assert "diffdrive odometry writes a log's odometry to a bag" in err
    monkeypatch.setitem(__import__("sys").modules, "rosbags.highlevel", None)
    with pytest.raises(ImportError, match=r"pip install 'diffdrive\[ros\]'"):
        ros.topics(TB3)


def test_copy_of_a_bag_folder_reads_like_the_original(tmp_path):
    ros.write_odometry(tmp_path / "a", [1.0, 2.0], np.zeros((2, 3)), format="ros2")
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    assert ros.is_bag(tmp_path / "b")
    assert len(ros.read_odometry(tmp_path / "b", "/odom").times) == 2


def test_a_tf_chain_and_velocity_joint_states(tmp_path):
    """odom -> base_link moves, base_link -> laser is static: the chain odom -> laser."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    t = store.types

    def stamp(k):
        return t["builtin_interfaces/msg/Time"](sec=k, nanosec=0)

    def transform(k, parent, child, x, yaw):
        return t["geometry_msgs/msg/TransformStamped"](
            header=t["std_msgs/msg/Header"](stamp=stamp(k), frame_id=parent),
            child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](x=x, y=0.0, z=0.0),
                rotation=t["geometry_msgs/msg/Quaternion"](
                    x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
                ),
            ),
        )

    path = tmp_path / "chain"
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        tf = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
        static = writer.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=store)
        joints = writer.add_connection("/js", "sensor_msgs/msg/JointState", typestore=store)
        message = t["tf2_msgs/msg/TFMessage"](
            transforms=[transform(0, "base_link", "laser", 0.2, 0.0)]
        )
        writer.write(static, 0, store.serialize_cdr(message, message.__msgtype__))
        for k in range(1, 4):
            message = t["tf2_msgs/msg/TFMessage"](
                transforms=[transform(k, "odom", "base_link", float(k), math.pi / 2)]
            )
            writer.write(tf, k, store.serialize_cdr(message, message.__msgtype__))
            message = t["sensor_msgs/msg/JointState"](
                header=t["std_msgs/msg/Header"](stamp=stamp(k), frame_id=""),
                name=["l", "r"],
                position=np.array([]),
                velocity=np.array([1.0 * k, 2.0 * k]),
                effort=np.array([]),
            )
            writer.write(joints, k, store.serialize_cdr(message, message.__msgtype__))
    times, poses = ros.read_tf(path, "odom", "laser")
    assert times.tolist() == [1.0, 2.0, 3.0]
    np.testing.assert_allclose(
        poses,
        [[1.0, 0.2, math.pi / 2], [2.0, 0.2, math.pi / 2], [3.0, 0.2, math.pi / 2]],
        atol=1e-12,
    )
    with pytest.raises(ros.BagError, match="no transform chain odom -> map"):
        ros.read_tf(path, "odom", "map")
    log = ros.read_joint_states(path, "l", "r", "/js")
    assert log.kind == "velocity"
    assert log.wheels.tolist() == [[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]]


def test_bag_errors_come_in_the_order_a_user_needs_them(capsys, tmp_path, monkeypatch):
    """A bag without the JointState topic says so before asking for joint names; without
    names, the joints there are are listed; info shows them and how to ask for a tf chain."""
    code = main(["odometry", str(HUSKY), "-o", "x.csv"])
    assert code == 1
    assert "no topic '/joint_states' (the bag has: /fix" in capsys.readouterr().err
    assert main(["odometry", str(TB3), "-o", "x.csv"]) == 1
    err = capsys.readouterr().err
    assert "--joints LEFT RIGHT (the joints on /joint_states: " in err
    assert "wheel_right_joint, wheel_left_joint)" in err
    assert main(["info", str(TB3)]) == 0
    out = capsys.readouterr().out
    assert "(joints: wheel_right_joint, wheel_left_joint)" in out
    assert "--tf PARENT CHILD" not in out
    from diffdrive.io.ros.reader import USES

    assert USES["tf2_msgs/msg/TFMessage"].endswith("--topic tf:PARENT:CHILD")


@pytest.mark.slow
def test_a_wrong_imu_mounting_is_named_when_the_gyro_and_wheels_disagree_that_often(
    capsys, tmp_path, monkeypatch
):
    """--imu-mount 1.5707963 0 0 (--imu-rpy 90 0 0 before) on the TurtleBot3 exited 0, 34 m
    off with half the intervals flagged
    as slip, and said nothing."""
    monkeypatch.chdir(tmp_path)
    argv = ["odometry", str(TB3), "--left-joint", "wheel_left_joint", "--right-joint"]
    argv += ["wheel_right_joint", "--gyro-topic", "/imu", "-q"]
    assert main([*argv, "--imu-mount", "1.5707963", "0", "0", "-o", "x.csv"]) == 0
    err = capsys.readouterr().err
    assert "% of the intervals flagged as slip" in err
    assert "A wrong IMU mounting (--imu-mount)" in err
    assert main([*argv, "-o", "y.csv"]) == 0  # the right mounting: no such warning
    assert "flagged as slip" not in capsys.readouterr().err


@pytest.mark.slow
def test_calibrate_warns_of_offsets_no_robot_of_its_size_has(capsys, tmp_path):
    """Both offsets on the TurtleBot3 against /odom: a 0.34 m axle offset and a 28.6 degree
    heading offset were accepted without a word."""
    argv = ["calibrate", str(TB3), "--left-joint", "wheel_left_joint", "--right-joint"]
    argv += ["wheel_right_joint", "--reference-topic", "/odom", "--wheel-radius", "0.033"]
    argv += ["--track-width", "0.287", "--cv", "none", "-o", str(tmp_path / "r.toml"), "-q"]
    assert main([*argv, "--extra", "axle_offset", "heading_offset"]) == 0
    err = capsys.readouterr().err
    assert "warning: axle offset 0.337 m is more than the track" in err
    assert "warning: heading offset 28.6 deg" in err
    assert main(argv) == 0  # no extra parameters: nothing to warn of
    assert "warning" not in capsys.readouterr().err


def test_info_names_the_options_each_topic_is_given_by():
    """``info``'s use of each topic names the subcommands and the option that take it (it
    never named --gps-topic, --pose-topic or --gyro-topic), and each named option is one of
    those subcommands'."""
    import re

    from diffdrive.cli import _options_of, build_parser
    from diffdrive.io.ros.reader import USES

    parser = build_parser()
    for msgtype, wanted in (
        ("sensor_msgs/msg/NavSatFix", "--gps-topic"),
        ("sensor_msgs/msg/Imu", "--gyro-topic"),
        ("geometry_msgs/msg/PoseWithCovarianceStamped", "--pose-topic"),
        ("nav_msgs/msg/Odometry", "--pose-topic"),
    ):
        assert wanted in USES[msgtype], msgtype
    for use in USES.values():
        for commands, option in re.findall(r"([a-z-]+(?:/[a-z-]+)+) (--[a-z-]+)", use):
            for command in commands.split("/"):
                assert option in _options_of(parser, command), (command, option)


@pytest.mark.slow
@pytest.mark.parametrize("command", ["odometry", "estimate"])
@pytest.mark.parametrize("gyro", [False, True], ids=["wheels", "gyro heading"])
def test_wheels_from_a_controllers_odometry_publish_the_speed_it_reports(
    tmp_path, capsys, gyro, command
):
    """With the wheels taken from the Husky's controller odometry, the twist written was each
    interval's pose difference over its stamps: 0.81 / 1.18 / 1.34 m/s alternating where the
    controller says about 1.0 (its poses are sampled off their stamps). It is the speed the
    controller reports, read back from the bag as a consumer reads it, and the command says
    so: odometry's, and the estimator's over the same wheels."""
    from diffdrive.io import ros

    argv = [command, str(HUSKY), "--wheel-topic", "/husky_velocity_controller/odom"]
    argv += ["--robot", "wheel_radius=0.165,track_width=0.555", "-o", str(tmp_path / "o.mcap")]
    if gyro:
        argv += ["--gyro-topic", "/imu/data", "--imu-mount", "1.5707963", "0", "0"]
        argv += ["--heading", "gyro"] if command == "odometry" else ["--settings", "heading=gyro"]
    assert main(argv) == 0
    assert "the controller reports at each stamp" in capsys.readouterr().out
    written = ros.read_odometry(tmp_path / "o.mcap", "/odom")
    source = ros.read_odometry(HUSKY, "/husky_velocity_controller/odom")
    speeds = np.interp(written.times, source.times, source.twists[:, 0])
    moving = speeds > 0.5
    assert moving.mean() > 0.3
    assert np.sqrt(np.mean((written.twists[moving, 0] - speeds[moving]) ** 2)) < 1e-9
