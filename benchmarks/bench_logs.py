"""Offline logs through the command line: a 10^6-row CSV encoder log to a written trajectory,
and a bag of joint states, decode alone and decode + odometry.

The CSV log is split into its phases (read, odometry, write) and set against the C update
loop itself (``Odometry.update_arrays``, the checked update of every row in C) and against the
same updates called one at a time from Python (what ``diffdrive odometry`` did before). The bag
is a ROS 2 MCAP bag of ``sensor_msgs/JointState`` messages written here with rosbags; decoding
is rosbags' (``diffdrive.io.ros.read_joint_states``). Medians of several runs.

    pip install -e '.[ros]'
    python benchmarks/bench_logs.py [--rows 1000000] [--messages 200000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import platform
import tempfile
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive.cli import main as cli
from diffdrive.demo import example_robot
from diffdrive.io import ros
from timing import median_time  # benchmarks/timing.py

TICKS = 4096


def encoder_log(path: Path, rows: int) -> None:
    rng = np.random.default_rng(0)
    counts = np.cumsum(rng.integers(0, 40, (rows, 2)), axis=0)
    t = np.arange(rows) * 0.01
    with path.open("w") as stream:
        stream.write("t,left_ticks,right_ticks\n")
        rows = zip(t.tolist(), counts.tolist(), strict=True)
        stream.writelines(f"{a!r},{left},{right}\n" for a, (left, right) in rows)


def joint_state_bag(path: Path, messages: int) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    t = store.types
    angles = np.cumsum(np.random.default_rng(1).uniform(0, 0.05, (messages, 2)), axis=0)
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection(
            "/joint_states", "sensor_msgs/msg/JointState", typestore=store
        )
        for k in range(messages):
            nanoseconds = 10**9 + k * 10_000_000
            message = t["sensor_msgs/msg/JointState"](
                header=t["std_msgs/msg/Header"](
                    stamp=t["builtin_interfaces/msg/Time"](
                        sec=nanoseconds // 10**9, nanosec=nanoseconds % 10**9
                    ),
                    frame_id="",
                ),
                name=["wheel_right_joint", "wheel_left_joint"],
                position=angles[k, ::-1].copy(),
                velocity=np.array([]),
                effort=np.array([]),
            )
            writer.write(connection, nanoseconds, store.serialize_cdr(message, message.__msgtype__))


def csv_phases(folder: Path, rows: int, repeats: int) -> dict[str, float]:
    log_path, out = folder / "log.csv", folder / "odometry.csv"
    encoder_log(log_path, rows)
    robot = example_robot()
    log = dd.io.read_log(log_path)
    times = {"read": median_time(lambda: dd.io.read_log(log_path), repeats)}

    def c_loop():
        odometry = dd.Odometry(robot, ticks_per_revolution=TICKS)
        return odometry.update_arrays("ticks", log.wheels[:, 0], log.wheels[:, 1], log.times)

    times["odometry (C loop)"] = median_time(c_loop, repeats)
    poses, _ = c_loop()
    times["write"] = median_time(lambda: dd.io.write_trajectory(out, log.times, poses), repeats)
    argv = ["odometry", str(log_path), "--ticks-per-revolution", str(TICKS), "-o", str(out), "-q"]
    times["whole command"] = median_time(lambda: cli(argv), repeats)
    left, right = log.wheels[:, 0].tolist(), log.wheels[:, 1].tolist()
    stamps = log.times.tolist()

    def python_loop():
        odometry = dd.Odometry(robot, ticks_per_revolution=TICKS)
        for k in range(len(stamps)):
            odometry.update_ticks(left[k], right[k], stamps[k])
            odometry.pose  # noqa: B018  (what the command read for every row)

    times["odometry, one call a row from Python"] = median_time(python_loop, 1)
    return times


def bag_phases(folder: Path, messages: int, repeats: int) -> dict[str, float]:
    bag = folder / "joints"
    joint_state_bag(bag, messages)
    joints = ["--left-joint", "wheel_left_joint", "--right-joint", "wheel_right_joint"]
    out = folder / "bag_odometry.csv"

    def decode():
        ros.read_joint_states(bag, "wheel_left_joint", "wheel_right_joint")

    argv = [
        "odometry",
        str(bag),
        *joints,
        "--wheel-radius",
        "0.05",
        "--track-width",
        "0.3",
        "-o",
        str(out),
        "-q",
    ]
    return {
        "decode": median_time(decode, repeats),
        "decode + odometry + write": median_time(lambda: cli(argv), repeats),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=1_000_000)
    parser.add_argument("--messages", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(
        f"machine: {platform.machine()}, {platform.processor() or 'cpu'}; "
        f"python {platform.python_version()}; medians of {args.repeats} runs"
    )
    with tempfile.TemporaryDirectory() as folder:
        csv = csv_phases(Path(folder), args.rows, args.repeats)
        loop = csv["odometry (C loop)"]
        print(f"\nCSV encoder log, {args.rows} rows: s, and x the C update loop")
        for name, seconds in csv.items():
            print(f"  {name:38} {seconds:8.3f} s  {seconds / loop:7.1f} x")
        bag = bag_phases(Path(folder), args.messages, args.repeats)
        print(f"\nMCAP bag, {args.messages} JointState messages")
        for name, seconds in bag.items():
            print(f"  {name:38} {seconds:8.3f} s  {args.messages / seconds:9.0f} messages/s")


if __name__ == "__main__":
    main()
