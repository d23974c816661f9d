"""``diffdrive synth``: what a robot would have logged along a trajectory, as a bag or table."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from diffdrive import sensors
from diffdrive.cli.options import (
    Command,
    Parents,
    add_encoder_options,
    add_imu_options,
    add_pairs_option,
    add_wheel_noise_option,
    example_trajectory,
    key_numbers,
    refuse_unused,
    robot_from,
    wheel_pair,
)
from diffdrive.estimation.gyro import rotation_from_rpy
from diffdrive.io import read_trajectory
from diffdrive.sensor_noise import GyroNoise, WheelNoise


def run_synth(args: argparse.Namespace) -> int:
    robot, ticks = robot_from(args)
    if args.input is None:
        example = example_trajectory(robot, dt=0.02)
        times, poses, what = example.times, example.poses, "the built-in example"
    else:
        times, poses = read_trajectory(args.input, args.time_unit, args.topic)
        what = str(args.input)
    if np.isnan(poses[:, 2]).any():
        raise ValueError(f"{what}: the trajectory has no heading; sensors need the full pose")
    encoders = sensors.encoder_readings(
        robot, times, poses, _encoder_model(args, ticks), seed=args.seed
    )
    gyro = sensors.gyro_readings(
        robot, times, poses, _gyro_model(args), seed=None if args.seed is None else args.seed + 1
    )
    commands = sensors.commands_of(robot, times, poses)
    absolute = _absolute(args, robot, times, poses)
    format = args.format or _format_of(args.output)
    # One clock for the table and the bag: both stamped as the bag must be (ROS reads a
    # stamp of 0 as unset), so a run's two files pair pose for pose.
    offset = sensors.bag_time_offset(times[0]) if args.time_offset is None else args.time_offset
    if not math.isfinite(offset):
        raise ValueError(f"--time-offset must be finite (s), got {offset}")
    if format != "csv" and not times[0] + offset > 0.0:
        raise ValueError(
            f"--time-offset {offset:g}: the bag's first stamp would be {times[0] + offset:g} "
            f"s, and ROS reads a stamp of 0 as unset; give an offset above {0.0 - times[0]:g}"
        )
    if format == "csv":
        if absolute is not None:
            raise ValueError("a pose or GPS sensor needs a bag (-o NAME.mcap, or --format ros2)")
        sensors.write_table(args.output, encoders, gyro=gyro, commands=commands, time_offset=offset)
        written = "wheels, gyro_z, commands and truth as a table"
    else:
        streams: dict[str, Any] = {"encoders": encoders, "gyro": gyro, "commands": commands}
        if absolute is not None:
            streams["absolute"] = absolute
        origin = tuple(args.gps) if args.gps else None
        sensors.write_bag(
            args.output,
            format=format,
            origin=origin,
            time_offset=offset,
            truth=(times, poses),
            **streams,
        )
        written = "/joint_states, /imu/data, /cmd_vel" + (
            "" if absolute is None else (", /fix" if args.gps else ", /pose")
        )
        written += ", the truth on /ground_truth"
    if not args.quiet:
        print(f"synth: {len(times)} samples along {what}: {written} in {args.output} ({format})")
        if offset:
            # The one thing that makes the run's clock differ from the trajectory's.
            print(
                f"synth: the stamps are the trajectory's plus {offset:g} s, in a table as in a "
                "bag (ROS reads a stamp of 0 as unset): evaluate against the run's own truth, "
                f"or give --t-offset {-offset:g} against {what}"
            )
    return 0


def _format_of(path: Path) -> str:
    suffix = path.suffix.lower()
    return "csv" if suffix == ".csv" else ("mcap" if suffix == ".mcap" else "ros2")


def _encoder_model(args: argparse.Namespace, ticks: float | None) -> sensors.EncoderModel:
    if args.unsigned and args.counter_bits is None:
        raise ValueError("--unsigned describes a counter that rolls over: give --counter-bits")
    slips = tuple(
        sensors.Slip(float(start), float(stop), wheel, float(ratio))
        for start, stop, wheel, ratio in (args.slip or [])
    )
    return sensors.EncoderModel(
        ticks_per_revolution=ticks,
        counter_bits=args.counter_bits,
        signed=not args.unsigned,
        radius_bias=tuple(args.radius_bias),
        track_bias=args.track_bias,
        wheel_noise=WheelNoise(*(wheel_pair(args) or (0.0, 0.0))),
        slips=slips,
        jitter=args.jitter,
        latency=args.latency,
        drop=args.drop,
    )


# --gyro's settings: (how GyroModel or GyroNoise names it, unit).
GYRO_KEYS = {
    "bias": ("bias", "rad/s"),
    "scale": ("scale", "relative"),
    "arw": ("angle_random_walk", "rad/s/sqrt(Hz)"),
    "rrw": ("rate_random_walk", "rad/s^2/sqrt(Hz)"),
    "instability": ("bias_instability", "rad/s"),
}
# --pose's settings: AbsoluteModel's, beside --pose-sigma.
POSE_KEYS = {
    "period": "s between poses (default: each sample)",
    "latency": "s until a pose arrives",
    "dropout": "probability one is lost",
    "outlier": "probability of an outlier",
}


def _gyro_model(args: argparse.Namespace) -> sensors.GyroModel:
    given = {
        GYRO_KEYS[key][0]: value
        for key, value in key_numbers("--gyro", args.gyro, GYRO_KEYS).items()
    }
    return sensors.GyroModel(
        bias=given.pop("bias", 0.0),
        scale=given.pop("scale", 0.0),
        noise=GyroNoise(**given),
        mounting=rotation_from_rpy(*args.imu_mount),
    )


def _absolute(args, robot, times, poses):
    """A pose sensor's readings (or a GPS's, with --gps), or None without --pose-sigma."""
    shaping = key_numbers("--pose", args.pose, POSE_KEYS)
    if args.pose_sigma is None and args.gps is None:
        refuse_unused({"--pose": bool(shaping)}, "a pose or GPS sensor's (--pose-sigma or --gps)")
        return None
    sigma = tuple(args.pose_sigma or (0.0, 0.0, 0.0))
    model = sensors.AbsoluteModel(
        sigma=sigma,
        period=shaping.get("period"),
        latency=shaping.get("latency", 0.0),
        dropout=shaping.get("dropout", 0.0),
        outlier=shaping.get("outlier", 0.0),
        position_only=args.gps is not None,
    )
    seed = None if args.seed is None else args.seed + 2
    return sensors.absolute_readings(robot, times, poses, model, seed=seed)


EPILOGS = {
    "synth": """examples:
  diffdrive synth -o run.mcap                    the built-in path: joints, IMU, commands
  diffdrive synth path.csv --robot robot.toml --ticks-per-revolution 4096 --counter-bits 16 \\
      --k 1e-5 --slip 6 6.4 left 0.5 --gyro arw=2e-3,bias=0.01 --seed 1 -o run.mcap
  diffdrive synth --ticks-per-revolution 4096 -o run.csv    a wheel log odometry reads

Every error source defaults to none (an ideal sensor); --seed makes the run repeatable. A bag
holds the trajectory itself as nav_msgs/Odometry on /ground_truth (world -> base_link, exact:
covariances at the 1e-9 floor), on the bag's clock; a table holds it as x, y, theta. ROS
reads a stamp of 0 as unset: a run's times, in a table as in a bag, start --time-offset s in
(default 1 s for a path that starts at 0), so that its two files share one clock.""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive synth``."""
    synth = command(
        "synth",
        "what a robot would log along a trajectory: encoders, gyro, poses or GPS, commands",
        [parents.robot],
        run_synth,
        EPILOGS["synth"],
    )
    synth.add_argument("input", nargs="?", type=Path, help="trajectory (CSV, JSON lines, TUM, bag)")
    synth.add_argument("--topic", metavar="TOPIC", help="for a bag: the trajectory's topic")
    synth.add_argument("--time-unit", choices=("s", "ms", "us", "ns"), help="of t (default s)")
    synth.add_argument("-o", "--output", type=Path, default=Path("synth.mcap"))
    synth.add_argument("--format", choices=("mcap", "ros2", "csv"), help="default: by suffix")
    synth.add_argument("--seed", type=int, help="the random numbers' seed (default: fresh)")
    synth.add_argument("--time-offset", type=float, help="s added to the run's times, table or bag")
    synth.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    encoder = synth.add_argument_group("encoders")
    add_encoder_options(encoder)
    encoder.add_argument("--unsigned", action="store_true", help="an unsigned counter")
    encoder.add_argument(
        "--radius-bias",
        type=float,
        nargs=2,
        default=(0.0, 0.0),
        metavar=("LEFT", "RIGHT"),
        help="relative radius errors",
    )
    encoder.add_argument("--track-bias", type=float, default=0.0, help="relative track error")
    add_wheel_noise_option(encoder, "Odometry's; default 0")
    encoder.add_argument(
        "--slip",
        nargs=4,
        action="append",
        metavar=("START", "STOP", "WHEEL", "RATIO"),
        help="a slip episode (s, s, left|right|both, ratio); repeat for more",
    )
    encoder.add_argument("--jitter", type=float, default=0.0, help="sampling jitter, s")
    encoder.add_argument("--latency", type=float, default=0.0, help="encoder latency, s")
    encoder.add_argument("--drop", type=float, default=0.0, help="probability a row is lost")
    gyro = synth.add_argument_group("gyro (rad/s)")
    add_pairs_option(
        gyro,
        "--gyro",
        "its errors, each 0 unless given: "
        + ", ".join(f"{key} ({unit})" for key, (_, unit) in GYRO_KEYS.items()),
    )
    add_imu_options(gyro, topic=False)
    pose = synth.add_argument_group("a pose sensor (or a GPS) in the bag")
    pose.add_argument(
        "--pose-sigma",
        type=float,
        nargs=3,
        metavar=("X", "Y", "THETA"),
        help="its standard deviations, m, m, rad: a pose sensor in the bag (/pose)",
    )
    add_pairs_option(
        pose,
        "--pose",
        "its timing and faults: " + "; ".join(f"{k}, {h}" for k, h in POSE_KEYS.items()),
    )
    pose.add_argument(
        "--gps",
        type=float,
        nargs=3,
        metavar=("LAT", "LON", "HEIGHT"),
        help="positions as NavSatFix about this origin (deg, deg, m)",
    )
