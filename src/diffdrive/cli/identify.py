"""``diffdrive identify``: how a drive answers, from a log: kS, kV, kA from its voltages, its
velocity response from its commands, written as a drive file."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from diffdrive.cli.options import (
    Command,
    Parents,
    read_log_of,
    refuse_assumed_robot,
    robot_from,
)
from diffdrive.dynamics import identify_drive
from diffdrive.io import TableError, write_drive
from diffdrive.io.read import read_commands


def run_identify(args: argparse.Namespace) -> int:
    refuse_assumed_robot(
        args, "identify gives the drive in the wheels' surface speeds, through their radii"
    )
    robot, ticks = robot_from(args)
    log = read_log_of(args)
    times, velocities = log.wheel_velocities(ticks or log.ticks_per_revolution, args.counter_bits)
    commanded = read_commands(args.input, robot, log, args.command_topic)
    command_times, commands = commanded if commanded is not None else (None, None)
    source = args.command_topic or ""
    voltages = None if log.voltages is None else log.voltages[: len(times)]
    if voltages is None and commands is None:
        raise TableError(
            f"{log.source}: nothing to identify the drive from: voltages (left_voltage, "
            "right_voltage columns) or commands (--command-topic, or left_command, "
            "right_command columns)"
        )
    found = identify_drive(
        robot,
        times,
        velocities,
        voltages=voltages,
        command_times=command_times,
        commands=commands,
        accelerations=tuple(args.accelerations),
    )
    what = f"identified by diffdrive identify from {log.source}" + (
        f" and {source}" if source else ""
    )
    write_drive(args.output, found.sections(), what)
    if not args.quiet:
        if found.drivetrain is not None:
            for name, channel in (
                ("linear", found.drivetrain.linear),
                ("angular", found.drivetrain.angular),
            ):
                gains = channel.feedforward
                print(
                    f"{name}: kS {gains.ks:.4g} V, kV {gains.kv:.4g} V s/m, kA {gains.ka:.4g} "
                    f"V s^2/m, measurement delay {1000 * channel.delay:.0f} ms (one-step RMSE "
                    f"{channel.rmse:.3g} m/s)"
                )
        if found.response is not None:
            response = found.response
            limit = (
                "none"
                if math.isinf(response.acceleration)
                else f"{response.acceleration:.3g} rad/s^2"
            )
            print(
                f"velocity response: delay {1000 * response.delay:.0f} ms, time constant "
                f"{1000 * response.time_constant:.0f} ms, gain {response.gain:.4f}, "
                f"acceleration limit {limit} (RMSE {response.rmse:.3g} rad/s)"
            )
        print(f"identify: wrote the drive to {args.output}")
    return 0


EPILOGS = {
    "identify": """examples:
  diffdrive identify sysid.csv --robot robot.toml -o drive.toml
      a table t, left_velocity, right_velocity (or angles, ticks), left_voltage,
      right_voltage: kS (V), kV (V s/m), kA (V s^2/m) of the linear and angular channels
  diffdrive identify robot.bag --joints wheel_left_joint wheel_right_joint \\
      --command-topic /cmd_vel --robot robot.toml --accelerations inf 20 40 60 -o drive.toml
      a velocity-commanded drive's delay, time constant, gain and acceleration limit

The drive file is TOML: [feedforward] and [angular] (ks, kv, ka, delay) and [response]
(delay, time_constant, gain, acceleration); diffdrive export wpilib --drive FILE puts
kS, kV, kA into WPILib's file.""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive identify``."""
    identify = command(
        "identify",
        "how the drive answers: kS, kV, kA from voltages, the velocity response from commands",
        [parents.robot_required, parents.logs],
        run_identify,
        EPILOGS["identify"],
    )
    identify.add_argument("input", type=Path, help="a log (table) or bag")
    identify.add_argument("-o", "--output", type=Path, default=Path("drive.toml"))
    identify.add_argument(
        "--command-topic",
        metavar="TOPIC",
        help="geometry_msgs/Twist commands of the bag (else: left_command, right_command)",
    )
    identify.add_argument(
        "--accelerations",
        type=float,
        nargs="+",
        default=[math.inf],
        metavar="A",
        help="the wheels' acceleration limits tried, rad/s^2 (inf: none; several are refined "
        "between, with scipy)",
    )
    identify.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
