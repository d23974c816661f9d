"""``diffdrive odometry`` with absolute measurements or a smoother: the log through
``estimate_trajectory``.

Measurements come from a bag's pose topic (``PoseWithCovarianceStamped`` or ``Odometry``: a
camera, a localiser), its GPS topic (``NavSatFix``, in the local east-north frame at its first
fix) or a table (``t, x, y`` and, for poses, ``theta``; optional ``sigma_x, sigma_y,
sigma_theta``). Their covariance is the message's or the table's, else ``--pose-sigma`` or
``--gps-sigma``; a message covariance that is not positive definite needs those.

Frames. The measurements are in their own frame (a map, or east-north); the log's wheels only
know where they started. The start pose in the measurements' frame is the one that best fits
the dead-reckoned path at the measurements' stamps onto their positions (least squares, SE(2)),
its uncertainty the fit's residual; the command prints it. Measurements outside the log's time
span are left out, and said so.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from diffdrive.backends.settings import OFFSET
from diffdrive.cli.options import estimate_columns, refuse_unused, wheel_noise, write_output
from diffdrive.cli.report import error_summary
from diffdrive.estimation import Measurement, estimate_trajectory
from diffdrive.estimation.fixes import IDENTIFIED_GATE, LEAST_FIXES
from diffdrive.estimation.measurements import start_in_frame
from diffdrive.estimation.settings import EstimatorSettings, Gate, Prior, WholeLog
from diffdrive.io import Run, TableError, is_bag
from diffdrive.model import Robot
from diffdrive.sensor_noise import WheelNoise

GATE_HELP = (
    "chi-square gate: refuse a measurement outside this probability (default "
    f"{Gate().probability:g}; with identified fixes 1 - {1 - IDENTIFIED_GATE:.0e}, a fix past it "
    "inflated, not refused)"
)


def wants_fusion(args) -> bool:
    """Whether the command runs the estimator with measurements or a smoother."""
    return bool(args.pose_topic or args.gps_topic or args.measurements or args.smooth) or bool(
        args.turn_scale_sigma
    )


def refuse_idle_options(args) -> None:
    """The measurement options, given without any measurements."""
    refuse_idle_datum(args)
    if args.pose_topic or args.gps_topic or args.measurements:
        return
    refuse_unused(
        {
            "--pose-sigma": args.pose_sigma is not None,
            "--gps-sigma": args.gps_sigma is not None,
            "--lever-arm": args.lever_arm is not None,
            "--gate": args.gate is not None,
            "--fixes": args.fixes is not None,
        },
        "used only with absolute measurements (--pose-topic, --gps-topic or --measurements)",
    )


def refuse_idle_datum(args) -> None:
    """--datum without GPS fixes to place."""
    refuse_unused(
        {"--datum": args.datum is not None and not args.gps_topic}, "used only with --gps-topic"
    )


def measurements_of_args(args) -> tuple[list[Measurement], list[str], int]:
    """The measurements the options name, a line about each source, and how many GPS fixes
    came without a covariance (taken for their noise to be identified from them)."""
    made: list[Measurement] = []
    notes: list[str] = []
    uncovered = 0
    if args.pose_topic or args.gps_topic:
        if args.input is None or not is_bag(args.input):
            raise TableError("--pose-topic and --gps-topic need a bag as the log")
        from diffdrive.io import ros

        if args.pose_topic:
            topic = ros.read_odometry(args.input, args.pose_topic)
            rows = zip(topic.times, topic.poses, topic.covariances, strict=True)
            made += [_made("pose", t, p, c, args, f"{args.pose_topic}") for t, p, c in rows]
            notes.append(f"{len(topic.times)} poses from {args.pose_topic}")
        if args.gps_topic:
            fixes = ros.read_navsatfix(args.input, args.gps_topic, args.datum)
            known = np.isfinite(fixes.variance) & (fixes.variance > 0.0)
            if args.fixes != "given" and args.gps_sigma is None and not known.all():
                # Their noise is identified from them: the covariance is never read.
                uncovered = int(np.sum(~known))
                notes.append(
                    f"{uncovered} of the {len(known)} fixes from {args.gps_topic} have "
                    "no covariance: their noise is identified from the fixes themselves"
                )
                variance = np.where(known, fixes.variance, 1.0)
            else:
                variance = fixes.variance
            rows = zip(fixes.times, fixes.positions, variance, strict=True)
            made += [
                _made("position", t, p, np.eye(2) * v, args, args.gps_topic) for t, p, v in rows
            ]
            lat, lon, alt = fixes.datum
            where = (
                "the first fix (--datum LAT LON ALT fixes the frame)"
                if args.datum is None
                else "the datum"
            )
            notes.append(
                f"{len(fixes.times)} GPS fixes from {args.gps_topic}, in east-north (x east, y "
                f"north, theta counter-clockwise from east) at {where}: {lat:.8f}, {lon:.8f}, "
                f"{alt:.3f} m"
            )
    if args.measurements:
        made += _table_measurements(args)
        notes.append(f"measurements from {args.measurements}")
    return made, notes, uncovered


def _made(kind, t, value, covariance, args, where) -> Measurement:
    """One measurement; its covariance, else the sigma option, else a named refusal."""
    size = 3 if kind == "pose" else 2
    given = np.asarray(covariance, dtype=float)
    usable = np.all(np.isfinite(given)) and np.all(np.linalg.eigvalsh(given) > 0.0)
    if not usable:
        sigma = args.pose_sigma if kind == "pose" else args.gps_sigma
        if sigma is None:
            option = "--pose-sigma SX SY STHETA" if kind == "pose" else "--gps-sigma M"
            raise TableError(
                f"{where}: the {kind} at t = {float(t):g} s has no positive definite "
                f"covariance: give {option}"
            )
        given = np.asarray(sigma, dtype=float) if kind == "pose" else np.full(2, sigma)
    value = np.asarray(value, dtype=float)[:size]
    try:
        return Measurement.make(kind, t, value, given, args.lever_arm)
    except ValueError as exc:
        raise TableError(f"{where}: {exc}") from None


def _table_measurements(args) -> list[Measurement]:
    from diffdrive.io.tables import read_header, read_table

    path = args.measurements
    header = read_header(path)
    kind = "pose" if "theta" in header else "position"
    names = ("sigma_x", "sigma_y", "sigma_theta") if kind == "pose" else ("sigma_x", "sigma_y")
    optional = ("theta", *names) if kind == "pose" else names
    table = read_table(path, ["t", "x", "y"], optional, time_unit=args.time_unit)
    columns = ["x", "y", "theta"] if kind == "pose" else ["x", "y"]
    values = np.column_stack([table[name] for name in columns])
    given = [name for name in names if name in table]
    if given and len(given) < len(names):
        # Some standard deviations and not others: none may be guessed for the rest.
        raise TableError(
            f"{path}:1: a {kind} table gives all of {', '.join(names)} or none; the header "
            f"has only {', '.join(given)}"
        )
    made = []
    for k, t in enumerate(table["t"]):
        where = f"{path}:{table.lines[k]}"
        if not given:
            covariance = np.full((len(columns), len(columns)), np.nan)
            made.append(_made(kind, t, values[k], covariance, args, where))
            continue
        sigmas = [table[name][k] for name in names]
        try:  # Measurement.make refuses a standard deviation that is not > 0
            made.append(Measurement.make(kind, t, values[k], sigmas, args.lever_arm))
        except ValueError as exc:
            raise TableError(f"{where}: {exc}") from None
    return made


def estimator_settings(
    args: argparse.Namespace, noise: WheelNoise, fixes: str, with_gyro: bool
) -> EstimatorSettings:
    """The one ``EstimatorSettings`` the options ask for: the wheels' ``noise``
    (``options.wheel_noise``), what the ``fixes`` are worth, and each option given (the
    heading from the wheels where there is no gyro); the library's default for every part not
    given. A ``--gate`` beside identified fixes keeps their inflated outliers."""
    whole: dict = {"fixes": fixes}
    if args.slip_test is not None:
        whole["slip_episodes"] = args.slip_test == "episodes"
    parts: dict = {"wheel_noise": noise, "method": args.method, "whole_log": WholeLog(**whole)}
    if args.heading is not None or not with_gyro:
        parts["heading"] = args.heading or "wheels"
    if args.gyro_bias is not None:
        parts["bias"] = args.gyro_bias
    if getattr(args, "turn_scale_sigma", None):
        parts["turn_scale"] = Prior(sigma=args.turn_scale_sigma)
    if getattr(args, "gate", None) is not None:
        parts["gate"] = Gate(args.gate, "inflate" if fixes == "identified" else "refuse")
    return EstimatorSettings(**parts)


def run_fusion(args, robot: Robot, log: Run, increments, gyro, note: str, commanded=None) -> int:
    """The estimator over the log with the measurements, filtered or smoothed; the poses,
    covariance and the filter's own columns written. ``commanded``: the wheel velocities
    commanded over each interval ``(T-1, 2)`` rad/s, for the slip flags, or None."""
    measurements, notes, uncovered = measurements_of_args(args)
    inside = [m for m in measurements if log.times[0] <= m.t <= log.times[-1]]
    if measurements and not inside:
        # Not one inside: the two clocks differ (Unix time against a log from 0, units), and
        # an estimate without them would pass for a fused one.
        stamps = [m.t for m in measurements]
        raise TableError(
            f"none of the {len(measurements)} measurements lies inside the log's time span "
            f"[{log.times[0]:g}, {log.times[-1]:g}] s (theirs: [{min(stamps):g}, "
            f"{max(stamps):g}] s): are they on the same clock, in the same unit?"
        )
    if len(inside) < len(measurements):
        notes.append(f"{len(measurements) - len(inside)} measurements outside the log left out")
    if args.heading not in (None, "wheels") and gyro is None:
        raise ValueError(f"--heading {args.heading} needs a gyro: --gyro-topic, or a gyro_z column")
    noise, assumed = wheel_noise(args, robot, log, increments)
    note += assumed
    # A receiver's fixes (--gps-topic) report its whole error: identified by default, given
    # enough of them; a covariance the user wrote (a table's sigmas) is taken as given.
    positions = sum(m.kind == "position" for m in inside)
    default = "identified" if args.gps_topic and positions >= LEAST_FIXES else "given"
    fixes = args.fixes or default
    if fixes == "given" and uncovered:  # too few to identify their noise from
        raise TableError(
            f"{uncovered} of the fixes from {args.gps_topic} have no covariance, and {positions} "
            f"fixes are too few to identify their noise from (at least {LEAST_FIXES}): give "
            "--gps-sigma M"
        )
    settings = estimator_settings(args, noise, fixes, gyro is not None)
    heading = settings.heading
    common = dict(gyro=gyro, commanded=commanded)
    start: np.ndarray | None = log.start_pose()
    covariance = None
    if fixes == "identified":  # the fixes' fit places the start
        start = None
    elif inside:
        dead = estimate_trajectory(
            robot, log.times, increments, settings=settings, smooth=False, **common
        )
        start, covariance, fit = start_in_frame(log.times, dead.poses, inside)
        notes.append(
            f"start pose in the measurements' frame: ({start[0]:.3f} m, {start[1]:.3f} m, "
            f"{start[2]:.4f} rad), fitted to them (RMS {fit:.3f} m)"
        )
    result = estimate_trajectory(
        robot,
        log.times,
        increments,
        measurements=inside,
        initial_pose=start,
        initial_covariance=covariance,
        settings=settings,
        smooth=args.smooth,
        **common,
    )
    twists, twist_covariances = result.twists, result.twist_covariances
    columns = estimate_columns(args, result.covariances, twists, twist_covariances, True)
    if heading != "wheels":
        columns.update(slip=result.slip.astype(float), gyro_bias=result.states[:, 3])
    if settings.turn_scale.estimated:
        columns["turn_scale"] = result.states[:, 4]
    if fixes == "identified":  # where the fixes are: the body's track plus their offset
        columns["fix_offset_x"] = result.states[:, OFFSET]
        columns["fix_offset_y"] = result.states[:, OFFSET + 1]
    which = "smoothed" if args.smooth else "filtered"
    what = f"{which} estimate of {log.source} ({heading} heading)"
    write_output(
        args, log.times, result.poses, what, columns, result.covariances, twists, twist_covariances
    )
    if result.rejected and result.rejected > 0.5 * max(1, len(inside)):
        print(
            f"diffdrive odometry: warning: the gate refused {result.rejected} of {len(inside)} "
            "measurements: the wheels' noise (--k-left, --k-right) or the measurements' "
            "covariance is likely too small, or the frames disagree",
            file=sys.stderr,
        )
    if not args.quiet:
        print(note)
        for line in (*result.settings, *notes):
            print(line)
        gate = result.used.gating.probability if result.used else math.nan
        print(
            f"measurements: {len(inside) - result.rejected} taken, {result.rejected} refused by "
            f"the gate ({gate:.10g}), fixes {fixes}"
        )
        if settings.turn_scale.estimated:
            print(f"turn scale at the end: {result.states[-1, 4]:.4f}")
        if fixes == "identified":
            x, y = result.states[-1, OFFSET : OFFSET + 2]
            print(
                f"the fixes' offset at the end: ({x:.3f}, {y:.3f}) m (columns fix_offset_x, "
                "fix_offset_y): the poses follow the wheels between fixes, the fixes' wander "
                "is in the offset"
            )
        if log.truth is not None:
            print(error_summary(result.poses, log.truth))
    return 0
