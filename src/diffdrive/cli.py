"""The ``diffdrive`` command line. With no arguments it runs the main job on a built-in example."""

from __future__ import annotations

import argparse
import json
import math
import re
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np

from diffdrive import batch, se2, sources
from diffdrive.calibration import EXTRAS, PARAMETERS, calibrate, odometry_of
from diffdrive.calibration import METHODS as CALIBRATION_METHODS
from diffdrive.encoders import MAX_COUNTER_BITS, MIN_COUNTER_BITS, count_changes
from diffdrive.evaluation import RPE_PAIRS, associate, ate, interpolate, rpe, run_errors, worst
from diffdrive.examples import (
    EXAMPLE_DURATION,
    example_log,
    example_robot,
    example_wheel_velocities,
)
from diffdrive.files import (
    ROBOT_KEYS,
    TIME_UNITS,
    TableError,
    atomic_output,
    read_robot,
    write_robot,
)
from diffdrive.integrate import METHODS, Method
from diffdrive.logs import WheelLog, narrower_counter
from diffdrive.model import DiffDrive
from diffdrive.odometry import Odometry, RefusedUpdateError, UpdateKind
from diffdrive.simulation import integrate_increments, simulate
from diffdrive.skid_steer import Robot, SkidSteer
from diffdrive.trajectories import FORMATS, write_trajectory
from diffdrive.types import Pose, Twist, WheelVelocities

# (label, left, right) wheel velocities in rad/s that show the characteristic motions.
_EXAMPLE_WHEELS = (
    ("straight", 10.0, 10.0),
    ("gentle left", 8.0, 10.0),
    ("spin in place", -5.0, 5.0),
    ("pivot on right wheel", 6.0, 0.0),
)


def _matrix(m: np.ndarray) -> str:
    return "\n".join("    [" + "  ".join(f"{v:+10.5f}" for v in row) + " ]" for row in m)


def kinematics_report(robot: DiffDrive) -> str:
    """A text report of ``robot``'s kinematics: matrices and a few characteristic motions."""
    lines = [
        f"robot: {robot}",
        "",
        "seed 003: [vx, omega] = K @ [wl, wr]",
        _matrix(robot.to_twist_matrix()),
        "Modern Robotics: [wl, wr] = H @ (omega, vx, vy)",
        _matrix(robot.h_matrix()),
        "and back: (omega, vx, vy) = F @ [wl, wr]",
        _matrix(robot.f_matrix()),
        "",
        f"{'motion':22} {'wl':>7} {'wr':>7} {'vx m/s':>8} {'omega':>8} {'radius m':>9}"
        f"   pose after 1 s (x, y, theta deg)",
    ]
    for label, left, right in _EXAMPLE_WHEELS:
        wheels = WheelVelocities(left, right)
        twist = robot.to_twist(wheels)
        pose = se2.exp(twist, 1.0)
        lines.append(
            f"{label:22} {left:7.2f} {right:7.2f} {twist.vx:8.4f} {twist.omega:8.4f} "
            f"{robot.turning_radius(wheels):9.4f}   "
            f"({pose.x:+.4f}, {pose.y:+.4f}, {math.degrees(pose.theta):+.2f})"
        )
    return "\n".join(lines)


def simulation_report(robot: DiffDrive, steps: int = 2000) -> str:
    """Simulate the built-in driving history with each method; compare the final poses."""
    lines = [
        f"simulated {EXAMPLE_DURATION:g} s of the built-in driving history in {steps} steps:",
        f"{'method':8} {'x m':>9} {'y m':>9} {'theta deg':>10} {'distance m':>11}",
    ]
    for method in METHODS:
        trajectory = simulate(
            robot,
            example_wheel_velocities,
            dt=EXAMPLE_DURATION / steps,
            duration=EXAMPLE_DURATION,
            method=method,
        )
        x, y, theta = trajectory.final_pose
        lines.append(
            f"{method:8} {x:9.4f} {y:9.4f} {math.degrees(theta):10.2f} "
            f"{trajectory.distance[-1]:11.4f}"
        )
    return "\n".join(lines)


ROBOT_DEFAULTS = "the built-in example robot: 42 mm wheels, track 0.2 m"

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

EPILOGS = {
    "simulate": f"""examples:
  diffdrive simulate                       the built-in driving history -> trajectory.csv
  diffdrive simulate drive.csv -o out.tum --method rk2 --robot robot.toml

{LOG_COLUMNS}""",
    "odometry": f"""examples:
  diffdrive odometry                      a built-in 20 Hz log of the example -> odometry.csv
  diffdrive odometry log.csv --ticks-per-revolution 4096 --counter-bits 12 -o odometry.csv
  diffdrive odometry log.csv --time-unit ns --max-wheel-speed 30 --twist --covariance

{LOG_COLUMNS}
With ground truth an error summary is printed. The largest wheel speed the log implies is
printed with its line: thousands of rad/s mean a wrong --counter-bits or ticks per revolution.""",
    "plot": f"""examples:
  diffdrive plot                          the built-in example -> trajectory.png
  diffdrive plot odometry.csv --truth log.csv -o odometry.svg

{TRAJECTORY_FILES} --truth is drawn underneath.""",
    "animate": """examples:
  diffdrive animate                       the built-in example -> trajectory.gif
  diffdrive animate trajectory.csv -o drive.mp4     (MP4 needs ffmpeg; else a GIF)""",
    "calibrate": f"""examples:
  diffdrive calibrate                      the built-in example runs -> robot.toml
  diffdrive calibrate runs/*_run-*.csv --method least_squares -o robot.toml

runs with ground truth, each as below (x, y, theta needed; OptiOdom files count 2796.8 a
turn unless told).
{LOG_COLUMNS}""",
    "evaluate": f"""examples:
  diffdrive evaluate                       the built-in example's odometry against its truth
  diffdrive evaluate odometry.tum --truth truth.csv --rpe 1.0 --json
  diffdrive evaluate est.tum --truth gt.tum --t-offset -0.003 --rpe 10 --rpe-unit poses

{TRAJECTORY_FILES} Poses are paired by time as evo pairs them: the nearest
stamp within --t-max-diff s, after adding --t-offset to the trajectory's times;
--interpolate instead samples the trajectory at every ground-truth time along its arcs.""",
    "info": """example:
  diffdrive info robot.bag      topics, types, counts, rates, and which diffdrive can use""",
    "learn": """examples:
  diffdrive learn                 serve the page on this machine and open it in the browser
  diffdrive learn --no-browser --port 2718     serve only; open http://127.0.0.1:2718
  diffdrive learn --export page.html           a static snapshot for a course website
needs the extra: pip install 'diffdrive[learn]'""",
    "fk": """example:
  diffdrive fk 8 10 --json      wheel velocities (rad/s) -> body twist
  diffdrive fk 1 -1e-3          (negative numbers are numbers, not options)""",
    "ik": """example:
  diffdrive ik 0.5 1.0          forward speed (m/s) and turn rate (rad/s) -> wheel velocities""",
}

# Past this speed at the rim (m/s) a wheel-speed jump is no motion of a wheeled robot but a
# misread log, unless the user sets the limit (--max-wheel-speed).
_RIM_SPEED_LIMIT = 50.0


def _robot_options() -> argparse.ArgumentParser:
    options = argparse.ArgumentParser(add_help=False)
    group = options.add_argument_group(f"robot (default: {ROBOT_DEFAULTS})")
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


def _log_options() -> argparse.ArgumentParser:
    options = argparse.ArgumentParser(add_help=False)
    group = options.add_argument_group("log")
    group.add_argument(
        "--time-unit", choices=TIME_UNITS,
        help="unit of the t column (default s; plainly other units are refused)",
    )  # fmt: skip
    group.add_argument(
        "--counter-bits", type=_between(MIN_COUNTER_BITS, MAX_COUNTER_BITS), metavar="B",
        help=f"width of the encoder counters ({MIN_COUNTER_BITS}-{MAX_COUNTER_BITS}), for "
        "roll-over; default: counters that never roll over",
    )  # fmt: skip
    bags = options.add_argument_group("a ROS bag or MCAP file as the log (diffdrive[ros])")
    bags.add_argument(
        "--joint-topic",
        default="/joint_states",
        metavar="TOPIC",
        help="sensor_msgs/JointState topic (default /joint_states)",
    )
    bags.add_argument("--left-joint", metavar="NAME", help="the left wheel's joint name")
    bags.add_argument("--right-joint", metavar="NAME", help="the right wheel's joint name")
    bags.add_argument(
        "--reference-topic",
        metavar="TOPIC",
        help="nav_msgs/Odometry (or tf:PARENT:CHILD) as the ground truth",
    )
    return options


def _output_options(default: str) -> argparse.ArgumentParser:
    options = argparse.ArgumentParser(add_help=False)
    options.add_argument("-o", "--output", type=Path, default=Path(default), help="file to write")
    options.add_argument("--format", choices=OUTPUT_FORMATS,
                         help="default: from the file's suffix; mcap (a file) and ros2 (a bag "
                         "folder) write nav_msgs/Odometry and /tf")  # fmt: skip
    options.add_argument("--frame", default="odom", help="bag output: the parent frame (odom)")
    options.add_argument("--child-frame", default="base_link",
                         help="bag output: the robot's frame (base_link)")  # fmt: skip
    options.add_argument("--method", choices=METHODS, default="exact", help="default: exact")
    options.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    return options


def _robot(args: argparse.Namespace) -> tuple[DiffDrive | SkidSteer, float | None]:
    """The robot of the command's options, and its ticks per revolution if known."""
    settings: dict[str, Any] = dict(read_robot(args.robot)) if args.robot else {}
    for name in ROBOT_KEYS:
        value = getattr(args, name)
        if value is not None:
            settings[name] = value
            if name in ("track_width", "half_track"):  # a flag overrides the file's either
                settings.pop("half_track" if name == "track_width" else "track_width", None)
    ticks = settings.pop("ticks_per_revolution", None)
    if ticks is not None and not (math.isfinite(ticks) and ticks > 0):
        raise ValueError(f"ticks_per_revolution must be finite and > 0, got {ticks!r}")
    if not settings:
        return example_robot(), ticks
    where = f" (in {args.robot})" if args.robot else ""
    try:
        if any(key.startswith("icr_") for key in settings):  # a skid-steer robot
            if {"track_width", "half_track", "axle_offset"} & settings.keys():
                raise ValueError("a skid-steer robot has icr_left, icr_right and icr_x instead "
                                 "of track_width, half_track and axle_offset")  # fmt: skip
            return SkidSteer(**settings), ticks
        return DiffDrive(**settings), ticks
    except ValueError as exc:
        raise ValueError(f"robot{where}: {exc}") from None


OutputFormat = Literal["csv", "jsonl", "tum", "mcap", "ros2"]
OUTPUT_FORMATS: tuple[OutputFormat, ...] = (*FORMATS, "mcap", "ros2")


def _format(args: argparse.Namespace) -> OutputFormat:
    """``--format``, else the output's suffix if it names a format, else csv."""
    wanted = args.format or args.output.suffix.lstrip(".").lower()
    return next((known for known in OUTPUT_FORMATS if known == wanted), "csv")


def _write(args, times, poses, what: str, columns=None, covariances=None, twists=None) -> None:
    """Write the trajectory in the chosen format: a file of poses and ``columns``, or
    ``nav_msgs/Odometry`` and ``/tf`` with ``covariances`` and ``twists`` to a bag."""
    format = _format(args)
    if format == "mcap" or format == "ros2":
        from diffdrive.ros import write_odometry

        written = [write_odometry(args.output, times, poses, covariances, twists,
                                  format=format, frame=args.frame,
                                  child_frame=args.child_frame)]  # fmt: skip
    else:
        written = write_trajectory(args.output, times, poses, format, columns)
    if not args.quiet:
        where = ", ".join(map(str, written))
        print(f"{what}: wrote {poses.shape[-2]} poses to {where} ({format})")


def _read_log(args: argparse.Namespace, path: Path | None = None) -> WheelLog:
    """The log of ``path`` (default: the command's input), a file or a bag topic."""
    path = args.input if path is None else path
    if path is None:
        return example_log()
    return sources.wheel_log(
        path, args.time_unit, joint_topic=args.joint_topic, left_joint=args.left_joint,
        right_joint=args.right_joint, reference_topic=args.reference_topic,
    )  # fmt: skip


def _start(log: WheelLog) -> np.ndarray:
    """Where a log's run starts: its first ground-truth pose, else the origin."""
    return np.zeros(3) if log.truth is None else log.truth[0]


def _checked_increments(args, log: WheelLog, robot: Robot, ticks) -> tuple[np.ndarray, str]:
    """The log's wheel increments ``(T, 2)`` rad, and a line on its largest wheel speed;
    refuses a counter width that does not fit, and a speed no robot drives at (without
    --max-wheel-speed, a rim speed of _RIM_SPEED_LIMIT m/s)."""
    increments = log.increments(ticks, args.counter_bits)
    speed, side, row = log.largest_wheel_speed(increments)
    radius = robot.left_wheel_radius if side == "left" else robot.right_wheel_radius
    line = (
        f"largest wheel speed in the log: {speed:.4g} rad/s ({speed * radius:.3g} m/s at the "
        f"rim), {side} wheel, {log.where(row)}"
    )
    limit = getattr(args, "max_wheel_speed", None)
    narrower = narrower_counter(log, args.counter_bits) if limit is None else None
    if narrower is not None:
        bits, row = narrower
        change = int(np.abs(count_changes(log.wheels[row - 1 : row + 1], args.counter_bits)).max())
        read_as = f"{args.counter_bits}-bit" if args.counter_bits else "never rolling over"
        raise TableError(
            f"{log.where(row)}: the counters jump by {change} counts, yet every reading fits "
            f"{bits} bits: a {bits}-bit counter rolling over, read as {read_as}? Give "
            f"--counter-bits {bits}; or --max-wheel-speed to take the jump as read"
        )
    if limit is None and speed * radius > _RIM_SPEED_LIMIT:
        hint = " a wrong --counter-bits or --ticks-per-revolution?" if log.kind == "ticks" else ""
        raise TableError(
            f"{log.where(row)}: the {side} wheel would turn at {speed:.4g} rad/s "
            f"({speed * radius:.3g} m/s at its rim), faster than any wheeled robot drives;"
            f"{hint} Give --max-wheel-speed to set the limit yourself"
        )
    return increments, line


def run_simulate(args: argparse.Namespace) -> int:
    robot, ticks = _robot(args)
    if args.input is None:
        _check_step_count(args.dt)
        trajectory = _example_trajectory(robot, args.dt, args.method)
        _write(args, trajectory.times, trajectory.poses,
               f"simulated the built-in {EXAMPLE_DURATION:g} s driving history")  # fmt: skip
        return 0
    log = _read_log(args)
    increments, note = _checked_increments(args, log, robot, ticks)
    if log.kind == "velocity":
        trajectory = simulate(
            robot, log.wheels[:-1], times=log.times, initial_pose=_start(log), method=args.method
        )
        poses = trajectory.poses
    else:
        twists = batch.to_twist(robot, increments)
        poses = integrate_increments(twists, _start(log), args.method)
    _write(args, log.times, poses, f"simulated {args.input}")
    if not args.quiet:
        print(note)
    return 0


def _check_step_count(dt: float) -> None:
    """Refuse a step for the built-in history that is not a number of steps memory can hold."""
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"--dt must be finite and > 0, got {dt}")
    steps = EXAMPLE_DURATION / dt
    if steps > 1e8:
        raise ValueError(
            f"--dt {dt:g} s makes {steps:.3g} steps of the {EXAMPLE_DURATION:g} s history, "
            f"{steps * 56 / 2**30:.3g} GiB of poses and wheel velocities; use a step of "
            f"{EXAMPLE_DURATION / 1e8:g} s or more"
        )


def run_odometry(args: argparse.Namespace) -> int:
    robot, ticks = _robot(args)
    log = _read_log(args)
    ticks = ticks or log.ticks_per_revolution
    increments, note = _checked_increments(args, log, robot, ticks)
    gyro = _gyro(args, log)
    if gyro is not None:
        if isinstance(robot, SkidSteer):
            raise ValueError("the gyro heading takes a differential drive (track_width), not a "
                             "skid-steer robot file (icr_left, icr_right)")  # fmt: skip
        return _gyro_odometry(args, robot, log, ticks, gyro, note)
    if args.heading not in (None, "wheels"):
        raise ValueError(f"--heading {args.heading} needs a gyro: --gyro-topic, or a gyro_z column")
    odometry = Odometry(
        robot, args.method, Pose(*_start(log)), ticks if log.kind == "ticks" else None,
        args.counter_bits, max_wheel_speed=args.max_wheel_speed, k_left=args.k_left or 0.0,
        k_right=args.k_right or 0.0,
    )  # fmt: skip
    times, wheels = log.times, log.wheels
    to_bag = _format(args) in ("mcap", "ros2")
    kinds: dict[str, UpdateKind] = {"ticks": "ticks", "angle": "positions",
                                    "velocity": "velocities"}  # fmt: skip
    kind = kinds[log.kind]
    first = 1 if kind == "velocities" else 0  # a velocity is held until the next row
    third = np.diff(times) if kind == "velocities" else times
    left, right = (wheels[:-1, 0], wheels[:-1, 1]) if first else (wheels[:, 0], wheels[:, 1])
    try:
        poses, covariances = odometry.update_arrays(kind, left, right, third,
                                                    args.covariance or to_bag)  # fmt: skip
    except RefusedUpdateError as refused:
        raise TableError(f"{log.where(refused.row + first)}: {refused.reason}") from None
    if first:
        start = _start(log)[None, :]
        poses = np.vstack([start, poses])
        if covariances is not None:
            covariances = np.vstack([np.zeros((1, 3, 3)), covariances])
    columns: dict[str, np.ndarray] = {}
    twists = batch.to_twist(robot, increments)
    twists = np.vstack([np.full(3, np.nan), twists / np.diff(times)[:, None]])
    if args.twist:
        columns.update(vx=twists[:, 0], vy=twists[:, 1], omega=twists[:, 2])
    if args.covariance and covariances is not None:
        flat = covariances.reshape(-1, 9)
        for name, index in COVARIANCE_COLUMNS.items():
            columns[name] = flat[:, index]
    _write(args, times, poses, f"odometry of {log.source}", columns, covariances, twists)
    if not args.quiet:
        print(note)
        if log.truth is not None:
            print(error_summary(poses, log.truth))
    return 0


def _gyro(args, log: WheelLog):
    """The gyro of the command: a bag's IMU topic (rotated by --imu-rpy), or the log's gyro_z
    column; None without one."""
    from diffdrive.gyro import Gyro, rotation_from_rpy

    if args.gyro_topic is not None:
        if args.input is None or not sources.is_bag(args.input):
            raise TableError("--gyro-topic needs a bag as the log")
        from diffdrive import ros

        imu = ros.read_imu(args.input, args.gyro_topic)
        mounting = rotation_from_rpy(*np.radians(args.imu_rpy))
        return Gyro.from_imu(imu.times, imu.angular_velocity, mounting)
    if log.gyro_rates is not None:
        return Gyro(log.times, log.gyro_rates)
    return None


def _gyro_odometry(args, robot: DiffDrive, log: WheelLog, ticks, gyro, note: str) -> int:
    """Odometry with a gyro: the heading from --heading, slip flags and the bias as columns."""
    from diffdrive.gyro import gyro_odometry

    inside = (log.times >= gyro.times[0]) & (log.times <= gyro.times[-1])
    if np.count_nonzero(inside) < 2:
        raise TableError(f"{log.source}: the gyro does not cover the log's times")
    if not inside.all():  # a bag's IMU may start a little after the wheels: keep the overlap
        log = _cut(log, inside)
        note += f"\nthe log is cut to [{log.times[0]:g}, {log.times[-1]:g}] s, where the gyro is"
    options = {"k_left": 1e-4 if args.k_left is None else args.k_left,
               "k_right": 1e-4 if args.k_right is None else args.k_right}  # fmt: skip
    result = gyro_odometry(robot, log.times, log.increments(ticks, args.counter_bits), gyro,
                           args.heading or "fused", _start(log), bias=args.gyro_bias,
                           commanded=_commands(args, robot, log), **options)  # fmt: skip
    columns = {"slip": result.slip.astype(float), "slip_score": result.slip_score,
               "gyro_bias": result.bias}  # fmt: skip
    if args.covariance:
        flat = result.covariances.reshape(-1, 9)
        columns.update({name: flat[:, index] for name, index in COVARIANCE_COLUMNS.items()})
    _write(args, log.times, result.poses, f"odometry of {log.source} ({result.heading} heading)",
           columns, result.covariances)  # fmt: skip
    if not args.quiet:
        print(note)
        flagged = f"{int(result.slip.sum())} of {len(result.slip) - 1} intervals flagged"
        print(f"slip: {flagged}; gyro bias {result.bias[0]:.5f} rad/s at the start, "
              f"{result.bias[-1]:.5f} at the end")  # fmt: skip
        if log.truth is not None:
            print(error_summary(result.poses, log.truth))
    return 0


def _commands(args, robot, log: WheelLog):
    """The wheel velocities commanded over each interval ``(T, 2)``: a bag's Twist topic
    (each held until the next) through inverse kinematics, the log's command columns, or
    None."""
    if args.command_topic is not None:
        from diffdrive import ros

        commands = ros.read_twists(args.input, args.command_topic)
        held = np.searchsorted(commands.times, log.times[:-1], side="right") - 1
        v, omega = commands.twists[np.maximum(held, 0)].T
        wheels = batch.to_wheel_velocities(robot, np.column_stack([v, 0.0 * v, omega]))
        return np.where((held >= 0)[:, None], wheels, 0.0)  # before the first: standing
    return None if log.commands is None else log.commands[:-1]


def _cut(log: WheelLog, keep: np.ndarray) -> WheelLog:
    """The rows ``keep`` (a contiguous run) of a log."""
    from dataclasses import replace

    def part(values):
        return None if values is None else values[keep]

    return replace(log, times=log.times[keep], wheels=log.wheels[keep], truth=part(log.truth),
                   lines=part(log.lines), gyro_rates=part(log.gyro_rates),
                   commands=part(log.commands))  # fmt: skip


# The covariance's distinct entries, by their index in the row-major 3x3 matrix.
COVARIANCE_COLUMNS = {
    "cov_xx": 0, "cov_xy": 1, "cov_xtheta": 2, "cov_yy": 4, "cov_ytheta": 5, "cov_thetatheta": 8,
}  # fmt: skip


def error_summary(poses: np.ndarray, truth: np.ndarray) -> str:
    """Maximum and final position (m) and heading (deg) errors of ``poses`` against ``truth``."""
    errors = run_errors(poses, truth)
    return (
        f"against the ground truth: position error max {errors.max_position:.4f} m, "
        f"final {errors.final_position:.4f} m; heading error max {errors.max_heading:.3f} deg, "
        f"final {errors.final_heading:.3f} deg"
    )


def _example_trajectory(robot: Robot, dt: float = 0.01, method: Method = "exact"):
    """The built-in driving history, simulated."""
    return simulate(
        robot, example_wheel_velocities, dt=dt, duration=EXAMPLE_DURATION, method=method
    )


def _trajectory_or_example(args: argparse.Namespace, robot: Robot):
    """``(times, poses, what)`` from the input trajectory (file or bag topic), or the
    built-in example."""
    if args.input is None:
        example = _example_trajectory(robot)
        return example.times, example.poses, "the built-in example"
    what = f"{args.input} {args.topic}" if args.topic else str(args.input)
    return (*sources.trajectory(args.input, args.time_unit, args.topic), what)


def run_plot(args: argparse.Namespace) -> int:
    from diffdrive.plot import plot_trajectory

    robot, _ = _robot(args)
    times, poses, what = _trajectory_or_example(args, robot)
    truth = None
    if args.truth is not None:
        truth = sources.trajectory(args.truth, args.time_unit, args.truth_topic)
    with atomic_output(args.output) as temporary:
        plot_trajectory(robot, times, poses, temporary, truth)
    if not args.quiet:
        print(f"plotted {what} to {args.output}")
    return 0


def run_animate(args: argparse.Namespace) -> int:
    from diffdrive.plot import animate, animation_writer

    robot, _ = _robot(args)
    times, poses, what = _trajectory_or_example(args, robot)
    if poses.ndim != 2:
        raise TableError(f"{args.input}: animate draws one robot; the file has {len(poses)}")
    writer, output = animation_writer(args.output)
    with atomic_output(output) as temporary:
        animate(robot, times, poses, temporary, writer, frames=args.frames, fps=args.fps,
                progress=not args.quiet and sys.stderr.isatty())  # fmt: skip
    if not args.quiet:
        print(f"animated {what} to {output} ({writer})")
    return 0


def _mirrored_example(t: np.ndarray) -> np.ndarray:
    """The built-in history with the wheels swapped: the same path, turning the other way."""
    return example_wheel_velocities(t)[:, ::-1]


def _example_runs() -> list[tuple[np.ndarray, np.ndarray]]:
    """Runs of the built-in history by a robot a little off the nominal one, with its truth:
    ``(increments (T, 2) rad, truth (T+1, 3))``."""
    true_robot = DiffDrive(
        left_wheel_radius=0.04166, right_wheel_radius=0.04163, track_width=0.2019
    )
    runs = []
    for history in (example_wheel_velocities, _mirrored_example):
        run = simulate(true_robot, history, dt=0.05, duration=EXAMPLE_DURATION)
        runs.append((np.diff(run.wheel_positions, axis=0), run.poses))
    return runs


def _calibration_run(args, path: Path, ticks: float | None):
    """``(increments, truth)`` of a run, and the ticks per revolution its format fixes."""
    log = _read_log(args, path)
    if log.truth is None:
        raise TableError(
            f"{path}: a run to calibrate on needs ground truth: columns x, y, theta, or a bag's "
            "--reference-topic"
        )
    return (log.increments(ticks, args.counter_bits), log.truth), log.ticks_per_revolution


def run_calibrate(args: argparse.Namespace) -> int:
    nominal, ticks = _robot(args)
    if args.runs:
        read = [_calibration_run(args, path, ticks) for path in args.runs]
        runs = [run for run, _ in read]
        ticks = ticks or next((own for _, own in read if own is not None), None)
        what = f"{len(runs)} runs"
    else:
        runs, what = _example_runs(), "the built-in example runs"
    names = [str(path) for path in args.runs] or ["example", "mirrored example"]
    fixed = tuple(args.fix or ())
    if args.extra is None:  # the default: what predicted best on held-out OptiOdom runs
        extra = EXTRAS if args.method in ("least_squares", "minimax") else ()
    else:
        extra = tuple(name for name in args.extra if name != "none")
    result = calibrate(nominal, runs, args.method, integration=args.integration,
                       square_side=args.square_side, names=names, fixed=fixed, extra=extra,
                       progress=not args.quiet and sys.stderr.isatty())  # fmt: skip
    robot = result.robot
    settings = {"left_wheel_radius": robot.left_wheel_radius,
                "right_wheel_radius": robot.right_wheel_radius}  # fmt: skip
    if isinstance(robot, SkidSteer):
        settings.update(icr_left=robot.icr_left, icr_right=robot.icr_right, icr_x=robot.icr_x)
    else:
        settings.update(track_width=robot.track_width, axle_offset=robot.axle_offset)
    if ticks is not None:
        settings["ticks_per_revolution"] = ticks
    write_robot(args.output, settings, f"calibrated by diffdrive ({args.method}) on {what}")
    if not args.quiet:
        print(calibration_report(nominal, result, runs, args.integration))
        if args.cv != "none" and args.method != "umbmark":
            print(held_out_report(nominal, runs, names, args, fixed, extra))
        print(f"calibrate: wrote the robot to {args.output}")
    return 0


def held_out_report(nominal, runs, names, args, fixed, extra=()) -> str:
    """The in-sample and held-out errors side by side, and the parameters' spread."""
    from diffdrive.validation import cross_validate

    if len(runs) < 2:
        return "held-out errors: none (one run: nothing to hold out; --cv none hides this)"
    scheme = "loo" if args.cv == "loo" else int(args.cv)
    cv = cross_validate(nominal, runs, args.method, scheme, integration=args.integration,
                        names=names, fixed=fixed, extra=extra)  # fmt: skip
    label = "leave one run out" if scheme == "loo" else f"{scheme} folds"
    lines = [f"{'errors over the runs':28} {'in-sample':>10} {'held-out':>10}   ({label})"]
    for name, unit in (("max_position", "m"), ("final_position", "m"),
                       ("max_heading", "deg"), ("final_heading", "deg")):  # fmt: skip
        held = "n/a" if cv.held_out is None else f"{getattr(cv.held_out, name):10.4f}"
        lines.append(f"{name + ', ' + unit:28} {getattr(cv.in_sample, name):10.4f} {held:>10}")
    if len(cv.fitted) > 1:
        spread = ", ".join(f"{p} +-{s:.2g}" for p, s in zip(PARAMETERS, cv.spread, strict=True))
        lines.append(f"parameters across the folds: {spread}")
    lines.extend(f"fold holding out {', '.join(names[k] for k in fold.held_out)} refused: "
                 f"{fold.refusal}" for fold in cv.refused)  # fmt: skip
    return "\n".join(lines)


def calibration_report(nominal: Robot, result, runs, integration: Method) -> str:
    """Parameters with their standard errors, and the largest errors before and after."""
    sigma = result.standard_errors
    lines = [f"{'parameter':20} {'nominal':>10} {'calibrated':>11} {'+-':>10}"]
    for k, name in enumerate(("left_wheel_radius", "right_wheel_radius", "track_width")):
        spread = "n/a" if sigma is None else f"{sigma[k]:.2g}"
        lines.append(
            f"{name:20} {getattr(nominal, name):10.6f} {getattr(result.robot, name):11.6f} "
            f"{spread:>10}"
        )
    shift = np.array([0.0, 0.0, result.heading_offset])
    before = worst([run_errors(odometry_of(nominal, i, t[0], integration), t) for i, t in runs])
    after = worst([run_errors(odometry_of(result.robot, i, t[0] + shift, integration), t)
                   for i, t in runs])  # fmt: skip
    offsets = [getattr(robot, "axle_offset", 0.0) for robot in (nominal, result.robot)]
    if offsets[0] != offsets[1]:  # fitted (a SkidSteer has icr_x instead)
        lines.append(f"{'axle_offset':20} {offsets[0]:10.6f} {offsets[1]:11.6f}")
    if result.heading_offset:
        lines.append(
            f"heading offset of the reference: {np.degrees(result.heading_offset):.3f} deg"
        )
    if result.condition is not None:
        lines.append(f"condition number of the fit: {result.condition:.3g}")
    if sigma is None:
        lines.append(f"+-: {result.uncertainty_note}")
    lines.append(
        f"largest position error over the runs: {before.max_position:.4f} m nominal, "
        f"{after.max_position:.4f} m calibrated ({integration} odometry)"
    )
    return "\n".join(lines)


def run_evaluate(args: argparse.Namespace) -> int:
    if args.input is None:
        log, robot = example_log(), example_robot()
        times, truth = log.times, log.truth
        estimate = odometry_of(robot, log.increments(), truth[0], "exact")
    else:
        if args.truth is None:
            raise TableError("evaluate needs --truth with a ground-truth trajectory or bag")
        times, estimate = sources.trajectory(args.input, args.time_unit, args.topic)
        truth_times, truth = sources.trajectory(args.truth, args.time_unit, args.truth_topic)
        for path, poses in ((args.input, estimate), (args.truth, truth)):
            if poses.ndim != 2:
                raise TableError(f"{path}: evaluate takes one robot; the file has {len(poses)}")
        times, estimate, truth = _paired(args, times, estimate, truth_times, truth)
    metrics = evaluation_metrics(args, times, estimate, truth)
    if args.json:
        print(json.dumps(metrics))
    else:
        for key, value in metrics.items():
            shown = "n/a" if value is None else (f"{value:.6f}" if isinstance(value, float)
                                                 else str(value))  # fmt: skip
            print(f"{key:34} {shown:>12}")
    return 0


def evaluation_metrics(args, times, estimate, truth) -> dict:
    """The paper's measures, ATE and RPE; a truth without headings (GPS) gives the position
    measures only (the others are None)."""
    positions_only = bool(np.isnan(truth[:, 2]).any())
    if positions_only:  # compare positions: the headings take no part
        estimate, truth = estimate.copy(), truth.copy()
        estimate[:, 2] = truth[:, 2] = 0.0
    errors = run_errors(estimate, truth)
    metrics = {
        "poses_compared": len(times),
        "max_position_error_m": errors.max_position,
        "final_position_error_m": errors.final_position,
        "max_heading_error_deg": None if positions_only else errors.max_heading,
        "final_heading_error_deg": None if positions_only else errors.final_heading,
        "ate_m": ate(estimate, truth),
        "ate_aligned_m": ate(estimate, truth, aligned=True),
    }
    name = f"rpe_{args.rpe:g}{args.rpe_unit}_{args.rpe_pairs}"
    metrics[f"{name}_m"] = metrics[f"{name}_deg"] = None
    if not positions_only:
        metrics[f"{name}_m"], metrics[f"{name}_deg"] = rpe(
            estimate, truth, args.rpe, unit=args.rpe_unit, times=times, pairs=args.rpe_pairs
        )
    return metrics


def _paired(args, times, estimate, truth_times, truth):
    """The estimate and the truth at paired times: associated as evo does, or the estimate
    interpolated along its arcs at the truth's times (--interpolate)."""
    if args.interpolate:
        shifted = times + args.t_offset
        inside = (truth_times >= shifted[0]) & (truth_times <= shifted[-1])
        if not inside.any():
            raise TableError(f"{args.truth}: no ground-truth time lies within {args.input}'s")
        at = truth_times[inside]
        return at, interpolate(shifted, estimate, at), truth[inside]
    i, j = associate(times, truth_times, args.t_max_diff, args.t_offset)
    if len(i) < 2:
        raise TableError(
            f"{args.truth}: {len(i)} of its times are within --t-max-diff {args.t_max_diff} s of "
            f"{args.input}'s (after --t-offset {args.t_offset} s); 2 or more are needed"
        )
    return truth_times[j], estimate[i], truth[j]


def run_info(args: argparse.Namespace) -> int:
    from diffdrive import ros

    found = ros.topics(args.input)
    print(f"{args.input}: {len(found)} topics")
    print(f"{'topic':32} {'type':32} {'messages':>8} {'Hz':>7}  use")
    for topic in found:
        print(f"{topic.name:32} {topic.msgtype:32} {topic.count:8} {topic.rate:7.2f}  {topic.use}")
    return 0


def run_learn(args: argparse.Namespace) -> int:
    from diffdrive import learn

    reason = learn.missing_extra()
    if reason is not None:
        print(f"diffdrive learn: error: {reason}", file=sys.stderr)
        return 1
    if args.export is not None:
        learn.export(args.export)
        print(f"wrote {args.export}: a static snapshot (it loads marimo's scripts from a CDN)")
        return 0
    return learn.serve(args.port, browser=not args.no_browser)


def run_fk(args: argparse.Namespace) -> int:
    robot, _ = _robot(args)
    wheels = WheelVelocities(args.left, args.right)
    twist = robot.to_twist(wheels)
    values = {
        "vx": twist.vx, "vy": twist.vy, "omega": twist.omega,
        "turning_radius": robot.turning_radius(wheels),
    }  # fmt: skip
    units = {"vx": "m/s", "vy": "m/s", "omega": "rad/s", "turning_radius": "m"}
    _print_values(values, args.json, units)
    return 0


def run_ik(args: argparse.Namespace) -> int:
    robot, _ = _robot(args)
    wheels = robot.to_wheel_velocities(Twist(args.vx, 0.0, args.omega))
    values = {"left": wheels.left, "right": wheels.right}
    _print_values(values, args.json, {"left": "rad/s", "right": "rad/s"})
    return 0


def _print_values(values: dict[str, float], as_json: bool, units: dict[str, str]) -> None:
    if as_json:
        print(json.dumps({k: (v if math.isfinite(v) else str(v)) for k, v in values.items()}))
        return
    for name, value in values.items():
        print(f"{name:15} {value:12.6g} {units[name]}")


# argparse's own pattern misses the exponent form (-1e-3), which it then takes for an option.
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def _between(smallest: int, largest: int):
    """An argparse type: a whole number from ``smallest`` to ``largest``."""

    def parse(text: str) -> int:
        value = int(text)
        if not smallest <= value <= largest:
            raise argparse.ArgumentTypeError(f"must be from {smallest} to {largest}, got {value}")
        return value

    parse.__name__ = "int"
    return parse


def _at_least(smallest: int):
    """An argparse type: a whole number >= ``smallest``."""

    def parse(text: str) -> int:
        value = int(text)
        if value < smallest:
            raise argparse.ArgumentTypeError(f"must be at least {smallest}, got {value}")
        return value

    parse.__name__ = "int"
    return parse


def example_outputs(robot: Robot, folder: Path) -> str:
    """Write the built-in trajectory (CSV, and a picture if matplotlib is there) to ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    trajectory = _example_trajectory(robot)
    table = folder / "trajectory.csv"
    write_trajectory(table, trajectory.times, trajectory.poses)
    written = [str(table)]
    try:
        from diffdrive.plot import plot_trajectory

        picture = folder / "trajectory.png"
        with atomic_output(picture) as temporary:
            plot_trajectory(robot, trajectory.times, trajectory.poses, temporary)
        written.append(str(picture))
    except ImportError:
        written.append("(no picture: pip install 'diffdrive[plot]')")
    return "outputs: " + ", ".join(written)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="diffdrive",
        description="Kinematics of differential-drive robots. With no arguments: the "
        "kinematics of a built-in example robot, and a simulation of its built-in driving "
        "history with each integration method.",
    )
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    robot = _robot_options()
    formatter = argparse.RawDescriptionHelpFormatter

    def command(name: str, help: str, parents: list, run) -> argparse.ArgumentParser:
        sub = commands.add_parser(
            name, help=help, description=help, epilog=EPILOGS[name], parents=parents,
            formatter_class=formatter,
        )  # fmt: skip
        sub.set_defaults(run=run)
        return sub

    logs = _log_options()
    sim = command(
        "simulate", "integrate a driving history into a trajectory",
        [robot, logs, _output_options("trajectory.csv")], run_simulate,
    )  # fmt: skip
    sim.add_argument("input", nargs="?", type=Path, help="driving history or log; none: built-in")
    sim.add_argument("--dt", type=float, default=0.01, help="step for the built-in history, s")
    odo = command(
        "odometry", "dead reckoning over an encoder log",
        [robot, logs, _output_options("odometry.csv")], run_odometry,
    )  # fmt: skip
    odo.add_argument("input", nargs="?", type=Path, help="encoder log; none: built-in")
    odo.add_argument(
        "--max-wheel-speed", type=float, metavar="RAD_S",
        help="refuse a row whose wheel turns faster (rad/s); default: a rim speed of "
        f"{_RIM_SPEED_LIMIT:g} m/s",
    )  # fmt: skip
    odo.add_argument("--k-left", type=float, metavar="M",
                     help="left wheel-error constant of the covariance model, m (default 0; "
                     "1e-4 with a gyro)")  # fmt: skip
    odo.add_argument(
        "--k-right",
        type=float,
        metavar="M",
        help="right wheel-error constant, m (default 0; 1e-4 with a gyro)",
    )
    gyro = odo.add_argument_group("a gyro: a bag's IMU topic or a gyro_z column (rad/s)")
    gyro.add_argument("--gyro-topic", metavar="TOPIC", help="sensor_msgs/Imu topic of the bag")
    gyro.add_argument(
        "--imu-rpy",
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=("ROLL", "PITCH", "YAW"),
        help="the IMU's mounting in the body, degrees (default 0 0 0: z up)",
    )
    gyro.add_argument("--heading", choices=("wheels", "gyro", "fused"),
                      help="heading from the wheels, the gyro, or both (default: fused with a "
                      "gyro); writes slip, slip_score and gyro_bias columns")  # fmt: skip
    gyro.add_argument(
        "--gyro-bias",
        type=float,
        metavar="RAD_S",
        help="the gyro's bias (default: its mean while the wheels stand still)",
    )
    gyro.add_argument("--command-topic", metavar="TOPIC",
                      help="geometry_msgs/Twist commands of the bag, to flag wheels that spin "
                      "beyond them (or left_command, right_command columns)")  # fmt: skip
    odo.add_argument(
        "--twist",
        action="store_true",
        help="add columns vx, vy, omega: the twist over the interval ending at "
        "each row (nan on the first)",
    )
    odo.add_argument(
        "--covariance",
        action="store_true",
        help=f"add columns {', '.join(COVARIANCE_COLUMNS)} (m^2, m rad, rad^2)",
    )
    times = argparse.ArgumentParser(add_help=False)
    times.add_argument("--time-unit", choices=TIME_UNITS, help="unit of the t column (default s)")
    times.add_argument("--topic", metavar="TOPIC",
                       help="for a bag: the trajectory's topic (nav_msgs/Odometry, "
                       "sensor_msgs/NavSatFix) or tf:PARENT:CHILD")  # fmt: skip
    times.add_argument("--truth-topic", metavar="TOPIC", help="for a bag: the truth's topic")
    pictures = argparse.ArgumentParser(add_help=False, parents=[times])
    pictures.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    pictures.add_argument(
        "input", nargs="?", type=Path, help="trajectory (CSV, JSON lines, TUM); none: built-in"
    )
    plot = command("plot", "draw a trajectory", [robot, pictures], run_plot)
    plot.add_argument("-o", "--output", type=Path, default=Path("trajectory.png"))
    plot.add_argument("--truth", type=Path, help="ground-truth trajectory, drawn underneath")
    movie = command("animate", "animate a trajectory", [robot, pictures], run_animate)
    movie.add_argument("-o", "--output", type=Path, default=Path("trajectory.gif"))
    movie.add_argument("--fps", type=_at_least(1), default=20)
    movie.add_argument("--frames", type=_at_least(2), default=120, help="frames to draw")
    cal = command("calibrate", "fit wheel radii and track width to ground truth",
                  [robot, logs], run_calibrate)  # fmt: skip
    cal.add_argument("runs", nargs="*", type=Path, help="runs with ground truth; none: built-in")
    cal.add_argument("-o", "--output", type=Path, default=Path("robot.toml"))
    cal.add_argument("--method", choices=CALIBRATION_METHODS, default="least_squares")
    cal.add_argument("--integration", choices=METHODS, default="exact",
                     help="the odometry's method (default exact)")  # fmt: skip
    cal.add_argument("--square-side", type=float, help="UMBmark's square, m")
    cal.add_argument("--cv", default="loo", metavar="loo|K|none",
                     help="held-out errors by cross-validation over the runs: leave one run "
                     "out (default), K folds, or none")  # fmt: skip
    cal.add_argument(
        "--fix",
        nargs="+",
        choices=PARAMETERS,
        metavar="PARAMETER",
        help="hold these at their nominal values (e.g. track_width)",
    )
    cal.add_argument(
        "--extra",
        nargs="+",
        choices=(*EXTRAS, "none"),
        metavar="PARAMETER",
        help="fit these too: axle_offset (the tracked point is not on the axle), "
        "heading_offset (the reference's heading is the robot's plus a constant); default "
        "both for least_squares and minimax, which predicted held-out runs best; none: neither",
    )
    cal.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    ev = command("evaluate", "a trajectory against ground truth", [times], run_evaluate)
    ev.add_argument("input", nargs="?", type=Path, help="trajectory; none: built-in")
    ev.add_argument("--truth", type=Path, help="ground-truth trajectory")
    ev.add_argument(
        "--t-max-diff",
        type=float,
        default=0.01,
        metavar="S",
        help="largest time difference of a pair of poses, s (default 0.01, as evo)",
    )
    ev.add_argument(
        "--t-offset",
        type=float,
        default=0.0,
        metavar="S",
        help="added to the trajectory's times before pairing, s (default 0)",
    )
    ev.add_argument(
        "--interpolate",
        action="store_true",
        help="sample the trajectory at the truth's times along its arcs",
    )
    ev.add_argument("--rpe", type=float, default=1.0, help="RPE window (default 1)")
    ev.add_argument("--rpe-unit", choices=["m", "s", "poses"], default="m")
    ev.add_argument(
        "--rpe-pairs",
        choices=RPE_PAIRS,
        default="consecutive",
        help="consecutive (evo's default) or all (evo's --all_pairs)",
    )
    ev.add_argument("--json", action="store_true")
    info = command("info", "what a ROS bag or MCAP file holds, and what diffdrive can use",
                   [], run_info)  # fmt: skip
    info.add_argument("input", type=Path, help="a ROS 1 bag, ROS 2 bag folder or MCAP file")
    learn = command("learn", "an interactive page for learning the kinematics, in the browser",
                    [], run_learn)  # fmt: skip
    learn.add_argument("--port", type=_between(1, 65535), help="port (default: a free one)")
    learn.add_argument("--no-browser", action="store_true", help="serve without opening it")
    learn.add_argument("--export", type=Path, metavar="HTML", help="write a static snapshot")
    fk = command("fk", "wheel velocities to the body twist", [robot], run_fk)
    fk._negative_number_matcher = _NEGATIVE_NUMBER  # -1e-3 is a number, not an option
    fk.add_argument("left", type=float, help="rad/s")
    fk.add_argument("right", type=float, help="rad/s")
    fk.add_argument("--json", action="store_true")
    ik = command("ik", "a body twist to wheel velocities", [robot], run_ik)
    ik._negative_number_matcher = _NEGATIVE_NUMBER
    ik.add_argument("vx", type=float, help="forward speed, m/s")
    ik.add_argument("omega", type=float, help="turn rate, rad/s")
    ik.add_argument("--json", action="store_true")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 done, 1 failed, 2 misused)."""
    args = build_parser().parse_args(argv)
    if args.command is None:
        robot = example_robot()
        print(kinematics_report(robot))
        print()
        print(simulation_report(robot))
        print()
        print(example_outputs(robot, Path("out")))
        return 0
    previous = _exit_on_sigterm()
    try:
        return args.run(args)
    except (ValueError, TypeError, OSError) as exc:
        print(f"diffdrive {args.command}: error: {exc}", file=sys.stderr)
        return 1
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _exit_on_sigterm():
    """Make SIGTERM unwind like Ctrl-C, so that a half-written output's temporary file goes;
    returns the handler it replaced (None where signals cannot be set: not the main thread)."""

    def terminate(signum, frame):
        raise SystemExit(128 + signum)

    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, terminate)


if __name__ == "__main__":
    sys.exit(main())
