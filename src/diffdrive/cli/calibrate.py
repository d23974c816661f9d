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
from diffdrive.cli.calibrate_driving import (
    add_driving_options,
    driving,
    refuse_misplaced,
    run_from_driving,
)
from diffdrive.cli.options import (
    LOG_COLUMNS,
    Command,
    Parents,
    add_imu_options,
    at_least,
    checked_ticks,
    gyro_of,
    read_log_of,
    refuse_assumed_robot,
    refuse_unused,
    robot_from,
    robot_settings,
)
from diffdrive.demo import (
    EXAMPLE_DURATION,
    example_wheel_velocities,
)
from diffdrive.evaluation import run_errors, worst
from diffdrive.integrate import METHODS, Method
from diffdrive.io import TableError, robot_from_settings, write_robot
from diffdrive.model import DiffDrive, Robot
from diffdrive.sensor_noise import GyroNoise
from diffdrive.simulation import dead_reckon, simulate

GYRO_ARW = 2e-3  # --gyro-arw's default, rad/s/sqrt(Hz)


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


def _track_from_gyro(args: argparse.Namespace, nominal, ticks) -> int:
    """--track-from-gyro: the track from one log's wheels and gyro, the radii the robot's."""
    from diffdrive.calibration import track_from_gyro

    if len(args.runs) != 1:
        raise TableError(f"--track-from-gyro takes one log, got {len(args.runs)}")
    if not isinstance(nominal, DiffDrive):
        raise TableError("--track-from-gyro calibrates a DiffDrive's track; the robot is not one")
    path = args.runs[0]
    log = read_log_of(args, path)
    gyro = gyro_of(args, log, path)
    if gyro is None:
        raise TableError(
            f"{path}: --track-from-gyro needs a gyro: --gyro-topic, or a gyro_z column"
        )
    inside = (log.times >= gyro.times[0]) & (log.times <= gyro.times[-1])
    if np.count_nonzero(inside) < 2:
        raise TableError(f"{path}: the gyro does not cover the log's times")
    log = log.rows(inside) if not inside.all() else log
    ticks = ticks or log.ticks_per_revolution
    increments, _ = log.checked_increments(nominal, ticks, args.counter_bits)
    found = track_from_gyro(
        nominal,
        log.times,
        increments,
        np.diff(gyro.angles(log.times)),
        wheel_noise=0.0 if args.k is None else args.k,
        ticks_per_revolution=ticks,
        gyro_noise=GyroNoise(
            angle_random_walk=GYRO_ARW if args.gyro_arw is None else args.gyro_arw
        ),
    )
    settings = nominal.with_geometry(
        nominal.left_wheel_radius, nominal.right_wheel_radius, found.track
    ).settings()
    if ticks is not None:
        settings["ticks_per_revolution"] = ticks
    write_robot(args.output, settings, f"track from the gyro of {path} by diffdrive")
    if not args.quiet:
        low, high = sorted(found.bracket)
        print(
            f"track from the gyro: {found.track:.5f} m (standard error {found.standard_error:.5f} "
            f"m; between {low:.5f} and {high:.5f} m whatever the noises; the plain ratio "
            f"{found.plain_ratio:.5f} m); gyro bias {found.bias:.5f} rad/s; radii kept "
            f"{nominal.left_wheel_radius:g} and {nominal.right_wheel_radius:g} m"
        )
        print(f"calibrate: wrote the robot to {args.output}")
    return 0


def _radii_robot(args: argparse.Namespace) -> tuple[Robot, float | None]:
    """--track-from-gyro's robot: its wheel radii given (a gyro sees the track over the
    radii), its track what is estimated, so not needed (1 m stands in until then)."""
    settings = robot_settings(args)
    ticks = checked_ticks(settings.pop("ticks_per_revolution", None))
    radii = {"wheel_radius", "left_wheel_radius", "right_wheel_radius"} & settings.keys()
    if not radii:
        raise ValueError(
            "--track-from-gyro keeps the wheel radii (a gyro sees the track over them): give "
            "--wheel-radius, or --left-wheel-radius and --right-wheel-radius, or --robot FILE"
        )
    if not {"track_width", "half_track", "icr_left", "icr_right"} & settings.keys():
        settings["track_width"] = 1.0
    return robot_from_settings(settings, f" (in {args.robot})" if args.robot else ""), ticks


def _refuse_options_of_the_other_kind(args: argparse.Namespace) -> None:
    """--track-from-gyro's options without it, or a fit's options with it; the driving
    calibration's likewise."""
    if args.track_from_gyro and driving(args):
        raise ValueError(
            "--track-from-gyro and --gps-topic/--pose-topic: one calibration at a time"
        )
    refuse_misplaced(args)
    if args.track_from_gyro or driving(args):
        fit = {
            "--method": args.method != "least_squares",
            "--integration": args.integration != "exact",
            "--square-side": args.square_side is not None,
            "--window": args.window is not None,
            "--cv": args.cv != "loo",
            "--fix": bool(args.fix),
            "--extra": args.extra is not None,
        }
        mode = "--track-from-gyro" if args.track_from_gyro else "a calibration from driving"
        refuse_unused(fit, f"not used by {mode}, which fits by its own model")
    else:
        gyro = {
            "--gyro-topic": args.gyro_topic is not None,
            "--imu-rpy": any(args.imu_rpy),
            "--gyro-arw": args.gyro_arw is not None,
            "--k": args.k is not None,
        }
        refuse_unused(gyro, "used only with --track-from-gyro, --gps-topic or --pose-topic")


def run_calibrate(args: argparse.Namespace) -> int:
    _refuse_options_of_the_other_kind(args)
    if args.track_from_gyro:
        return _track_from_gyro(args, *_radii_robot(args))
    nominal, ticks = robot_from(args)
    if driving(args):
        refuse_assumed_robot(args, "calibration from driving starts from the nominal geometry")
        return run_from_driving(args, nominal, ticks)
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


EPILOGS = {
    "calibrate": f"""examples:
  diffdrive calibrate                      the built-in example runs -> robot.toml
  diffdrive calibrate runs/*_run-*.csv --robot nominal.toml --method least_squares -o robot.toml
  diffdrive calibrate run.bag --left-joint L --right-joint R --wheel-radius 0.033 \
      --track-from-gyro --gyro-topic /imu -o robot.toml     the track from a gyro
  diffdrive calibrate husky.bag --wheel-topic /husky_velocity_controller/odom --robot husky.toml \
      --gps-topic /fix --gyro-topic /imu/data --imu-rpy 90 0 0 -o robot.toml
                                           from ordinary driving: wheels, antenna, clocks, gyro

runs with ground truth, each as below (x, y, theta needed; OptiOdom files count 2796.8 a
turn unless told). Runs need the nominal robot (--robot, or the geometry flags: the fit starts
from it); the built-in robot is the default for the built-in runs only, and --track-from-gyro
needs only the radii.
{LOG_COLUMNS}""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive calibrate``."""
    cal = command(
        "calibrate",
        "fit wheel radii and track width to ground truth",
        [parents.robot, parents.logs],
        run_calibrate,
        EPILOGS["calibrate"],
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
    gyro = cal.add_argument_group(
        "the track from a gyro, without ground truth (the radii: the robot's)"
    )
    gyro.add_argument(
        "--track-from-gyro",
        action="store_true",
        help="one log's wheels against its gyro (calibration.track_from_gyro)",
    )
    add_imu_options(gyro)
    gyro.add_argument(
        "--gyro-arw",
        type=float,
        metavar="RAD_S_SQRT_HZ",
        help=f"the gyro's angle random walk (default: {GYRO_ARW} for --track-from-gyro; "
        "identified from the drive when driving, and held where given)",
    )
    gyro.add_argument(
        "--k",
        type=float,
        metavar="M",
        help="the wheels' noise, m (default: 0, read exactly, for --track-from-gyro; "
        "identified from the drive when driving, and held where given)",
    )
    add_driving_options(cal)
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
