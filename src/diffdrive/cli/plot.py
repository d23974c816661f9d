"""``diffdrive plot`` and ``diffdrive animate``: pictures of a trajectory."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from diffdrive.cli.options import (
    TRAJECTORY_FILES,
    Command,
    Parents,
    assumed_robot,
    at_least,
    refuse_truth_topic_alone,
    robot_from,
    trajectory_or_example,
)
from diffdrive.io import TableError, atomic_output, read_trajectory


def run_plot(args: argparse.Namespace) -> int:
    from diffdrive.plot import plot_trajectory

    refuse_truth_topic_alone(args)
    robot, _ = robot_from(args)
    times, poses, what = trajectory_or_example(args, robot)
    truth = None
    if args.truth is not None:
        truth = read_trajectory(args.truth, args.time_unit, args.truth_topic)
    assumed = assumed_robot(args)
    if args.errors:
        return _plot_errors(args, times, poses, truth)
    with atomic_output(args.output) as temporary:
        plot_trajectory(robot, times, poses, temporary, truth, assumed=assumed)
    if not args.quiet:
        print(f"plotted {what} to {args.output}")
    return 0


def _plot_errors(args, times, poses, truth) -> int:
    """The estimate's errors against the truth with its 2-sigma bands (--errors)."""
    from diffdrive.evaluation import interpolate
    from diffdrive.io.trajectories import read_covariances
    from diffdrive.plot import plot_error_bands

    if args.input is None or truth is None or poses.ndim != 2:
        raise TableError("--errors needs one estimate with a covariance and its --truth")
    covariances = read_covariances(args.input, len(times), args.time_unit, args.topic)
    truth_times, truth_poses = truth
    inside = (times >= truth_times[0]) & (times <= truth_times[-1])
    if np.count_nonzero(inside) < 2:
        raise TableError(f"{args.truth}: its times do not cover {args.input}'s")
    at = times[inside]
    with atomic_output(args.output) as temporary:
        share = plot_error_bands(
            at,
            poses[inside],
            covariances[inside],
            interpolate(truth_times, truth_poses, at),
            temporary,
        )
    if not args.quiet:
        print(f"plotted the errors of {args.input} to {args.output}: {share:.1%} inside 2 sigma")
    return 0


def run_animate(args: argparse.Namespace) -> int:
    from diffdrive.plot import animate, animation_writer

    if args.truth_topic is not None:
        raise TableError("--truth-topic: animate draws the trajectory alone, with no truth")
    robot, _ = robot_from(args)
    times, poses, what = trajectory_or_example(args, robot)
    if poses.ndim != 2:
        raise TableError(f"{args.input}: animate draws one robot; the file has {len(poses)}")
    writer, output = animation_writer(args.output)
    with atomic_output(output) as temporary:
        animate(
            robot,
            times,
            poses,
            temporary,
            writer,
            frames=args.frames,
            fps=args.fps,
            progress=not args.quiet and sys.stderr.isatty(),
        )
    if not args.quiet:
        print(f"animated {what} to {output} ({writer})")
    return 0


EPILOGS = {
    "plot": f"""examples:
  diffdrive plot                          the built-in example -> trajectory.png
  diffdrive plot odometry.csv --truth log.csv -o odometry.svg

{TRAJECTORY_FILES} --truth is drawn underneath.""",
    "animate": """examples:
  diffdrive animate                       the built-in example -> trajectory.gif
  diffdrive animate trajectory.csv -o drive.mp4     (MP4 needs ffmpeg; else a GIF)""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive plot and animate``."""
    plot = command(
        "plot", "draw a trajectory", [parents.robot, parents.pictures], run_plot, EPILOGS["plot"]
    )
    plot.add_argument("-o", "--output", type=Path, default=Path("trajectory.png"))
    plot.add_argument("--truth", type=Path, help="ground-truth trajectory, drawn underneath")
    plot.add_argument(
        "--errors",
        action="store_true",
        help="draw the errors against --truth with the estimate's plus/minus 2-sigma bands "
        "(its covariance columns, as odometry --covariance writes them)",
    )
    movie = command(
        "animate",
        "animate a trajectory",
        [parents.robot, parents.pictures],
        run_animate,
        EPILOGS["animate"],
    )
    movie.add_argument("-o", "--output", type=Path, default=Path("trajectory.gif"))
    movie.add_argument("--fps", type=at_least(1), default=20)
    movie.add_argument("--frames", type=at_least(2), default=120, help="frames to draw")
