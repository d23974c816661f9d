"""``diffdrive calibrate``: wheel radii and track width from runs with ground truth."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from diffdrive.calibration import (
    CALIBRATION_METHODS,
    DEFAULT_EXTRA,
    EXTRAS,
    PARAMETERS,
    Increments,
    LeastSquares,
    MethodOptions,
    UMBmark,
    calibrate,
)
from diffdrive.cli.options import (
    LOG_COLUMNS,
    Command,
    Parents,
    at_least,
    read_log_of,
    refuse_assumed_robot,
    robot_from,
)
from diffdrive.demo import (
    EXAMPLE_DURATION,
    example_wheel_velocities,
)
from diffdrive.evaluation import run_errors, worst
from diffdrive.integrate import METHODS, Method
from diffdrive.io import TableError, write_robot
from diffdrive.model import DiffDrive, Robot
from diffdrive.simulation import dead_reckon, simulate


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


def _calibration_run(args, path: Path, ticks: float | None, robot: Robot):
    """``(increments, truth)`` of a run, and the ticks per revolution its format fixes; the
    increments refused where they cannot be ``robot``'s (``Run.checked_increments``)."""
    log = read_log_of(args, path)
    if log.truth is None:
        raise TableError(
            f"{path}: a run to calibrate on needs ground truth: columns x, y, theta, or a bag's "
            "--reference-topic"
        )
    increments, _ = log.checked_increments(robot, ticks, args.counter_bits)
    return (increments, log.truth), log.ticks_per_revolution


def run_calibrate(args: argparse.Namespace) -> int:
    nominal, ticks = robot_from(args)
    if args.runs:
        # The fit starts from the nominal robot, and --fix and UMBmark keep parts of it.
        refuse_assumed_robot(args, "calibrate fits the robot from its nominal geometry")
    if args.runs:
        read = [_calibration_run(args, path, ticks, nominal) for path in args.runs]
        runs = [run for run, _ in read]
        ticks = ticks or next((own for _, own in read if own is not None), None)
        what = f"{len(runs)} runs"
    else:
        runs, what = _example_runs(), "the built-in example runs"
    names = [str(path) for path in args.runs] or ["example", "mirrored example"]
    if args.cv not in ("loo", "none") and int(args.cv) > len(runs):
        raise ValueError(f"--cv {args.cv}: more folds than the {len(runs)} runs")
    fixed = tuple(args.fix or ())
    options = method_options(args)
    result = calibrate(
        nominal,
        runs,
        args.method,
        options,
        integration=args.integration,
        names=names,
        fixed=fixed,
        progress=not args.quiet and sys.stderr.isatty(),
    )
    settings = result.robot.settings()
    if ticks is not None:
        settings["ticks_per_revolution"] = ticks
    reports = []  # before the file is written: a fold that fails leaves nothing behind
    if not args.quiet:
        reports.append(calibration_report(nominal, result, runs, args.integration))
        if args.cv != "none" and args.method != "umbmark":
            reports.append(held_out_report(nominal, runs, names, args, fixed, options))
    write_robot(args.output, settings, f"calibrated by diffdrive ({args.method}) on {what}")
    for finding in result.implausible:  # said even with -q: the robot file may be wrong
        print(f"diffdrive calibrate: warning: {finding}", file=sys.stderr)
    if not args.quiet:
        print("\n".join(reports))
        print(f"calibrate: wrote the robot to {args.output}")
    return 0


def _folds(text: str) -> str:
    """``--cv``: ``loo``, ``none`` or a whole number of folds >= 2."""
    if text in ("loo", "none"):
        return text
    try:
        folds = int(text)
    except ValueError:
        folds = 0
    if folds < 2:
        raise argparse.ArgumentTypeError(f"must be loo, none or a number of folds >= 2, got {text}")
    return str(folds)


def method_options(args: argparse.Namespace) -> MethodOptions:
    """The options of ``--method`` from the flags. A flag of another method gives that
    method's options, which ``calibrate`` refuses by name (never ignored)."""
    extra = DEFAULT_EXTRA if args.extra is None else tuple(e for e in args.extra if e != "none")
    given: dict[str, tuple[bool, MethodOptions]] = {
        "increments": (args.window is not None, Increments(args.window or 1)),
        "umbmark": (args.square_side is not None, UMBmark(args.square_side)),
        "least_squares": (args.extra is not None, LeastSquares(extra=extra)),
    }
    own = "least_squares" if args.method == "minimax" else args.method
    foreign = [options for method, (flag, options) in given.items() if flag and method != own]
    return foreign[0] if foreign else given[own][1]


def held_out_report(nominal, runs, names, args, fixed, options: MethodOptions) -> str:
    """The in-sample and held-out errors side by side, and the parameters' spread."""
    from diffdrive.calibration.cross_validation import cross_validate

    if len(runs) < 2:
        return "held-out errors: none (one run: nothing to hold out; --cv none hides this)"
    scheme = "loo" if args.cv == "loo" else int(args.cv)
    cv = cross_validate(
        nominal,
        runs,
        args.method,
        scheme,
        options,
        integration=args.integration,
        names=names,
        fixed=fixed,
    )
    label = "leave one run out" if scheme == "loo" else f"{scheme} folds"
    lines = [f"{'errors over the runs':28} {'in-sample':>10} {'held-out':>10}   ({label})"]
    for name, unit in (
        ("max_position", "m"),
        ("final_position", "m"),
        ("max_heading", "deg"),
        ("final_heading", "deg"),
    ):
        held = "n/a" if cv.held_out is None else f"{getattr(cv.held_out, name):10.4f}"
        lines.append(f"{name + ', ' + unit:28} {getattr(cv.in_sample, name):10.4f} {held:>10}")
    if len(cv.fitted) > 1:
        spread = ", ".join(f"{p} +-{s:.2g}" for p, s in zip(PARAMETERS, cv.spread, strict=True))
        lines.append(f"parameters across the folds: {spread}")
    lines.extend(
        f"fold holding out {', '.join(names[k] for k in fold.held_out)} refused: {fold.refusal}"
        for fold in cv.refused
    )
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
    before = worst([run_errors(dead_reckon(nominal, i, t[0], integration), t) for i, t in runs])
    # What the written robot file gives: the reference's heading offset is not in it.
    after = worst([run_errors(dead_reckon(result.robot, i, t[0], integration), t) for i, t in runs])
    offsets = [robot.equivalent.axle_offset for robot in (nominal, result.robot)]
    if offsets[0] != offsets[1]:  # fitted (a SkidSteer's is -icr_x)
        lines.append(f"{'axle_offset':20} {offsets[0]:10.6f} {offsets[1]:11.6f}")
    if result.heading_offset:
        shift = np.array([0.0, 0.0, result.heading_offset])
        turned = worst(
            [
                run_errors(dead_reckon(result.robot, i, t[0] + shift, integration), t)
                for i, t in runs
            ]
        )
        lines.append(
            f"heading offset of the reference: {np.degrees(result.heading_offset):.3f} deg (not "
            f"in the robot file; with the reference's start turned by it the largest position "
            f"error is {turned.max_position:.4f} m)"
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


EPILOG = f"""examples:
  diffdrive calibrate                      the built-in example runs -> robot.toml
  diffdrive calibrate runs/*_run-*.csv --robot nominal.toml --method least_squares -o robot.toml

runs with ground truth, each as below (x, y, theta needed; OptiOdom files count 2796.8 a
turn unless told). Runs need the nominal robot (--robot, or the geometry flags: the fit starts
from it); the built-in robot is the default for the built-in runs only. Without ground truth:
diffdrive calibrate-gyro (the track from a gyro) and calibrate-driving (against GPS or poses).
{LOG_COLUMNS}"""


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive calibrate``."""
    cal = command(
        "calibrate",
        "fit wheel radii and track width to ground truth",
        [parents.robot, parents.logs],
        run_calibrate,
        EPILOG,
    )
    cal.add_argument("runs", nargs="*", type=Path, help="runs with ground truth; none: built-in")
    cal.add_argument("-o", "--output", type=Path, default=Path("robot.toml"))
    cal.add_argument("--method", choices=CALIBRATION_METHODS, default="least_squares")
    cal.add_argument(
        "--integration",
        choices=METHODS,
        default="exact",
        help="the odometry's method (default exact)",
    )
    cal.add_argument("--square-side", type=float, help="UMBmark's square, m")
    cal.add_argument(
        "--window",
        type=at_least(1),
        metavar="STEPS",
        help="the increments method: fit this many steps at a time (default 1; "
        "20 suits 20 Hz motion capture)",
    )
    cal.add_argument(
        "--cv",
        type=_folds,
        default="loo",
        metavar="loo|K|none",
        help="held-out errors by cross-validation over the runs: leave one run "
        "out (default), K folds, or none",
    )
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
        help="least_squares and minimax: fit these too: axle_offset (the tracked point is not "
        "on the axle; written to the robot file), heading_offset (the reference's heading is "
        "the robot's plus a constant; the reference's, not written, so the errors are "
        "reported without it as well); default none, as the library's",
    )
    cal.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
