"""What the subcommands share: their options, the robot they describe, reading logs and
writing results."""

from __future__ import annotations

import argparse
import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from diffdrive.demo import (
    EXAMPLE_DURATION,
    example_log,
    example_robot,
    example_wheel_velocities,
)
from diffdrive.encoders import MAX_COUNTER_BITS, MIN_COUNTER_BITS
from diffdrive.integrate import METHODS, Method
from diffdrive.io import (
    FORMATS,
    ROBOT_KEYS,
    TIME_UNITS,
    Run,
    TableError,
    is_bag,
    overridden,
    read_robot,
    read_run,
    read_trajectory,
    robot_from_settings,
    write_trajectory,
)
from diffdrive.io.trajectories import COVARIANCE_COLUMNS
from diffdrive.model import Robot
from diffdrive.sensor_noise import DEFAULT as DEFAULT_WHEEL_NOISE
from diffdrive.sensor_noise import WheelNoise
from diffdrive.simulation import simulate

ROBOT_DEFAULTS = "the built-in example robot: 42 mm wheels, track 0.2 m"
ASSUMED_ROBOT = "the built-in robot (42 mm wheels, track 0.2 m; assumed: give --robot)"


LOG_COLUMNS = """input: a table (CSV, or separated by ; tab or spaces; UTF-8, a BOM is fine)
with columns t (s, or --time-unit) and one pair of wheel columns:
  left_ticks, right_ticks        absolute counter readings (give --ticks-per-revolution,
                                 and --counter-bits for counters that roll over)
  left_angle, right_angle        accumulated wheel angles, rad
  left_velocity, right_velocity  rad/s, each held from its row's time until the next row's
                                 (the last row's is not used), in every command
and optionally x, y, theta (ground truth): the run then starts from its first pose. An
OptiOdom run file (no header: t, x, y, theta, ticks_right, ticks_left) is read too."""


TRAJECTORY_FILES = """trajectory files: CSV (t, x, y, theta), JSON lines or TUM
(t x y z qx qy qz qw), told apart by their content; a robot column holds several robots."""


def robot_options(required: bool = False) -> argparse.ArgumentParser:
    """The robot's options; ``required``: the command refuses to assume the built-in one."""
    options = argparse.ArgumentParser(add_help=False)
    title = (
        "robot (required: a robot file or the geometry flags; the built-in one is not assumed)"
        if required
        else f"robot (default: {ROBOT_DEFAULTS})"
    )
    group = options.add_argument_group(title)
    group.add_argument("--robot", type=Path, help="a robot file (TOML) with the settings below")
    helps = {
        "ticks_per_revolution": "encoder counts per wheel revolution",
        "track_width": "m, the FULL distance between the wheels' contact points",
        "half_track": "m, half the track width (the notes' b, d, D or L); instead of it",
        "icr_left": "m: a skid-steer robot's left ICR on body y (instead of the track)",
        "icr_right": "m: its right ICR on body y",
        "icr_x": "m: its ICR on body x (the point that does not slide sideways)",
    }
    for name in ROBOT_KEYS:
        group.add_argument(
            f"--{name.replace('_', '-')}", type=float, metavar="X", help=helps.get(name, "m")
        )
    return options


def log_options() -> argparse.ArgumentParser:
    options = argparse.ArgumentParser(add_help=False)
    group = options.add_argument_group("log")
    group.add_argument(
        "--time-unit",
        choices=TIME_UNITS,
        help="unit of the t column (default s; plainly other units are refused)",
    )
    group.add_argument(
        "--counter-bits",
        type=between(MIN_COUNTER_BITS, MAX_COUNTER_BITS),
        metavar="B",
        help=f"width of the encoder counters ({MIN_COUNTER_BITS}-{MAX_COUNTER_BITS}), for "
        "roll-over; default: counters that never roll over",
    )
    bags = options.add_argument_group("a ROS bag or MCAP file as the log (diffdrive[ros])")
    bags.add_argument(
        "--joint-topic",
        default="/joint_states",
        metavar="TOPIC",
        help="sensor_msgs/JointState topic (default /joint_states)",
    )
    bags.add_argument("--left-joint", metavar="NAME", help="the left wheel's joint name")
    bags.add_argument(
        "--wheel-topic",
        metavar="TOPIC",
        help="instead of joints: a drive controller's nav_msgs/Odometry (the motion between "
        "its poses) or Twist commands (each held until the next), through the robot's inverse "
        "kinematics",
    )
    bags.add_argument("--right-joint", metavar="NAME", help="the right wheel's joint name")
    bags.add_argument(
        "--reference-topic",
        metavar="TOPIC",
        help="nav_msgs/Odometry (or tf:PARENT:CHILD) as the ground truth",
    )
    return options


def output_options(default: str) -> argparse.ArgumentParser:
    options = argparse.ArgumentParser(add_help=False)
    options.add_argument("-o", "--output", type=Path, default=Path(default), help="file to write")
    options.add_argument(
        "--format",
        choices=OUTPUT_FORMATS,
        help="default: from the file's suffix; mcap (a file) and ros2 (a bag "
        "folder) write nav_msgs/Odometry and /tf",
    )
    options.add_argument("--frame", default="odom", help="bag output: the parent frame (odom)")
    options.add_argument(
        "--child-frame", default="base_link", help="bag output: the robot's frame (base_link)"
    )
    options.add_argument("--method", choices=METHODS, default="exact", help="default: exact")
    options.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    return options


# The settings that fix a robot's geometry; ticks per revolution are the encoders', not it.
GEOMETRY_KEYS = tuple(key for key in ROBOT_KEYS if key != "ticks_per_revolution")


def robot_settings(args: argparse.Namespace) -> dict[str, float]:
    """The robot file's settings with the flags over them."""
    flags = {name: getattr(args, name) for name in ROBOT_KEYS if getattr(args, name) is not None}
    from_file = read_robot(args.robot) if args.robot else {}
    return overridden(from_file, flags, lambda key: "--" + key.replace("_", "-"))


def robot_given(args: argparse.Namespace) -> bool:
    """Whether the command was told the robot's geometry (radii, track: a robot file's or the
    flags'); ``--ticks-per-revolution`` alone describes the encoders, not the robot."""
    return any(key in GEOMETRY_KEYS for key in robot_settings(args))


def refuse_assumed_robot(args: argparse.Namespace, writes: str) -> None:
    """``ValueError`` when the command, which ``writes`` the robot's geometry or what follows
    from it into a file, was told no geometry: the built-in robot's there would be a wrong
    answer nothing downstream questions. The message names the flags."""
    if robot_given(args):
        return
    only = (
        " (--ticks-per-revolution is the encoders', not the geometry)"
        if getattr(args, "ticks_per_revolution", None) is not None
        or "ticks_per_revolution" in robot_settings(args)
        else ""
    )
    raise ValueError(
        f"{writes}: give --robot FILE, or --wheel-radius and --track-width{only}; the built-in "
        "robot is not assumed here"
    )


def assumed_robot(args: argparse.Namespace) -> str | None:
    """What the command assumed of a robot it was not told of, for a file's log; else None.

    A file was driven by some real robot: the built-in one's geometry is only a guess there,
    and a report must say so (the built-in example needs no such word)."""
    return None if robot_given(args) or args.input is None else ASSUMED_ROBOT


def robot_note(args: argparse.Namespace) -> str:
    """A report's line on the robot it assumed (with its newline), or nothing."""
    assumed = assumed_robot(args)
    return "" if assumed is None else f"\nrobot: {assumed}"


def checked_ticks(ticks: float | None) -> float | None:
    """A robot's ticks per revolution, refused unless finite and > 0 (None: not given)."""
    if ticks is not None and not (math.isfinite(ticks) and ticks > 0):
        raise ValueError(f"ticks_per_revolution must be finite and > 0, got {ticks!r}")
    return ticks


def robot_from(args: argparse.Namespace) -> tuple[Robot, float | None]:
    """The robot of the command's options, and its ticks per revolution if known."""
    settings = robot_settings(args)
    ticks = checked_ticks(settings.pop("ticks_per_revolution", None))
    if not settings:
        return example_robot(), ticks
    return robot_from_settings(settings, f" (in {args.robot})" if args.robot else ""), ticks


OutputFormat = Literal["csv", "jsonl", "tum", "mcap", "ros2"]
OUTPUT_FORMATS: tuple[OutputFormat, ...] = (*FORMATS, "mcap", "ros2")


def output_format(args: argparse.Namespace) -> OutputFormat:
    """``--format``, else the output's suffix if it names a format, else csv."""
    wanted = args.format or args.output.suffix.lstrip(".").lower()
    return next((known for known in OUTPUT_FORMATS if known == wanted), "csv")


def write_output(
    args,
    times,
    poses,
    what: str,
    columns=None,
    covariances=None,
    twists=None,
    twist_covariances=None,
) -> None:
    """Write the trajectory in the chosen format: a file of poses and ``columns``, or
    ``nav_msgs/Odometry`` and ``/tf`` with ``covariances``, ``twists`` and
    ``twist_covariances`` to a bag."""
    format = output_format(args)
    if format == "mcap" or format == "ros2":
        from diffdrive.io.ros import write_odometry

        written = [
            write_odometry(
                args.output,
                times,
                poses,
                covariances,
                twists,
                twist_covariances,
                format=format,
                frame=args.frame,
                child_frame=args.child_frame,
            )
        ]
    else:
        frames = (getattr(args, "frame", "odom"), getattr(args, "child_frame", "base_link"))
        if frames != ("odom", "base_link"):
            raise ValueError(
                f"--frame and --child-frame name a bag's frames; a {format} file has none "
                "(write .mcap, or --format ros2)"
            )
        written = write_trajectory(args.output, times, poses, format, columns)
    if not args.quiet:
        where = ", ".join(map(str, written))
        print(f"{what}: wrote {poses.shape[-2]} poses to {where} ({format})")


def read_log_of(args: argparse.Namespace, path: Path | None = None) -> Run:
    """The log of ``path`` (default: the command's input), a file or a bag topic."""
    path = args.input if path is None else path
    if path is None:
        return example_log()
    return read_run(
        path,
        args.time_unit,
        joint_topic=args.joint_topic,
        left_joint=args.left_joint,
        right_joint=args.right_joint,
        reference_topic=args.reference_topic,
        wheel_topic=args.wheel_topic,
        robot=robot_from(args)[0] if args.wheel_topic else None,
    )


# The covariance's distinct entries, by their index in the row-major 3x3 matrix: the pose's
# over (x, y, theta), the twist's over (vx, vy, omega).
TWIST_COVARIANCE_COLUMNS = {
    "cov_vxvx": 0,
    "cov_vxvy": 1,
    "cov_vxomega": 2,
    "cov_vyvy": 4,
    "cov_vyomega": 5,
    "cov_omegaomega": 8,
}


def matrix_columns(matrices: np.ndarray, names: dict[str, int]) -> dict[str, np.ndarray]:
    """The distinct entries of symmetric 3x3 ``matrices`` ``(N, 3, 3)`` as named columns."""
    flat = np.asarray(matrices).reshape(-1, 9)
    return {name: flat[:, index] for name, index in names.items()}


def estimate_columns(args, covariances, twists, twist_covariances, covariance: bool) -> dict:
    """A trajectory file's extra columns: with ``--twist`` the twist ``vx, vy, omega``; with
    ``covariance`` the pose covariance's entries and, with ``--twist``, the twist's."""
    columns: dict[str, np.ndarray] = {}
    if args.twist:
        columns.update(vx=twists[:, 0], vy=twists[:, 1], omega=twists[:, 2])
    if covariance:
        columns.update(matrix_columns(covariances, COVARIANCE_COLUMNS))
        if args.twist:
            columns.update(matrix_columns(twist_covariances, TWIST_COVARIANCE_COLUMNS))
    return columns


def wheel_noise(
    args: argparse.Namespace, robot: Robot | None = None, log=None, increments=None
) -> tuple[WheelNoise, str]:
    """``--k-left`` and ``--k-right`` (m) as a ``WheelNoise`` and a report's line (with its
    newline) on what was assumed, or nothing. A wheel not given is identified from the log's
    ground truth where it has one (``log.truth``; ``noise.identify`` of ``increments`` against
    it, the reference held at motion capture's accuracy), else the library's default
    (``diffdrive.sensor_noise.DEFAULT``). Both 0 are refused for a bag: its
    ``nav_msgs/Odometry`` would carry zero covariances, which a filter reads as exact
    (robot_localization floors them to 1e-9 and holds the robot to them)."""
    given = (args.k_left, args.k_right)
    k_left = DEFAULT_WHEEL_NOISE.left if args.k_left is None else args.k_left
    k_right = DEFAULT_WHEEL_NOISE.right if args.k_right is None else args.k_right
    source = "a default where not given: --k-left, --k-right"
    truth = None if log is None else log.truth
    if None in given and truth is not None and robot is not None:
        from diffdrive.calibration.noise import identify_wheel_noise

        found, why = identify_wheel_noise(robot, increments, truth)
        if found is None:
            source = f"the default: {why}"
        else:
            source = f"{why}; --k-left, --k-right to give them"
            k_left = found.left if args.k_left is None else k_left
            k_right = found.right if args.k_right is None else k_right
    noise = WheelNoise(k_left, k_right)
    if k_left == 0.0 and k_right == 0.0 and output_format(args) in ("mcap", "ros2"):
        raise ValueError(
            "--k-left 0 --k-right 0: the /odom messages would carry zero covariances, which ROS "
            "filters read as exact; give the wheels' noise (k > 0, m)"
        )
    if all(k is not None for k in given):
        return noise, ""
    if any(k is not None for k in given):
        source = (
            f"the {'left' if args.k_left is not None else 'right'} as given, the other {source}"
        )
    return noise, f"\nwheel noise: k = {k_left:.3g} m left, {k_right:.3g} m right ({source})"


def example_trajectory(robot: Robot, dt: float = 0.01, method: Method = "exact"):
    """The built-in driving history, simulated."""
    return simulate(
        robot, example_wheel_velocities, dt=dt, duration=EXAMPLE_DURATION, method=method
    )


def trajectory_or_example(args: argparse.Namespace, robot: Robot):
    """``(times, poses, what)`` from the input trajectory (file or bag topic), or the
    built-in example."""
    if args.input is None:
        example = example_trajectory(robot)
        return example.times, example.poses, "the built-in example"
    what = f"{args.input} {args.topic}" if args.topic else str(args.input)
    return (*read_trajectory(args.input, args.time_unit, args.topic), what)


def print_values(values: dict[str, float], as_json: bool, units: dict[str, str]) -> None:
    if as_json:
        print(json.dumps({k: (v if math.isfinite(v) else str(v)) for k, v in values.items()}))
        return
    for name, value in values.items():
        print(f"{name:15} {value + 0.0:12.6g} {units[name]}")  # + 0.0: no "-0" printed


# argparse's own pattern misses the exponent form (-1e-3), which it then takes for an option.
NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def refuse_unused(options: dict[str, bool], why: str) -> None:
    """Refuse the options given (``True``) that would change nothing in this run: a user who
    set them would believe they had. ``ValueError``: their names, then ``why``."""
    given = [name for name, used in options.items() if used]
    if given:
        raise ValueError(f"{', '.join(given)}: {why}")


def between(smallest: int, largest: int):
    """An argparse type: a whole number from ``smallest`` to ``largest``."""

    def parse(text: str) -> int:
        value = int(text)
        if not smallest <= value <= largest:
            raise argparse.ArgumentTypeError(f"must be from {smallest} to {largest}, got {value}")
        return value

    parse.__name__ = "int"
    return parse


def at_least(smallest: int):
    """An argparse type: a whole number >= ``smallest``."""

    def parse(text: str) -> int:
        value = int(text)
        if value < smallest:
            raise argparse.ArgumentTypeError(f"must be at least {smallest}, got {value}")
        return value

    parse.__name__ = "int"
    return parse


# How a subcommand module adds its parser: command(name, help, parents, run, epilog).
Command = Callable[..., argparse.ArgumentParser]


@dataclass(frozen=True)
class Parents:
    """The option groups that several subcommands share (argparse parent parsers)."""

    robot: argparse.ArgumentParser
    logs: argparse.ArgumentParser
    times: argparse.ArgumentParser
    pictures: argparse.ArgumentParser
    robot_required: argparse.ArgumentParser


def gyro_of(args: argparse.Namespace, log: Run, path: Path | None = None):
    """The gyro of the command's log (``path``, default its input): a bag's IMU topic (rotated
    by --imu-rpy), or the log's gyro_z column; None without one."""
    from diffdrive.estimation.gyro import Gyro, rotation_from_rpy

    source = args.input if path is None else path
    if not np.all(np.isfinite(args.imu_rpy)):
        raise ValueError(f"--imu-rpy must be three finite angles (degrees), got {args.imu_rpy}")
    if args.gyro_topic is None and any(args.imu_rpy):
        # A gyro_z column is the body's yaw rate already: no mounting is applied to it.
        raise ValueError("--imu-rpy turns a bag's IMU (--gyro-topic); a gyro_z column has none")
    if args.gyro_topic is not None:
        if source is None or not is_bag(source):
            raise TableError("--gyro-topic needs a bag as the log")
        from diffdrive.io import ros

        imu = ros.read_imu(source, args.gyro_topic)
        mounting = rotation_from_rpy(*np.radians(args.imu_rpy))
        return Gyro.from_imu(imu.times, imu.angular_velocity, mounting)
    if log.gyro_rates is not None:
        return Gyro(log.times, log.gyro_rates)
    return None


def add_datum_option(group) -> None:
    """``--datum LAT LON ALT``: the GPS frame's origin, as navsat_transform's datum."""
    group.add_argument(
        "--datum",
        type=float,
        nargs=3,
        metavar=("LAT", "LON", "ALT"),
        help="the GPS frame's origin (deg, deg, m), as robot_localization's navsat_transform "
        "datum: x east, y north, theta counter-clockwise from east (default: the first fix)",
    )


def add_imu_options(group, topic: bool = True) -> None:
    """``--gyro-topic`` (unless ``topic`` is False) and ``--imu-rpy``, the IMU's mounting."""
    if topic:
        group.add_argument("--gyro-topic", metavar="TOPIC", help="sensor_msgs/Imu topic of the bag")
    group.add_argument(
        "--imu-rpy",
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=("ROLL", "PITCH", "YAW"),
        help="the IMU's mounting in the body, degrees (default 0 0 0: z up)",
    )
