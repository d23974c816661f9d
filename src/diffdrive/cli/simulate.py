"""``diffdrive simulate``: integrate a driving history into a trajectory."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from diffdrive.cli.options import (
    LOG_COLUMNS,
    Command,
    Parents,
    add_method_option,
    example_trajectory,
    output_format,
    output_options,
    read_log_of,
    robot_from,
    robot_note,
    write_output,
)
from diffdrive.demo import EXAMPLE_DURATION
from diffdrive.simulation import simulate_run

DT = 0.01  # --dt's default, s


def run_simulate(args: argparse.Namespace) -> int:
    robot, ticks = robot_from(args)
    if args.input is None:
        trajectory = example_trajectory(robot, args.dt, args.method)
        twists = trajectory.twists  # each step's, held over it: row k the step ending there
        write_output(
            args,
            trajectory.times,
            trajectory.poses,
            f"simulated the built-in {EXAMPLE_DURATION:g} s driving history",
            twists=np.concatenate([twists[:1], twists]),
        )
        return 0
    if args.dt != DT:
        raise ValueError(f"--dt sets the built-in history's step; {args.input} has its own times")
    if output_format(args) in ("mcap", "ros2"):
        # A log's dead reckoning as an exact trajectory: its zero covariances would tell a
        # ROS filter to trust it beyond any sensor.
        raise ValueError(
            f"simulate writes {args.input} as an exact trajectory, and a bag's nav_msgs/Odometry "
            "would carry zero covariances; diffdrive odometry writes a log's odometry to a bag "
            "with its covariances (--k)"
        )
    log = read_log_of(args)
    increments, note = log.checked_increments(robot, ticks, args.counter_bits)
    note += robot_note(args)
    poses = simulate_run(robot, log, increments, args.method)
    write_output(args, log.times, poses, f"simulated {args.input}")
    if not args.quiet:
        print(note)
    return 0


EPILOGS = {
    "simulate": f"""examples:
  diffdrive simulate                       the built-in driving history -> trajectory.csv
  diffdrive simulate -o sim.mcap           as nav_msgs/Odometry (exact: zero covariances)
  diffdrive simulate drive.csv -o out.tum --method rk2 --robot robot.toml

{LOG_COLUMNS}""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive simulate``."""
    sim = command(
        "simulate",
        "integrate a driving history into a trajectory",
        [parents.robot, parents.logs, output_options("trajectory.csv")],
        run_simulate,
        EPILOGS["simulate"],
    )
    sim.add_argument("input", nargs="?", type=Path, help="driving history or log; none: built-in")
    add_method_option(sim)
    sim.add_argument(
        "--dt", type=float, default=DT, help=f"step for the built-in history, s (default {DT})"
    )
