"""``diffdrive export``: the calibrated robot, its noise model and its drive as other stacks'
files, each checked against the runs it came from before it is written."""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

from diffdrive.calibration.noise import (
    MOTION_CAPTURE,
    NoiseModel,
    identify_what_it_can,
    score,
)
from diffdrive.cli.calibrate import _calibration_run
from diffdrive.cli.options import (
    Command,
    Parents,
    between,
    refuse_assumed_robot,
    refuse_unused,
    robot_from,
    robot_noise,
)
from diffdrive.estimation.settings import Encoders
from diffdrive.export import (
    FILES,
    MIN_INSIDE_95,
    TARGETS,
    DriveConstants,
    Reference,
    amcl_fit,
    export,
    refusals,
)
from diffdrive.io import TableError, is_bag, read_drive, read_robot, robot_from_settings
from diffdrive.sensor_noise import WheelNoise


def run_export(args: argparse.Namespace) -> int:
    in_file = robot_noise(args).get("wheel_noise")  # (WheelNoise, its file) or None
    _refuse_misplaced(args, in_file is not None)
    refuse_assumed_robot(
        args, f"export {args.to} writes the robot's geometry and the noise it implies"
    )
    wheel_names = _wheel_names(args)
    drive = _drive(args)
    model_robot, ticks = robot_from(args)
    robot = nominal = model_robot.equivalent  # a SkidSteer's equivalent drive: what ROS takes
    if getattr(args, "nominal", None) is not None:
        settings = read_robot(args.nominal)
        nominal = robot_from_settings(settings, f" (in {args.nominal})").equivalent
    notes = ["written by diffdrive export"]
    lines: list[str] = []
    score = ""
    if args.runs:
        model, held, score = _identified(args, robot, ticks, notes, lines)
        if in_file is not None:
            lines.append(
                f"the wheel noise in {in_file[1]} left aside: the runs identify the noise model"
            )
    else:
        model, given = _by_hand(args, in_file)
        notes.append(f"noise model {given}: not checked")
        held = []
    if held and not args.accept_inconsistent:
        raise ValueError(
            f"export: the noise model is not fit to write into {args.to}'s file: "
            + "; ".join(held)
            + f" ({score}). --accept-inconsistent writes it anyway, saying so in the file"
        )
    if held:
        notes.append(
            "WRITTEN THOUGH INCONSISTENT with its runs (--accept-inconsistent): " + "; ".join(held)
        )
    at = Reference(**{name: getattr(args, name) for name in TARGET_REFERENCE[args.to]})
    if args.to == "amcl":
        fit = amcl_fit(robot, model, at)
        x_miss, y_miss = fit.split
        notes.append(
            f"alphas matched to Nav2's sampler on {'; '.join(fit.motions)}: within "
            f"{fit.worst:.0%} of the model on each term (the turn's x and y as their sum; "
            f"apart, {x_miss:+.0%} and {y_miss:+.0%}: AMCL turns each update's noise at its "
            "start heading)"
        )
    if args.to == "wpilib" and drive is None:
        notes.append("no drive identification given (--drive): no kS, kV, kA")
    encoders = _encoders(args, ticks, notes)
    output = args.output or Path(FILES[args.to])
    figures = export(
        args.to,
        robot,
        nominal,
        model,
        output,
        at,
        notes,
        wheel_names=wheel_names,
        drive=drive,
        encoders=encoders,
    )
    for reason in held:  # said even with -q: the file is known to be off
        print(f"diffdrive export: warning: written though {reason}", file=sys.stderr)
    if not args.quiet:
        for line in lines:
            print(line)
        print(
            f"noise model: k {model.k_left:.3g} m left, {model.k_right:.3g} m right, radius "
            f"sigma {model.radius_sigma:.4g} (correlation {model.correlation[0, 1]:.2f}), "
            f"track sigma {model.track_sigma:.4g}, reference {1000 * model.reference_sigma:.3g} mm "
            f"and {math.degrees(model.reference_heading_sigma):.3g} deg"
        )
        for name, value in _flat(figures):
            if isinstance(value, list) and len(value) > 6:
                value = f"{len(value)} values"
            elif isinstance(value, list):
                value = ", ".join(v if isinstance(v, str) else f"{v:.6g}" for v in value)
            elif isinstance(value, float):
                value = f"{value:.6g}"
            print(f"  {name}: {value}")
        print(f"export: wrote {args.to} parameters to {output}")
    return 0


def _refuse_misplaced(args, noise_in_file: bool) -> None:
    """The options that cannot apply to this export, by name."""
    if args.runs:
        by_hand = {
            "--k": args.k is not None,
            "--radius-sigma": args.radius_sigma is not None,
            "--track-sigma": args.track_sigma is not None,
        }
        refuse_unused(by_hand, "a noise model by hand, where the runs identify one: not both")
    else:
        refuse_unused(
            {
                "--reference-noise": args.reference_noise is not None,
                "--accept-inconsistent": args.accept_inconsistent,
            },
            "used only with runs, which identify the noise model and hold it to them",
        )
    if not args.runs and args.k is None and not noise_in_file:
        raise ValueError(
            "export needs a noise model: runs with ground truth to identify it on, --k (m), or "
            "a robot file with the noise calibrate-driving found ([noise.wheel_noise]); with "
            "--radius-sigma and --track-sigma"
        )


def _by_hand(args, in_file) -> tuple[NoiseModel, str]:
    """The noise model without runs, and where it came from: the wheels' k from --k, else
    from a robot file's ``[noise.wheel_noise]`` (what ``calibrate-driving`` identified), each
    radius and the track spread by --radius-sigma and --track-sigma."""
    spread = NoiseModel.symmetric(0.0, args.radius_sigma or 0.0, args.track_sigma or 0.0)
    if args.k is not None:
        wheels, given = WheelNoise.symmetric(args.k), "given by hand (--k"
    else:  # _refuse_misplaced has checked that the robot file holds it
        part, source = in_file
        wheels, given = WheelNoise.coerce(part), f"with the wheels' k from {source} ("
    given += ", --radius-sigma, --track-sigma)"
    return replace(spread, wheel_noise=wheels), given


def _wheel_names(args) -> tuple[str, str] | None:
    """The controller's wheel joints (--joints , ), which ros2 needs."""
    if args.to != "ros2":
        return None
    if args.joints is None:
        raise ValueError(
            "export ros2 writes diff_drive_controller's left_wheel_names and "
            "right_wheel_names: give --joints LEFT RIGHT (the wheels' joints in the robot's "
            "URDF, as a bag's /joint_states names them)"
        )
    return args.joints[0], args.joints[1]


def _flat(figures: dict[str, object]):
    """(name, value) of each figure, a group's (the C header's structs) as group.name."""
    for name, value in figures.items():
        if isinstance(value, dict):
            yield from ((f"{name}.{field}", item) for field, item in value.items())
        else:
            yield name, value


def _encoders(args, ticks: float | None, notes: list[str]) -> Encoders | None:
    """The firmware's encoders (c-header): counts per revolution and the counters' width,
    which the C core needs to turn readings into angles, refused by name when not given."""
    if args.to != "c-header":
        return None
    if ticks is None:
        raise ValueError(
            "export c-header writes the encoders' counts per wheel revolution, which the "
            "firmware turns ticks into angles with: give --ticks-per-revolution N (or "
            "ticks_per_revolution in the robot file)"
        )
    if args.counter_bits is None:
        raise ValueError(
            "export c-header writes the width of the encoder counters, which tells a "
            "roll-over from a jump: give --counter-bits B (16 on many motor drivers, 32 on a "
            "microcontroller's timer, 64 for a count that never rolls over)"
        )
    notes.append(
        "max_wheel_speed not known here: INFINITY, no reading refused for its speed (set it "
        "to the motors' top speed, rad/s, to catch a glitch or a misread roll-over)"
    )
    return Encoders(ticks_per_revolution=ticks, counter_bits=args.counter_bits)


def _drive(args) -> DriveConstants | None:
    """WPILib's kS, kV, kA from a drive file (``diffdrive identify`` writes one)."""
    if getattr(args, "drive", None) is None:
        return None
    sections = read_drive(args.drive)
    if "feedforward" not in sections:
        raise TableError(
            f"{args.drive}: no [feedforward] (kS, kV, kA): the drive was identified from "
            "commands alone, a velocity response; WPILib's feedforward needs a voltage log "
            "(diffdrive identify of a table with left_voltage, right_voltage)"
        )
    linear = sections["feedforward"]
    angular = sections.get("angular", {})
    missing = [key for key in ("ks", "kv", "ka") if key not in linear]
    if missing:
        raise TableError(f"{args.drive}: [feedforward] lacks {', '.join(missing)}")
    return DriveConstants(
        linear["ks"], linear["kv"], linear["ka"], angular.get("kv"), angular.get("ka")
    )


def _identified(args, robot, ticks, notes: list[str], lines: list[str]):
    """The noise model identified on the runs, the reference's accuracy held at what was
    stated (or at motion capture's for tables), the reasons its own runs give against
    writing it (``export.refusals``) and the line of its score on them."""
    read = [_calibration_run(args, path, ticks, robot)[0] for path in args.runs]
    fixed = None
    stated = args.reference_noise
    if stated is None and not any(is_bag(path) for path in args.runs):
        stated = MOTION_CAPTURE  # m and rad, as --reference-noise takes them
        source = "motion capture's (a table's ground truth), by default"
    else:
        source = "as stated (--reference-noise)" if stated is not None else "identified"
    if stated is not None:
        meters, radians = stated
        fixed = {"reference_sigma": meters, "reference_heading_sigma": radians}
        source = f"{1000 * meters:g} mm and {math.degrees(radians):g} deg, {source}"
    model, left_out = identify_what_it_can(robot, read, fixed=fixed)
    identified = f"identified on {len(read)} runs" + (
        f" ({', '.join(left_out)} left out: the runs cannot identify them)" if left_out else ""
    )
    found = score(robot, read, model)
    held = (
        f"held to its runs (the reference's own noise added): {found.inside_95:.0%} of "
        f"{found.used} poses inside its 95 % ellipse (at least {MIN_INSIDE_95:.0%} needed), "
        f"ANEES {found.anees:.3g}"
    )
    notes += [f"noise model {identified}; the reference's accuracy {source}", held]
    lines += [f"noise model {identified}; the reference's accuracy {source}", held]
    at_bound = [
        t for t in ("radius_sigma", "track_sigma") if t in model.terms and not getattr(model, t)
    ]
    if at_bound:
        lines.append(f"{', '.join(at_bound)} at 0: the runs show no run-to-run change of it")
    return model, refusals(found, model), held


EPILOGS = {
    "export": """examples:
  diffdrive calibrate run1.csv run2.csv --robot nominal.toml -o robot.toml
  diffdrive export ros2 --robot robot.toml --nominal nominal.toml run1.csv run2.csv \\
      --joints left_wheel_joint right_wheel_joint
  diffdrive export amcl --robot robot.toml --k 1e-4 --radius-sigma 0.002
  diffdrive identify sysid.csv --robot robot.toml -o drive.toml
  diffdrive export wpilib --robot robot.toml --drive drive.toml run1.csv run2.csv
  diffdrive export c-header --robot robot.toml --ticks-per-revolution 4096 \\
      --counter-bits 16 run1.csv run2.csv

The noise model is identified on the runs given (ground truth as the reference, its own
accuracy held at --reference-noise: by default motion capture's, 1 mm and 0.1 deg, for tables;
identified for a bag's --reference-topic), then held to them: below 80 % of their poses inside
its 95 % ellipse, or with its wheel noise k at 0, it is refused (--accept-inconsistent writes
it, saying so in the file). Or it is taken from --k, --radius-sigma and --track-sigma. How each
figure is derived: the module diffdrive.export, and the notes at the top of the file. Each
target's own options: diffdrive export TARGET --help.""",
}


# Each target's ``Reference`` fields: the motions its figures are taken at and the settings
# of the stack that reads them, each an option of its own.
TARGET_REFERENCE = {
    "ros2": ("distance", "speed", "rate", "window"),
    "robot_localization": ("speed",),
    "amcl": ("distance", "turn", "speed", "turn_rate", "scan_rate", "update_min_d", "update_min_a"),
    "wpilib": ("distance",),
    "c-header": (),
}
TARGET_HELP = {
    "ros2": "diff_drive_controller's parameters (YAML): the wheels and the covariance diagonals",
    "robot_localization": "robot_localization's process noise (YAML)",
    "amcl": "Nav2 AMCL's alpha1-alpha4, matched to its sampler (YAML)",
    "wpilib": "WPILib's DifferentialDrivePoseEstimator and feedforward (JSON)",
    "c-header": "the C core's robot, encoders and noise for the robot's firmware (a C header)",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive export TARGET``: one subcommand a target, each with its
    own options only."""
    ex = command(
        "export",
        "the calibrated robot, its noise model and its drive as ROS 2, robot_localization, "
        "AMCL or WPILib files, or a C header for the C core in the robot's firmware",
        [],
        run_export,
        EPILOGS["export"],
    )
    targets = ex.add_subparsers(dest="to", metavar="TARGET", required=True)
    for target in TARGETS:
        sub = targets.add_parser(
            target,
            help=TARGET_HELP[target],
            description=TARGET_HELP[target],
            parents=[parents.robot_required, parents.logs],
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        _common_options(sub)
        if target == "ros2":
            sub.add_argument("--nominal", type=Path, help="the nominal robot file ROS multiplies")
        if target == "wpilib":
            sub.add_argument(
                "--drive", type=Path, metavar="FILE", help="kS, kV, kA from diffdrive identify"
            )
        _reference_options(sub, TARGET_REFERENCE[target])


def _common_options(ex: argparse.ArgumentParser) -> None:
    """The noise model's options, the output and the runs: every target's."""
    ex.add_argument("runs", nargs="*", type=Path, help="runs with ground truth to identify on")
    ex.add_argument("-o", "--output", type=Path, help="default: the target's usual file name")
    ex.add_argument("--k", type=float, metavar="M", help="wheel noise, m (without runs)")
    ex.add_argument("--radius-sigma", type=float, metavar="REL", help="per-run radius error")
    ex.add_argument("--track-sigma", type=float, metavar="REL", help="per-run track error")
    ex.add_argument(
        "--reference-noise",
        type=float,
        nargs=2,
        metavar=("M", "RAD"),
        help="the runs' reference's own accuracy, m and rad (default: 0.001 0.00175, motion "
        "capture's, for tables; identified for a bag's --reference-topic)",
    )
    ex.add_argument(
        "--accept-inconsistent",
        action="store_true",
        help="write a model its runs refute (fewer than 80 %% inside its 95 %% ellipse, or k at "
        "0), saying so in the file",
    )
    ex.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")


def _reference_options(ex: argparse.ArgumentParser, names: tuple[str, ...]) -> None:
    """The target's ``Reference`` fields (``TARGET_REFERENCE``) as options, each with its
    default."""
    defaults = Reference()
    helps = {
        "distance": "straight, m (1)",
        "turn": "turn, rad (1)",
        "speed": "speed, m/s (0.5)",
        "turn_rate": "turn rate in place, rad/s (1)",
        "rate": "the controller's update rate, Hz (50): each update's velocity from one period",
        "window": "velocity_rolling_window_size, updates (10, the controller's default)",
        "scan_rate": "the laser's rate, Hz (10): when AMCL looks at the odometry",
        "update_min_d": "update_min_d, m (0.25, Nav2's default), written with the alphas",
        "update_min_a": "update_min_a, rad (0.2, Nav2's default), written with the alphas",
    }
    for name in names:
        kind = between(1, 1_000_000) if name == "window" else float
        flag = "--" + name.replace("_", "-")
        ex.add_argument(flag, type=kind, default=getattr(defaults, name), help=helps[name])
