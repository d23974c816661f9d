"""``diffdrive export``: the calibrated robot and its noise model as other stacks' files."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from diffdrive.cli.calibrate import _calibration_run
from diffdrive.cli.options import (
    Command,
    Parents,
    refuse_assumed_robot,
    refuse_unused,
    robot_from,
)
from diffdrive.export import TARGETS, Reference, export
from diffdrive.io import read_robot, robot_from_settings
from diffdrive.noise import TERMS, NoiseModel, identify_what_it_can

FILES = {
    "ros2": "diff_drive_controller.yaml",
    "robot_localization": "ekf.yaml",
    "amcl": "amcl.yaml",
    "wpilib": "pose_estimator.yaml",
}


def run_export(args: argparse.Namespace) -> int:
    if args.runs:
        by_hand = {
            "--k": args.k is not None,
            "--radius-sigma": args.radius_sigma is not None,
            "--track-sigma": args.track_sigma is not None,
        }
        refuse_unused(by_hand, "a noise model by hand, where the runs identify one: not both")
    if not args.runs and args.k is None:
        raise ValueError(
            "export needs a noise model: runs with ground truth to identify it on, or --k (m) "
            "with --radius-sigma and --track-sigma"
        )
    refuse_assumed_robot(
        args, f"export --to {args.to} writes the robot's geometry and the noise it implies"
    )
    model_robot, ticks = robot_from(args)
    robot = nominal = model_robot.equivalent  # a SkidSteer's equivalent drive: what ROS takes
    if args.nominal is not None:
        settings = read_robot(args.nominal)
        nominal = robot_from_settings(settings, f" (in {args.nominal})").equivalent
    if args.runs:
        runs = [_calibration_run(args, path, ticks)[0] for path in args.runs]
        model, left_out = identify_what_it_can(robot, runs)
        source = f"identified on {len(runs)} runs" + (
            f" ({', '.join(left_out)} left out: the runs cannot identify them)" if left_out else ""
        )
    else:
        model = NoiseModel(
            args.k,
            args.radius_sigma or 0.0,
            args.track_sigma or 0.0,
            0.0,
            0.0,
            np.zeros((5, 5)),
            0,
            TERMS[:3],
        )
        source = "given"
    at = Reference(args.distance, args.turn, args.speed, args.rate)
    output = args.output or Path(FILES[args.to])
    note = f"written by diffdrive export; noise model {source}"
    figures = export(args.to, robot, nominal, model, output, at, note)
    if not args.quiet:
        print(
            f"noise model ({source}): k {model.k:.3g} m, radius sigma {model.radius_sigma:.4g}, "
            f"track sigma {model.track_sigma:.4g}"
        )
        for name, value in figures.items():
            if isinstance(value, list) and len(value) > 6:
                value = f"{len(value)} values"
            elif isinstance(value, list):
                value = ", ".join(f"{v:.6g}" for v in value)
            elif isinstance(value, float):
                value = f"{value:.6g}"
            print(f"  {name}: {value}")
        print(f"export: wrote {args.to} parameters to {output}")
    return 0


EPILOGS = {
    "export": """examples:
  diffdrive calibrate run1.csv run2.csv -o robot.toml
  diffdrive export --to ros2 --robot robot.toml --nominal nominal.toml run1.csv run2.csv
  diffdrive export --to amcl --robot robot.toml --k 1e-4 --radius-sigma 0.002

The noise model is identified on the runs given (ground truth as the reference), or taken from
--k, --radius-sigma and --track-sigma. How each figure is derived: the module
diffdrive.export, and the comments at the top of the file written.""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive export``."""
    ex = command(
        "export",
        "the calibrated robot and its noise model as ROS 2, robot_localization, AMCL or "
        "WPILib parameters",
        [parents.robot, parents.logs],
        run_export,
        EPILOGS["export"],
    )
    ex.add_argument("runs", nargs="*", type=Path, help="runs with ground truth to identify on")
    ex.add_argument("--to", choices=TARGETS, required=True, help="the file to write")
    ex.add_argument("-o", "--output", type=Path, help="default: the target's usual file name")
    ex.add_argument("--nominal", type=Path, help="the nominal robot file ROS multiplies")
    ex.add_argument("--k", type=float, metavar="M", help="wheel noise, m (without runs)")
    ex.add_argument("--radius-sigma", type=float, metavar="REL", help="per-run radius error")
    ex.add_argument("--track-sigma", type=float, metavar="REL", help="per-run track error")
    ex.add_argument("--distance", type=float, default=1.0, help="straight motion, m (1)")
    ex.add_argument("--turn", type=float, default=1.0, help="turn in place, rad (1)")
    ex.add_argument("--speed", type=float, default=0.5, help="speed, m/s (0.5)")
    ex.add_argument("--rate", type=float, default=50.0, help="odometry rate, Hz (50)")
    ex.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
