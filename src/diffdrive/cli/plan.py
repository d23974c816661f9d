"""``diffdrive plan`` and ``diffdrive follow``: a path timed within every wheel's limits, and
trackers driving robots along it."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from diffdrive.cli.options import (
    Command,
    Parents,
    output_options,
    refuse_assumed_robot,
    robot_from,
)
from diffdrive.cli.options import write_output as write_poses
from diffdrive.control import (
    MPPI,
    Avoidance,
    FollowSettings,
    LTVUnicycle,
    MPPISampling,
    PathLimits,
    Predictive,
    PurePursuit,
    Ramsete,
    delay_margin,
    follow,
    limit_ratios,
    plan,
    read_map,
)
from diffdrive.control._timing import compiles_first
from diffdrive.dynamics import DriveModel, Feedforward
from diffdrive.io import TableError, read_drive, read_table
from diffdrive.io.tables import read_header

LIMIT_FLAGS = {
    "max_velocity": "m/s",
    "max_acceleration": "m/s^2",
    "max_angular_velocity": "rad/s",
    "max_angular_acceleration": "rad/s^2",
    "max_centripetal_acceleration": "m/s^2",
    "max_wheel_velocity": "rad/s",
    "max_wheel_acceleration": "rad/s^2",
    "max_voltage": "V",
    "max_jerk": "m/s^3",
}
TRACKERS = ("ramsete", "ltv", "pure-pursuit")


def _plan_of(args: argparse.Namespace):
    # The wheels' limits and the spline's curvature meet through the track and radii: the
    # built-in robot's would give a plan for another robot.
    refuse_assumed_robot(args, f"{args.command} needs the robot")
    robot, _ = robot_from(args)
    if compiles_first():  # said once: the first plan would otherwise sit silent for long
        print(
            f"diffdrive {args.command}: compiling the path-timing kernel with numba, once "
            "(about half a minute); later runs load it from the cache",
            file=sys.stderr,
        )
    unused = [name for name in read_header(args.waypoints) if name not in ("x", "y", "theta")]
    if unused:
        # A heading under another name would be dropped and the spline's own taken instead.
        raise ValueError(
            f"{args.waypoints}: column {', '.join(map(repr, unused))} is not read; waypoints are "
            "x, y (m) and optionally theta (rad, the robot's heading)"
        )
    table = read_table(args.waypoints, ["x", "y"], ["theta"], increasing=None)
    columns = ["x", "y"] + (["theta"] if "theta" in table else [])
    waypoints = np.column_stack([table[name] for name in columns])
    feedforward = None
    if args.feedforward is not None:
        # SysId's gains are per m/s of the wheel's surface; the plan's wheels turn in rad/s.
        radius = 0.5 * (robot.left_wheel_radius + robot.right_wheel_radius)
        feedforward = Feedforward(*args.feedforward).per_radian(radius)
    limits = PathLimits(
        **{name: getattr(args, name) for name in LIMIT_FLAGS}, feedforward=feedforward
    )
    stops = _indices(args.stops) if args.stops else []
    try:
        return robot, plan(waypoints, robot, limits, reverse=args.reverse, stops=stops)
    except ValueError as error:
        where = (
            " (waypoints count from 0: waypoint n is on the (n + 2)th line, after the header)"
            if "waypoint" in str(error)
            else ""
        )
        raise ValueError(f"{args.waypoints}: {error}{where}") from None


def run_plan(args: argparse.Namespace) -> int:
    robot, result = _plan_of(args)
    trajectory = result.to_trajectory(args.dt)
    sampled = result.sample(trajectory.times)
    columns = {
        "v": sampled["twist"][:, 0],
        "omega": sampled["twist"][:, 1],
        "left": sampled["wheel_velocities"][:, 0],
        "right": sampled["wheel_velocities"][:, 1],
    }
    # Judged on the rows written, as whoever drives them will step through them.
    ratios = limit_ratios(trajectory.times, sampled["twist"], robot, result.limits)
    write_poses(args, trajectory.times, trajectory.poses, "plan", columns)
    if args.plot:
        from diffdrive.plot import plot_plan

        plot_plan(result, args.plot)
    if not args.quiet:
        print(
            f"plan: {result.duration:.3f} s over {result.length:.3f} m, "
            f"{len(result.times)} states, written every {args.dt} s"
        )
        for name, ratio in ratios.items():
            print(f"  {name}: at most {100 * ratio.max():.1f} % of its limit")
        if args.plot:
            print(f"plan: drew {args.plot}")
    return 0


def _tracker(args: argparse.Namespace, drive: DriveModel | None, avoid: Avoidance | None):
    if args.tracker == "mppi":  # it rolls its samples out through the delay itself
        known = drive or DriveModel(time_constant=args.lag)
        return MPPI(
            dt=args.dt,
            drive=known,
            delay=args.delay or known.delay,
            avoid=avoid,
            sampling=MPPISampling(seed=args.seed),
        )
    tracker = {"ramsete": Ramsete, "ltv": LTVUnicycle, "pure-pursuit": PurePursuit}[args.tracker]
    made = tracker(dt=args.dt) if args.tracker == "ltv" else tracker()
    if args.predict:
        return Predictive(made, delay=args.delay, dt=args.dt, lag=args.lag)
    return made


def _drive_of(args: argparse.Namespace) -> DriveModel | None:
    """``--drive``'s response as a ``DriveModel``, or None; ``TableError`` naming the file
    when it has no ``[response]``."""
    if args.drive is None:
        return None
    if args.lag:
        raise ValueError("--drive gives the wheels' response: leave --lag out")
    sections = read_drive(args.drive)
    if "response" not in sections:
        raise TableError(
            f"{args.drive}: follow --drive needs its [response] section (a velocity-commanded "
            "drive's delay, time constant, gain and acceleration; diffdrive identify writes "
            "it from commands)"
        )
    response = sections["response"]
    return DriveModel(
        delay=response.get("delay", 0.0),
        time_constant=response.get("time_constant", 0.0),
        gain=response.get("gain", 1.0),
        max_acceleration=response.get("acceleration", np.inf),
    )


def _avoidance_of(args: argparse.Namespace) -> Avoidance | None:
    """``--obstacles``' map and the robot's footprint (m, finite, >= 0) among them, or None
    (``follow``'s trackers have none); the footprint is checked before the map is read."""
    if getattr(args, "obstacles", None) is None:
        return None
    where, text = args.obstacles
    try:
        footprint = float(text)
    except ValueError:
        footprint = math.nan
    if not (math.isfinite(footprint) and footprint >= 0.0):
        raise ValueError(
            f"--obstacles {where} {text}: the footprint is the robot's radius, m (finite, >= 0)"
        )
    return Avoidance(read_map(Path(where)), footprint)


def _response(args: argparse.Namespace, drive: DriveModel | None) -> str:
    """The report's words for the wheels' response the run simulated."""
    if drive is None:
        return f"lag {args.lag} s"
    return (
        f"drive {args.drive}: time constant {drive.time_constant:g} s, gain {drive.gain:g}, "
        f"acceleration limit {drive.max_acceleration:g} rad/s^2"
    )


def run_follow(args: argparse.Namespace) -> int:
    if args.seed is not None and not args.wheel_noise and args.tracker != "mppi":
        raise ValueError("--seed draws the wheel noise: give --wheel-noise too, or leave it out")
    if args.predict and not (args.delay or args.lag):
        raise ValueError("--predict predicts over the delay and lag: give --delay or --lag")
    drive = _drive_of(args)
    avoid = _avoidance_of(args)
    robot, result = _plan_of(args)
    tracker = _tracker(args, drive, avoid)
    if getattr(args, "nav2_mppi", None):  # refused now, not after the run
        from diffdrive.export.nav2_mppi import nav2_mppi_parameters

        nav2_mppi_parameters(tracker, robot, result.limits)
    noise = args.wheel_noise  # k (m), both wheels
    run = follow(
        result,
        tracker,
        dt=args.dt,
        delay=args.delay,
        lag=args.lag,
        drive=drive,
        settings=FollowSettings(robots=args.robots, wheel_noise=noise, seed=args.seed),
    )
    stalls = list(getattr(tracker, "stalls", []))  # before delay_margin runs it again
    errors = run.errors()
    known = args.delay if args.predict or args.tracker == "mppi" else 0.0
    columns = {
        "cross_track": errors.cross_track[0],
        "along_track": errors.along_track[0],
        "heading_error": errors.heading[0],
    }
    write_poses(args, run.times, run.poses[0], "follow", columns)
    if getattr(args, "nav2_mppi", None):
        from diffdrive.export.nav2_mppi import write_nav2_mppi

        write_nav2_mppi(args.nav2_mppi, tracker, robot, result.limits)
    if args.plot:
        from diffdrive.plot import plot_plan

        plot_plan(result, args.plot, followed=run)
    if not args.quiet:  # the report; -q leaves out its delay-margin search, the longest part
        margin = delay_margin(result, tracker, dt=args.dt, lag=args.lag, known=known, drive=drive)
        name = f"{args.tracker}{' (predictive)' if args.predict else ''}"
        print(
            f"follow: {name}, delay {float(run.delays[0]):g} s, {_response(args, drive)}, "
            f"wheel noise {args.wheel_noise} m, {args.robots} robot(s)"
        )
        for label, part in (("robot 0 (written)", slice(0, 1)), ("all robots", slice(None))):
            summary = {
                "mean position": float(errors.position[part].mean()),
                "max position": float(errors.position[part].max()),
                "max cross-track": float(np.abs(errors.cross_track[part]).max()),
                "max heading": float(np.degrees(np.abs(errors.heading[part]).max())),
            }
            print(
                f"  {label}: error mean {1e3 * summary['mean position']:.1f} mm, max "
                f"{1e3 * summary['max position']:.1f} mm; cross-track max "
                f"{1e3 * summary['max cross-track']:.1f} mm; heading max "
                f"{summary['max heading']:.2f} deg"
            )
            if args.robots == 1:
                break
        if avoid is not None:
            gaps = avoid.obstacles.clearance_at(run.poses[..., :2]) - avoid.footprint
            touching = int(np.count_nonzero(gaps < 0.0))
            print(
                f"  obstacles ({args.obstacles[0]}): closest {1e3 * float(gaps.min()):.0f} mm "
                f"beyond the footprint; touching at {touching} of {gaps.size} poses"
            )
        ends = np.hypot(*(run.poses[:, -1, :2] - result.poses[-1, :2]).T)
        print(
            f"  end: robot 0 {1e3 * float(ends[0]):.1f} mm from the plan's last pose"
            + (f", every robot within {1e3 * float(ends.max()):.1f} mm" if args.robots > 1 else "")
        )
        for stall in stalls:
            outcome = "a way from there followed" if stall.detour else f"no way: {stall.why}"
            print(
                f"  stalled: robot {stall.robot} at {stall.t:.2f} s, {stall.distance:.3f} m "
                f"from the goal; {outcome}"
            )
        if getattr(args, "nav2_mppi", None):
            print(f"  Nav2 MPPI parameters: {args.nav2_mppi}")
        beyond = " beyond the known delay" if known else ""
        print(
            f"  delay margin{beyond}: {margin:.2f} s (by simulation along this plan, with this lag)"
        )
    return 0


EPILOGS = {
    "plan": """examples:
  diffdrive plan waypoints.csv --robot robot.toml --max-velocity 1 --max-acceleration 1 \\
      --max-wheel-velocity 20 -o plan.csv --plot plan.png
  diffdrive plan waypoints.csv --robot robot.toml --max-velocity 3 --max-acceleration 2 \\
      --max-voltage 10 --feedforward 1.34 3.13 0.926 -o plan.csv

waypoints.csv has columns x, y (m) and optionally theta (rad, the robot's heading); two rows at
one place with different headings make a turn in place. Written: t, x, y, theta, v, omega and
the wheel velocities left, right (rad/s) every --dt s; printed: how much of each limit the
written rows use.""",
    "follow": """examples:
  diffdrive follow waypoints.csv --robot robot.toml --max-velocity 1 --max-acceleration 1 \\
      --tracker ltv --delay 0.1 --lag 0.1 --predict --plot follow.png
  diffdrive follow waypoints.csv --robot robot.toml --max-velocity 1 --max-acceleration 1 \\
      --robots 200 --wheel-noise 1e-4 --seed 1 -o follow.csv

Written: robot 0's true poses with its cross-track, along-track and heading errors. Printed:
the errors, how far from the plan's last pose the robots end, and the delay margin, found by
simulation (-q prints nothing and leaves that search out). Around obstacles: diffdrive mppi.""",
    "mppi": """examples:
  diffdrive mppi waypoints.csv --robot robot.toml --max-velocity 1 --max-acceleration 1 \\
      --delay 0.1 --lag 0.1 --obstacles map.yaml 0.2 --nav2-mppi mppi.yaml --plot mppi.png

It rolls its samples out through the delay and the lag itself. Written: robot 0's true poses
with its cross-track, along-track and heading errors. Printed: the errors, how far from the
plan's last pose the robots end, each stall found short of the goal (and whether a way from
there was followed), and the delay margin beyond the known delay, found by simulating the
controller again (the longest part: -q prints nothing and leaves it out). --nav2-mppi's
figures are checked before the run (a wheel limit is needed).""",
}


def _indices(text: str) -> list[int]:
    """``--stops``: waypoint indices separated by commas (a refusal, exit 1, as for any
    value the command reads)."""
    try:
        return [int(part) for part in text.split(",")]
    except ValueError:
        raise ValueError(
            f"--stops takes waypoint indices (whole numbers from 0) separated by commas, got "
            f"{text!r}"
        ) from None


def _planning_options(sub: argparse.ArgumentParser) -> None:
    sub.add_argument("waypoints", type=Path, help="CSV of waypoints: x, y[, theta]")
    for name, unit in LIMIT_FLAGS.items():
        sub.add_argument("--" + name.replace("_", "-"), type=float, metavar=unit.upper())
    sub.add_argument(
        "--feedforward",
        type=float,
        nargs=3,
        metavar=("KS", "KV", "KA"),
        help="the wheels' feedforward as SysId gives it: V, V s/m, V s^2/m (with --max-voltage)",
    )
    sub.add_argument("--reverse", action="store_true", help="drive the path backward")
    sub.add_argument(
        "--stops",
        metavar="I,J",
        help="interior waypoints to halt at, counted from 0, separated by commas",
    )
    sub.add_argument("--dt", type=float, default=0.02, help="period, s (0.02)")
    sub.add_argument("--plot", type=Path, metavar="PNG", help="draw the plan (and the runs)")


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive plan`` and ``diffdrive follow``."""
    planned = command(
        "plan",
        "the fastest timing of a path through waypoints within every wheel's limits",
        [parents.robot_required, output_options("plan.csv")],
        run_plan,
        EPILOGS["plan"],
    )
    _planning_options(planned)
    followed = command(
        "follow",
        "simulate a tracker (Ramsete, LTV, pure pursuit) driving robots along a plan, with "
        "delay, lag and noisy odometry",
        [parents.robot_required, output_options("follow.csv")],
        run_follow,
        EPILOGS["follow"],
    )
    _planning_options(followed)
    followed.add_argument("--tracker", choices=TRACKERS, default="ramsete")
    _run_options(followed)
    followed.add_argument("--predict", action="store_true", help="predict over the delay and lag")
    followed.add_argument("--seed", type=int, help="for the wheel noise")
    sampled = command(
        "mppi",
        "simulate sampling-based predictive control (MPPI) driving robots along a plan, "
        "around a map's obstacles, with delay, lag and noisy odometry",
        [parents.robot_required, output_options("mppi.csv")],
        run_follow,
        EPILOGS["mppi"],
    )
    sampled.set_defaults(tracker="mppi", predict=False)
    _planning_options(sampled)
    _run_options(sampled)
    sampled.add_argument("--seed", type=int, help="for the wheel noise and the sampling")
    sampled.add_argument(
        "--obstacles",
        nargs=2,
        metavar=("MAP_YAML", "FOOTPRINT"),
        help="a ROS map's map.yaml (map_server, Nav2's map_saver) and the robot's radius "
        "among its obstacles, m",
    )
    sampled.add_argument(
        "--nav2-mppi",
        type=Path,
        metavar="FILE",
        help="also write the controller's settings as Nav2 MPPI controller parameters (YAML)",
    )


def _run_options(sub: argparse.ArgumentParser) -> None:
    """What the simulated robots are: their wheels' delay and response, how many, their noise."""
    sub.add_argument("--delay", type=float, default=0.0, help="actuation delay, s (0)")
    sub.add_argument("--lag", type=float, default=0.0, help="wheels' time constant, s (0)")
    sub.add_argument(
        "--drive",
        type=Path,
        metavar="FILE",
        help="the wheels' identified response instead of --lag: a drive file's [response] "
        "(diffdrive identify writes it): delay, time constant, gain, acceleration limit",
    )
    sub.add_argument("--robots", type=int, default=1, help="robots in the batch (1)")
    sub.add_argument("--wheel-noise", type=float, default=0.0, metavar="M", help="k, m (0)")
