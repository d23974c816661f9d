"""``diffdrive odometry``: dead reckoning over an encoder log, with a gyro if there is one."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from diffdrive.cli.estimate import estimator_settings
from diffdrive.cli.options import (
    COVARIANCE_COLUMNS,
    LOG_COLUMNS,
    TWIST_COVARIANCE_COLUMNS,
    Command,
    Parents,
    add_imu_options,
    add_method_option,
    add_wheel_noise_option,
    estimate_columns,
    gyro_of,
    noise_changes,
    output_format,
    output_options,
    read_log_of,
    refuse_unused,
    reported_twists,
    robot_from,
    robot_note,
    wheel_commands,
    wheel_noise,
    within_gyro,
    write_output,
)
from diffdrive.cli.report import error_summary
from diffdrive.estimation.odometry import odometry_of_run
from diffdrive.estimation.twists import interval_twists
from diffdrive.io import RIM_SPEED_LIMIT, Run
from diffdrive.model import Robot

# Past this share of intervals flagged, slip is not the explanation: robots slip on a few
# percent of intervals; the TurtleBot3 bag, whose simulated wheels and /odom part ways for a
# stretch, flags 10 to 13 %, and its IMU mounted wrongly 48 %.
SUSPICIOUS_SLIP_SHARE = 0.25


def run_odometry(args: argparse.Namespace) -> int:
    robot, ticks = robot_from(args)
    log = read_log_of(args)
    ticks = ticks or log.ticks_per_revolution
    increments, note = log.checked_increments(robot, ticks, args.counter_bits, args.max_wheel_speed)
    note += robot_note(args)
    gyro = gyro_of(args, log)
    if gyro is None:
        _refuse_gyro_options(args)
    if gyro is not None:
        return _gyro_odometry(args, robot, log, ticks, gyro, note)
    if args.heading not in (None, "wheels"):
        raise ValueError(f"--heading {args.heading} needs a gyro: --gyro-topic, or a gyro_z column")
    noise, assumed = wheel_noise(args, robot, log, increments)
    assert noise is not None  # without a gyro nothing identifies it later: always a figure
    with_covariance = args.covariance or output_format(args) in ("mcap", "ros2")
    poses, covariances = odometry_of_run(
        robot,
        log,
        args.method,
        ticks_per_revolution=ticks,
        counter_bits=args.counter_bits,
        max_wheel_speed=args.max_wheel_speed,
        wheel_noise=noise,
        covariance=with_covariance,
    )
    twists, twist_covariances = interval_twists(robot, log.times, increments, noise)
    twists, reported = reported_twists(log, twists, omega=True)
    note += reported
    columns = estimate_columns(
        covariances, twists, twist_covariances, twist=args.twist, covariance=args.covariance
    )
    what = f"odometry of {log.source}"
    write_output(args, log.times, poses, what, columns, covariances, twists, twist_covariances)
    if not args.quiet:
        print(note + (assumed if with_covariance or args.twist else ""))
        if log.truth is not None:
            print(error_summary(poses, log.truth))
    return 0


def _refuse_gyro_options(args) -> None:
    """The options that act through a gyro, given for a log without one."""
    refuse_unused(
        {
            "--gyro-bias": args.gyro_bias is not None,
            "--slip-test": args.slip_test is not None,
            "--command-topic": args.command_topic is not None,
        },
        "used only with a gyro (--gyro-topic, or a gyro_z column)",
    )


def _gyro_settings(args: argparse.Namespace) -> dict[str, object]:
    """The estimator's settings the gyro flags give, by name (``estimator_settings``)."""
    given: dict[str, object] = {"method": args.method}
    if args.heading is not None:
        given["heading"] = args.heading
    if args.gyro_bias is not None:
        given["bias"] = args.gyro_bias
    if args.slip_test is not None:
        given["whole_log.slip_episodes"] = args.slip_test == "episodes"
    return given


def _gyro_odometry(args, robot: Robot, log: Run, ticks, gyro, note: str) -> int:
    """Odometry with a gyro: the heading from --heading, slip flags and the bias as columns."""
    from diffdrive.estimation.gyro import gyro_odometry

    log, note = within_gyro(log, gyro, note)
    increments = log.increments(ticks, args.counter_bits)
    noise, assumed = wheel_noise(args, robot, log, increments, gyro=True)
    from_files, said = noise_changes(args)
    note += assumed + said
    result = gyro_odometry(
        robot,
        log.times,
        increments,
        gyro,
        estimator_settings(noise, "given", True, {**from_files, **_gyro_settings(args)}),
        initial_pose=log.start_pose(),
        commanded=wheel_commands(args, robot, log),
    )
    twists, reported = reported_twists(log, result.twists, omega=False)
    note += reported
    twist_covariances = result.twist_covariances
    columns = estimate_columns(
        result.covariances,
        twists,
        twist_covariances,
        twist=args.twist,
        covariance=args.covariance,
    )
    columns.update(
        slip=result.slip.astype(float), slip_score=result.slip_score, gyro_bias=result.bias
    )
    what = f"odometry of {log.source} ({result.heading} heading)"
    write_output(
        args, log.times, result.poses, what, columns, result.covariances, twists, twist_covariances
    )
    share = float(np.count_nonzero(result.slip[1:])) / max(1, len(result.slip) - 1)
    if share > SUSPICIOUS_SLIP_SHARE:  # said even with -q: the result is likely wrong
        print(
            f"diffdrive odometry: warning: {100 * share:.0f} % of the intervals flagged as "
            "slip: the gyro and the wheels disagree far more often than a robot slips. A wrong "
            "IMU mounting (--imu-mount), a gyro in other units or the wrong gyro axis is the "
            "likely cause; check with --heading wheels",
            file=sys.stderr,
        )
    if not args.quiet:
        print(note)
        for line in result.settings:
            print(line)
        flagged = f"{int(result.slip.sum())} of {len(result.slip) - 1} intervals flagged"
        print(
            f"slip: {flagged}; gyro bias {result.bias[0]:.5f} rad/s at the start, "
            f"{result.bias[-1]:.5f} at the end"
        )
        if log.truth is not None:
            print(error_summary(result.poses, log.truth))
    return 0


EPILOGS = {
    "odometry": f"""examples:
  diffdrive odometry                      a built-in 20 Hz log of the example -> odometry.csv
  diffdrive odometry log.csv --ticks-per-revolution 4096 --counter-bits 12 -o odometry.csv
  diffdrive odometry log.csv --time-unit ns --max-wheel-speed 30 --twist --covariance
  diffdrive odometry run.mcap --joints left_wheel_joint right_wheel_joint \\
      --gyro-topic /imu/data -o odometry.mcap

{LOG_COLUMNS}
With ground truth an error summary is printed. The largest wheel speed the log implies is
printed with its line: thousands of rad/s mean a wrong --counter-bits or ticks per revolution.""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive odometry``."""
    odo = command(
        "odometry",
        "dead reckoning over an encoder log",
        [parents.robot, parents.logs, output_options("odometry.csv")],
        run_odometry,
        EPILOGS["odometry"],
    )
    odo.add_argument("input", nargs="?", type=Path, help="encoder log; none: built-in")
    odo.add_argument(
        "--max-wheel-speed",
        type=float,
        metavar="RAD_S",
        help="refuse a row whose wheel turns faster (rad/s); default: a rim speed of "
        f"{RIM_SPEED_LIMIT:g} m/s",
    )
    add_wheel_noise_option(odo, "default 1e-4, or identified from ground truth; said when used")
    add_method_option(odo)
    gyro = odo.add_argument_group("a gyro: a bag's IMU topic or a gyro_z column (rad/s)")
    add_imu_options(gyro)
    gyro.add_argument(
        "--heading",
        choices=("wheels", "gyro", "fused"),
        help="heading from the wheels, the gyro, or both (default: fused with a "
        "gyro); writes slip, slip_score and gyro_bias columns",
    )
    gyro.add_argument(
        "--gyro-bias",
        type=float,
        metavar="RAD_S",
        help="the gyro's bias (default: its mean while the wheels stand still)",
    )
    gyro.add_argument(
        "--slip-test",
        choices=("episodes", "interval"),
        help="flag each interval whose wheel and gyro turns disagree (interval), and also "
        "the runs of intervals one slipping wheel explains (episodes, the default)",
    )
    gyro.add_argument(
        "--command-topic",
        metavar="TOPIC",
        help="geometry_msgs/Twist commands of the bag, to flag wheels that spin "
        "beyond them (or left_command, right_command columns)",
    )
    odo.add_argument(
        "--twist",
        action="store_true",
        help="add columns vx, vy, omega (m/s, m/s, rad/s): the body twist over the interval "
        "ending at each row (the first row: the first interval's); with --covariance also "
        f"{', '.join(TWIST_COVARIANCE_COLUMNS)}",
    )
    odo.add_argument(
        "--covariance",
        action="store_true",
        help=f"add columns {', '.join(COVARIANCE_COLUMNS)} (m^2, m rad, rad^2)",
    )
