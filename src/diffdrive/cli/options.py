"""What the subcommands share: their options, the robot they describe, reading logs and
writing results."""

from __future__ import annotations

import argparse
import json
import math
import re
from collections.abc import Callable, Collection
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
    read_robot_noise,
    read_run,
    read_trajectory,
    robot_from_settings,
    write_trajectory,
)
from diffdrive.io.read import read_commands
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
    add_pairs_option(
        group,
        "--robot",
        f"a robot file (TOML), or its settings given here: {', '.join(ROBOT_KEYS)} (m)",
        files=True,
    )
    group.add_argument("--wheel-radius", type=float, metavar="M", help="both wheels' radius, m")
    group.add_argument(
        "--track-width",
        type=float,
        metavar="M",
        help="m, the FULL distance between the wheels' contact points (half_track, the notes' "
        "b, d, D or L: --robot half_track=M)",
    )
    return options


def key_values(flag: str, text: str, keys: Collection[str]) -> dict[str, str]:
    """``KEY=VALUE[,KEY=VALUE...]`` given to ``flag``, as a dict of the texts; ``ValueError``
    naming the flag and the part that is not such a pair or names no key in ``keys``."""
    pairs: dict[str, str] = {}
    for part in text.split(","):
        key, equals, value = part.partition("=")
        key = key.strip()
        if not equals or not key or not value.strip():
            raise ValueError(f"{flag} {text!r}: {part!r} is not KEY=VALUE")
        if key not in keys:
            raise ValueError(f"{flag}: unknown setting {key!r}; known: {', '.join(sorted(keys))}")
        if key in pairs:
            raise ValueError(f"{flag} {text!r}: {key} given twice")
        pairs[key] = value.strip()
    return pairs


def add_pairs_option(group, flag: str, help: str, files: bool = False) -> None:
    """``flag KEY=VALUE,...`` (``files``: or a TOML file of them), repeated to add, the later
    winning."""
    group.add_argument(
        flag,
        action="append",
        metavar=("FILE|" if files else "") + "KEY=VALUE,...",
        help=f"{help}; repeat to add, the later winning",
    )


def key_numbers(flag: str, entries: list[str] | None, keys: Collection[str]) -> dict[str, float]:
    """Every ``KEY=VALUE`` of ``flag``'s ``entries`` as numbers, the later winning."""
    values: dict[str, float] = {}
    for entry in entries or ():
        given = key_values(flag, entry, keys)
        values.update({key: number_of(flag, key, text) for key, text in given.items()})
    return values


def number_of(flag: str, key: str, text: str) -> float:
    """``text`` as a float; ``ValueError`` naming ``flag`` and ``key`` when it is none."""
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"{flag} {key}={text}: {text!r} is not a number") from None


def log_options() -> argparse.ArgumentParser:
    options = argparse.ArgumentParser(add_help=False)
    group = options.add_argument_group("log")
    group.add_argument(
        "--time-unit",
        choices=TIME_UNITS,
        help="unit of the t column (default s; plainly other units are refused)",
    )
    add_encoder_options(group)
    bags = options.add_argument_group("a ROS bag or MCAP file as the log (diffdrive[ros])")
    bags.add_argument(
        "--joint-topic",
        default="/joint_states",
        metavar="TOPIC",
        help="sensor_msgs/JointState topic (default /joint_states)",
    )
    bags.add_argument(
        "--joints",
        nargs=2,
        metavar=("LEFT", "RIGHT"),
        help="the wheels' joint names in it",
    )
    bags.add_argument(
        "--wheel-topic",
        metavar="TOPIC",
        help="instead of joints: a drive controller's nav_msgs/Odometry (the motion between "
        "its poses) or Twist commands (each held until the next), through the robot's inverse "
        "kinematics",
    )
    bags.add_argument(
        "--reference-topic",
        metavar="TOPIC",
        help="nav_msgs/Odometry (or tf:PARENT:CHILD) as the ground truth",
    )
    return options


def add_encoder_options(group) -> None:
    """``--ticks-per-revolution`` and ``--counter-bits``: the encoders' counts."""
    group.add_argument(
        "--ticks-per-revolution",
        type=float,
        metavar="N",
        help="encoder counts per wheel revolution (or the robot file's ticks_per_revolution)",
    )
    group.add_argument(
        "--counter-bits",
        type=between(MIN_COUNTER_BITS, MAX_COUNTER_BITS),
        metavar="B",
        help=f"width of the encoder counters ({MIN_COUNTER_BITS}-{MAX_COUNTER_BITS}), for "
        "roll-over; default: counters that never roll over",
    )


def output_options(default: str) -> argparse.ArgumentParser:
    options = argparse.ArgumentParser(add_help=False)
    options.add_argument("-o", "--output", type=Path, default=Path(default), help="file to write")
    options.add_argument(
        "--format",
        choices=OUTPUT_FORMATS,
        help="default: from the file's suffix; mcap (a file) and ros2 (a bag "
        "folder) write nav_msgs/Odometry and /tf",
    )
    options.add_argument(
        "--frames",
        nargs=2,
        default=BAG_FRAMES,
        metavar=("PARENT", "CHILD"),
        help="bag output: the parent frame and the robot's (default: odom base_link)",
    )
    options.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    return options


def add_method_option(parser) -> None:
    """``--method``: how each interval is integrated."""
    parser.add_argument("--method", choices=METHODS, default="exact", help="default: exact")


def add_wheel_noise_option(parser, default: str) -> None:
    """``--k K [K_RIGHT]``: the wheels' error constants (m), one for both or left and right."""
    parser.add_argument(
        "--k",
        type=float,
        nargs="+",
        metavar=("K", "K_RIGHT"),
        help=f"the wheels' error constant, m: one for both, or left and right ({default})",
    )


def wheel_pair(args: argparse.Namespace) -> tuple[float, float] | None:
    """``--k``'s left and right, or None where not given; ``ValueError`` past two."""
    if args.k is None:
        return None
    if len(args.k) > 2:
        raise ValueError(f"--k takes one value (both wheels) or two (left, right), got {args.k}")
    return args.k[0], args.k[-1]


# The settings the flags give; the rest through --robot KEY=VALUE.
ROBOT_FLAGS = ("wheel_radius", "track_width", "ticks_per_revolution")
BAG_FRAMES = ("odom", "base_link")

# The settings that fix a robot's geometry; ticks per revolution are the encoders', not it.
GEOMETRY_KEYS = tuple(key for key in ROBOT_KEYS if key != "ticks_per_revolution")


def robot_settings(args: argparse.Namespace) -> dict[str, float]:
    """The robot's settings: its files (``--robot FILE``) each over the one before, then what
    the command line gives (``--robot KEY=VALUE`` and the flags) over them all; two of those
    that set the same length are refused."""
    settings: dict[str, float] = {}
    given: dict[str, float] = {}
    for entry in args.robot or ():
        if "=" in entry:
            given.update(key_numbers("--robot", [entry], ROBOT_KEYS))
        else:
            settings = overridden(settings, read_robot(Path(entry)))
    flags = {name for name in ROBOT_FLAGS if getattr(args, name, None) is not None}
    given.update({name: getattr(args, name) for name in flags})

    def named(key: str) -> str:
        return "--" + key.replace("_", "-") if key in flags else f"--robot {key}"

    return overridden(settings, given, named)


def robot_noise(args: argparse.Namespace) -> dict[str, tuple[object, str]]:
    """The noise the robot files given hold (``read_robot_noise``), each part with the file it
    came from: a later file's part over an earlier's."""
    found: dict[str, tuple[object, str]] = {}
    for entry in args.robot or ():
        if "=" not in entry:
            found.update({name: (part, entry) for name, part in read_robot_noise(entry).items()})
    return found


def noise_changes(args: argparse.Namespace) -> tuple[dict[str, object], str]:
    """The robot files' noise parts other than the wheels' (``wheel_noise`` takes those) as
    ``EstimatorSettings`` changes by name, and a report's line on them (with its newline), or
    nothing."""
    parts = {name: found for name, found in robot_noise(args).items() if name != "wheel_noise"}
    lines = "".join(
        f"\n{name.replace('_', ' ')}: from {source}" for name, (_, source) in parts.items()
    )
    return {name: part for name, (part, _) in parts.items()}, lines


def robot_files(args: argparse.Namespace) -> str:
    """`` (in FILE, ...)`` of the robot files given, for a message; else nothing."""
    files = [entry for entry in args.robot or () if "=" not in entry]
    return f" (in {', '.join(files)})" if files else ""


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
    return robot_from_settings(settings, robot_files(args)), ticks


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
                frame=args.frames[0],
                child_frame=args.frames[1],
            )
        ]
    else:
        if tuple(args.frames) != BAG_FRAMES:
            raise ValueError(
                f"--frames names a bag's frames; a {format} file has none "
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
        left_joint=joints(args)[0],
        right_joint=joints(args)[1],
        reference_topic=args.reference_topic,
        wheel_topic=args.wheel_topic,
        robot=robot_from(args)[0] if args.wheel_topic else None,
    )


def joints(args: argparse.Namespace) -> tuple[str | None, str | None]:
    """``--joints LEFT RIGHT``, or (None, None)."""
    return (args.joints[0], args.joints[1]) if args.joints else (None, None)


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


def estimate_columns(
    covariances, twists, twist_covariances, *, twist: bool, covariance: bool = True
) -> dict:
    """A trajectory file's extra columns: with ``twist`` the twist ``vx, vy, omega``; with
    ``covariance`` the pose covariance's entries and, with ``twist``, the twist's."""
    columns: dict[str, np.ndarray] = {}
    if twist:
        columns.update(vx=twists[:, 0], vy=twists[:, 1], omega=twists[:, 2])
    if covariance:
        columns.update(matrix_columns(covariances, COVARIANCE_COLUMNS))
        if twist:
            columns.update(matrix_columns(twist_covariances, TWIST_COVARIANCE_COLUMNS))
    return columns


def wheel_noise(
    args: argparse.Namespace,
    robot: Robot | None = None,
    log=None,
    increments=None,
    *,
    gyro: bool = False,
) -> tuple[WheelNoise | None, str]:
    """``--k`` (m; one for both wheels, or left and right) as a ``WheelNoise`` and a report's
    line (with its newline) on what was assumed, or nothing. Not given, a robot file's
    ``[noise.wheel_noise]``; else identified from the log's ground truth where it has one
    (``log.truth``; ``noise.identify`` of ``increments`` against it, the reference held at
    motion capture's accuracy); else (or where the truth does not tell it), with a ``gyro``,
    None: the estimator identifies it from the wheels' turn against the gyro's and says so;
    else the library's default (``diffdrive.sensor_noise.DEFAULT``). Both 0 are refused for
    a bag: its ``nav_msgs/Odometry`` would carry zero covariances, which a filter reads as
    exact (robot_localization floors them to 1e-9 and holds the robot to them)."""
    given = wheel_pair(args)
    in_file = robot_noise(args).get("wheel_noise")
    if given is not None:
        return _refuse_zero(args, WheelNoise(*given)), ""
    if in_file is not None:
        part, source = in_file
        noise, why = WheelNoise.coerce(part), f"from {source}; --k to give them"
    else:
        noise, why = DEFAULT_WHEEL_NOISE, "a default where not given: --k K or --k LEFT RIGHT"
        truth = None if log is None else log.truth
        if truth is not None and robot is not None:
            from diffdrive.calibration.noise import identify_wheel_noise

            found, how = identify_wheel_noise(robot, increments, truth)
            if found is not None:
                noise, why = found, f"{how}; --k to give them"
            elif gyro:  # the estimator identifies it from the gyro, and says so
                return None, f"\nwheel noise: not from the ground truth ({how})"
            else:
                noise, why = DEFAULT_WHEEL_NOISE, f"the default: {how}"
        elif gyro:
            return None, ""
    line = f"\nwheel noise: k = {noise.left:.3g} m left, {noise.right:.3g} m right ({why})"
    return _refuse_zero(args, noise), line


def _refuse_zero(args: argparse.Namespace, noise: WheelNoise) -> WheelNoise:
    """``noise``, refused where both are 0 and the output is a bag (see ``wheel_noise``)."""
    if noise.left == 0.0 and noise.right == 0.0 and output_format(args) in ("mcap", "ros2"):
        raise ValueError(
            "--k 0: the /odom messages would carry zero covariances, which ROS filters read as "
            "exact; give the wheels' noise (k > 0, m)"
        )
    return noise


def reported_twists(log: Run, twists: np.ndarray, omega: bool) -> tuple[np.ndarray, str]:
    """The twists to write and a line on them: where the wheels came from a drive
    controller's ``Odometry``, the speed (and with ``omega``, the turn rate) it reports at
    each stamp. Its poses are sampled off their stamps, so their differences over the
    stamps alternate (0.81 / 1.18 m/s on the Husky bag, where it reports 1.0)."""
    if log.reported is None:
        return twists, ""
    twists = np.array(twists, dtype=float)
    twists[:, 0] = log.reported[:, 0]
    if omega:
        twists[:, 2] = log.reported[:, 1]
    what = "speed and turn rate" if omega else "speed"
    return (
        twists,
        f"\ntwist: the {what} the controller reports at each stamp (its poses lie off them)",
    )


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


def refuse_truth_topic_alone(args: argparse.Namespace) -> None:
    """``--truth-topic`` (the pictures' and ``evaluate``'s shared option) without ``--truth``,
    refused by name: the topic names one in the bag ``--truth`` gives."""
    if args.truth is None and args.truth_topic is not None:
        raise ValueError("--truth-topic names the truth's topic in the bag --truth gives")


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
    by --imu-mount), or the log's gyro_z column; None without one."""
    from diffdrive.estimation.gyro import Gyro, rotation_from_rpy

    source = args.input if path is None else path
    if not np.all(np.isfinite(args.imu_mount)):
        raise ValueError(f"--imu-mount must be three finite angles (rad), got {args.imu_mount}")
    if args.gyro_topic is None and any(args.imu_mount):
        # A gyro_z column is the body's yaw rate already: no mounting is applied to it.
        raise ValueError("--imu-mount turns a bag's IMU (--gyro-topic); a gyro_z column has none")
    if args.gyro_topic is not None:
        if source is None or not is_bag(source):
            raise TableError("--gyro-topic needs a bag as the log")
        from diffdrive.io import ros

        imu = ros.read_imu(source, args.gyro_topic)
        mounting = rotation_from_rpy(*args.imu_mount)
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
    """``--gyro-topic`` (unless ``topic`` is False) and ``--imu-mount``, the IMU's mounting."""
    if topic:
        group.add_argument("--gyro-topic", metavar="TOPIC", help="sensor_msgs/Imu topic of the bag")
    group.add_argument(
        "--imu-mount",
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=("ROLL", "PITCH", "YAW"),
        help="the IMU's mounting in the body, rad (default 0 0 0: z up; 1.5707963 0 0: a "
        "quarter roll)",
    )


def within_gyro(log: Run, gyro, note: str) -> tuple[Run, str]:
    """The log cut to the gyro's span (a bag's IMU may start a little after the wheels)."""
    inside = (log.times >= gyro.times[0]) & (log.times <= gyro.times[-1])
    if np.count_nonzero(inside) < 2:
        raise TableError(f"{log.source}: the gyro does not cover the log's times")
    if not inside.all():
        log = log.rows(inside)
        note += (
            f"\nthe log is cut to [{log.times[0]:.3f}, {log.times[-1]:.3f}] s, where the gyro is"
        )
    return log, note


def wheel_commands(args, robot, log: Run):
    """The wheel velocities commanded over each interval ``(T, 2)`` (``read_commands``, held;
    0 before the first), or None."""
    from diffdrive.dynamics.response import held_commands

    found = read_commands(args.input, robot, log, args.command_topic)
    return None if found is None else held_commands(*found, log.times[:-1])


def add_gyro_noise_options(group, held: str) -> None:
    """``--gyro-arw`` and ``--k``: the gyro's and the wheels' noise, ``held`` saying what
    each is when not given."""
    group.add_argument(
        "--gyro-arw",
        type=float,
        metavar="RAD_S_SQRT_HZ",
        help=f"the gyro's angle random walk ({held})",
    )
    group.add_argument("--k", type=float, metavar="M", help=f"the wheels' noise, m ({held})")
