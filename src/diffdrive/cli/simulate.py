"""``diffdrive simulate``: integrate a driving history into a trajectory."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from diffdrive.cli.options import (
    LOG_COLUMNS,
    Command,
    Parents,
    example_trajectory,
    output_options,
    read_log_of,
    robot_from,
    write_output,
)
from diffdrive.demo import EXAMPLE_DURATION
from diffdrive.simulation import simulate_run


def run_simulate(args: argparse.Namespace) -> int:
    robot, ticks = robot_from(args)
    if args.input is None:
        _check_step_count(args.dt)
        trajectory = example_trajectory(robot, args.dt, args.method)
        write_output(
            args,
            trajectory.times,
            trajectory.poses,
            f"simulated the built-in {EXAMPLE_DURATION:g} s driving history",
        )
        return 0
    log = read_log_of(args)
    increments, note = log.checked_increments(robot, ticks, args.counter_bits)
    poses = simulate_run(robot, log, increments, args.method)
    write_output(args, log.times, poses, f"simulated {args.input}")
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


EPILOGS = {
    "simulate": f"""examples:
  diffdrive simulate                       the built-in driving history -> trajectory.csv
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
    sim.add_argument("--dt", type=float, default=0.01, help="step for the built-in history, s")
