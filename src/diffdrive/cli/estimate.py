"""``diffdrive estimate``: the pose estimator over a log (``estimate_trajectory``), its wheels
and gyro with absolute measurements, filtered or smoothed.

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
import dataclasses
import math
import sys
from pathlib import Path
from typing import Literal

import numpy as np

from diffdrive.backends.settings import OFFSET
from diffdrive.cli.options import (
    LOG_COLUMNS,
    Command,
    Parents,
    add_datum_option,
    add_imu_options,
    add_pairs_option,
    add_wheel_noise_option,
    estimate_columns,
    gyro_of,
    key_values,
    noise_changes,
    output_options,
    read_log_of,
    refuse_unused,
    reported_twists,
    robot_from,
    robot_note,
    wheel_commands,
    wheel_noise,
    within_gyro,
    write_output,
)
from diffdrive.cli.report import error_summary
from diffdrive.estimation import Measurement, estimate_trajectory
from diffdrive.estimation.fixes import LEAST_FIXES
from diffdrive.estimation.measurements import start_in_frame
from diffdrive.estimation.settings import PARTS, EstimatorSettings, WholeLog
from diffdrive.io import RIM_SPEED_LIMIT, TableError, is_bag
from diffdrive.io.robots import load_toml, toml_value
from diffdrive.sensor_noise import WheelNoise


def _refuse_idle_options(args) -> None:
    """The measurement options, given without any measurements."""
    refuse_idle_datum(args)
    if args.pose_topic or args.gps_topic or args.measurements:
        return
    refuse_unused(
        {
            "--pose-sigma": args.pose_sigma is not None,
            "--gps-sigma": args.gps_sigma is not None,
            "--lever-arm": args.lever_arm is not None,
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
    noise: WheelNoise | None,
    fixes: Literal["given", "identified"],
    with_gyro: bool,
    changes: dict[str, object],
) -> EstimatorSettings:
    """The one ``EstimatorSettings`` a command asks for: the wheels' ``noise``
    (``options.wheel_noise``), what the ``fixes`` are worth, then its ``changes`` by name
    (``EstimatorSettings.changed``: ``--settings``, or ``odometry``'s gyro flags); the heading
    from the wheels where there is no gyro, and the library's default for every part not
    given. A gate given beside identified fixes keeps their inflated outliers."""
    if "whole_log.fixes" in changes:
        raise ValueError("--settings whole_log.fixes: give --fixes given|identified")
    base = EstimatorSettings(wheel_noise=noise, whole_log=WholeLog(fixes=fixes))
    if not with_gyro:
        base = base.replace(heading="wheels")
    wanted = dict(changes)
    if "gate.probability" in wanted and "gate.outliers" not in wanted:
        wanted["gate.outliers"] = "inflate" if fixes == "identified" else "refuse"
    return base.changed(wanted)


def settings_changes(entries: list[str] | None) -> dict[str, object]:
    """``--settings``: each a settings file (TOML: a part's fields in a table named after it)
    or ``KEY=VALUE`` pairs (``gate.probability=0.99,heading=gyro``), the later winning; the
    values as TOML reads them, a bare word as text. Checked by ``EstimatorSettings.changed``."""
    changes: dict[str, object] = {}
    for entry in entries or ():
        if "=" in entry:
            given = key_values("--settings", entry, _SETTING_KEYS)
            changes.update({key: toml_value(text) for key, text in given.items()})
            continue
        path = Path(entry)
        for key, value in load_toml(path, "an estimator settings file").items():
            inner = value.items() if isinstance(value, dict) else [("", value)]
            changes.update({f"{key}.{name}" if name else key: item for name, item in inner})
        try:
            EstimatorSettings().changed(changes)
        except (ValueError, TypeError) as exc:
            raise TableError(f"{path}: {exc}") from None
    return changes


# Every name --settings may set: the parts and their fields, checked again by changed().
_SETTING_KEYS = frozenset(
    [item.name for item in dataclasses.fields(EstimatorSettings)]
    + [
        f"{part.name}.{inner.name}"
        for part in dataclasses.fields(EstimatorSettings)
        if part.name in PARTS
        for inner in dataclasses.fields(PARTS[part.name][0])
    ]
)


def run_estimate(args: argparse.Namespace) -> int:
    """The estimator over the log with the measurements, filtered or smoothed; the poses,
    covariance, twist and the filter's own columns written."""
    _refuse_idle_options(args)
    changes = settings_changes(args.settings)
    robot, ticks = robot_from(args)
    log = read_log_of(args)
    ticks = ticks or log.ticks_per_revolution
    _, note = log.checked_increments(robot, ticks, args.counter_bits, args.max_wheel_speed)
    note += robot_note(args)
    gyro = gyro_of(args, log)
    commanded = None
    if gyro is None:
        refuse_unused(
            {"--command-topic": args.command_topic is not None},
            "used only with a gyro (--gyro-topic, or a gyro_z column)",
        )
    else:
        log, note = within_gyro(log, gyro, note)
        commanded = wheel_commands(args, robot, log)
    increments = log.increments(ticks, args.counter_bits)
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
    if changes.get("heading", "wheels") != "wheels" and gyro is None:
        raise ValueError(
            f"--settings heading={changes['heading']} needs a gyro: --gyro-topic, or a gyro_z "
            "column"
        )
    noise, assumed = wheel_noise(args, robot, log, increments, gyro=gyro is not None)
    from_files, said = noise_changes(args)
    note += assumed + said
    changes = {**from_files, **changes}  # --settings over the robot files' noise
    # A receiver's fixes (--gps-topic) report its whole error: identified by default, given
    # enough of them; a covariance the user wrote (a table's sigmas) is taken as given.
    positions = sum(m.kind == "position" for m in inside)
    default: Literal["given", "identified"] = (
        "identified" if args.gps_topic and positions >= LEAST_FIXES else "given"
    )
    fixes: Literal["given", "identified"] = args.fixes or default
    if fixes == "given" and uncovered:  # too few to identify their noise from
        raise TableError(
            f"{uncovered} of the fixes from {args.gps_topic} have no covariance, and {positions} "
            f"fixes are too few to identify their noise from (at least {LEAST_FIXES}): give "
            "--gps-sigma M"
        )
    settings = estimator_settings(noise, fixes, gyro is not None, changes)
    if settings.turn_scale.estimated and gyro is None and not inside:
        raise ValueError(
            "--settings turn_scale: the turn scale learns from a gyro or absolute measurements, "
            "and this run has neither"
        )
    if not inside:
        refuse_unused(
            {"--settings gate": any(key.startswith("gate.") for key in changes)},
            "used only with absolute measurements (--pose-topic, --gps-topic or --measurements)",
        )
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
    twists, reported = reported_twists(log, result.twists, omega=heading == "wheels")
    note += reported
    twist_covariances = result.twist_covariances
    columns = estimate_columns(result.covariances, twists, twist_covariances, twist=True)
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
            f"diffdrive estimate: warning: the gate refused {result.rejected} of {len(inside)} "
            "measurements: the wheels' noise (--k) or the measurements' "
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


EPILOG = f"""examples:
  diffdrive estimate run.mcap --joints left_wheel_joint right_wheel_joint \\
      --gyro-topic /imu/data --pose-topic /pose --smooth -o estimate.csv
  diffdrive estimate husky.bag --wheel-topic /husky_velocity_controller/odom \\
      --gyro-topic /imu/data --gps-topic /navsat/fix --robot husky.toml -o estimate.mcap
  diffdrive estimate log.csv --measurements fixes.csv --settings gate.probability=0.99

{LOG_COLUMNS}
Written: the poses with the covariance and the twist (columns vx, vy, omega and theirs), with
a gyro its bias and slip flags, with identified fixes their offset.

--settings sets any part of the estimator (diffdrive.estimation.EstimatorSettings) by name:
a part (heading=gyro, bias=0.002, method=rk2) or a part's field (gate.probability=0.99,
gate.outliers=inflate, turn_scale.sigma=0.05, fix_offset.rate=0.01, slip.threshold=20,
whole_log.slip_episodes=false), or a TOML file of them, a part's fields in a table of its
name ([gate] probability = 0.99). What is not given keeps the library's default; --fixes says
what the fixes are worth (identified from {LEAST_FIXES} or more --gps-topic fixes by default; a gate
beside identified fixes inflates its outliers)."""


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive estimate``."""
    est = command(
        "estimate",
        "the pose estimator over a log: wheels, a gyro and absolute measurements, filtered "
        "or smoothed",
        [parents.robot, parents.logs, output_options("estimate.csv")],
        run_estimate,
        EPILOG,
    )
    est.add_argument("input", nargs="?", type=Path, help="the log; none: built-in")
    est.add_argument(
        "--max-wheel-speed",
        type=float,
        metavar="RAD_S",
        help="refuse a row whose wheel turns faster (rad/s); default: a rim speed of "
        f"{RIM_SPEED_LIMIT:g} m/s",
    )
    add_wheel_noise_option(est, "default 1e-4, or identified from ground truth; said when used")
    gyro = est.add_argument_group("a gyro: a bag's IMU topic or a gyro_z column (rad/s)")
    add_imu_options(gyro)
    gyro.add_argument(
        "--command-topic",
        metavar="TOPIC",
        help="geometry_msgs/Twist commands of the bag, to flag wheels that spin beyond them "
        "(or left_command, right_command columns)",
    )
    fused = est.add_argument_group("absolute measurements")
    fused.add_argument(
        "--pose-topic", metavar="TOPIC", help="PoseWithCovarianceStamped or Odometry topic"
    )
    fused.add_argument("--gps-topic", metavar="TOPIC", help="NavSatFix topic of the bag")
    add_datum_option(fused)
    fused.add_argument(
        "--measurements",
        type=Path,
        metavar="FILE",
        help="a table t, x, y[, theta][, sigma_x, sigma_y[, sigma_theta]]: poses with theta, "
        "else positions",
    )
    fused.add_argument(
        "--pose-sigma",
        type=float,
        nargs=3,
        metavar=("SX", "SY", "STHETA"),
        help="standard deviations (m, m, rad) of poses that come without a covariance",
    )
    fused.add_argument(
        "--gps-sigma",
        type=float,
        metavar="M",
        help="standard deviation (m) of positions that come without a covariance",
    )
    fused.add_argument(
        "--lever-arm",
        type=float,
        nargs=2,
        metavar=("X", "Y"),
        help="where the pose or GPS sensor sits in the body frame, m (default 0 0)",
    )
    fused.add_argument(
        "--fixes",
        choices=("identified", "given"),
        help="what position fixes are worth: identified from the fixes themselves (white noise, "
        "the offset's wander, the wheels' distance scale, the start; the default for "
        f"{LEAST_FIXES} or more --gps-topic fixes) or given (their covariance, white; the "
        "default for a table's)",
    )
    est.add_argument(
        "--smooth",
        action="store_true",
        help="the whole log forward and back (Rauch-Tung-Striebel): every pose uses every "
        "measurement",
    )
    add_pairs_option(
        est, "--settings", "the estimator's settings by name, or a TOML file of them (below)", True
    )
