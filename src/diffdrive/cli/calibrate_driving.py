"""``diffdrive calibrate-driving BAG --gps-topic|--pose-topic``: the wheels, the sensor's mount and
clock, and the gyro's terms from ordinary driving, against a reference that is not ground
truth (``calibration.calibrate_to_reference``).

The reference is named as the odometry command names the same readings, ``--gps-topic``
(``sensor_msgs/NavSatFix``) or ``--pose-topic`` (``nav_msgs/Odometry`` or
``geometry_msgs/PoseWithCovarianceStamped``): ``--reference-topic`` already names ground truth
in every command, which this is not.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from diffdrive._validate import positive
from diffdrive.calibration.reference import (
    PARAMETERS,
    ReferenceCalibration,
    ReferenceSettings,
    UndeterminedError,
    calibrate_to_reference,
    estimable,
)
from diffdrive.cli.options import (
    Command,
    Parents,
    add_datum_option,
    add_gyro_noise_options,
    add_imu_options,
    gyro_of,
    read_log_of,
    refuse_assumed_robot,
    robot_from,
)
from diffdrive.io import TableError, is_bag, write_robot
from diffdrive.model import DiffDrive
from diffdrive.sensor_noise import DEFAULT, DEFAULT_GYRO, GyroNoise, WheelNoise

# Where the reference's noise is identified from when its readings report none (m; m and
# degrees): only a start, which the identification moves (it found the noise from figures 2-10
# times off in the tests).
START_GPS = 1.0
START_POSE = (0.05, 2.0)


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive calibrate-driving``."""
    parser = command(
        "calibrate-driving",
        "the wheels, the reference's mount and clock and the gyro's terms from ordinary "
        "driving, against GPS fixes or poses that are not ground truth",
        [parents.robot_required, parents.logs],
        run_calibrate_driving,
        EPILOG,
    )
    parser.add_argument("input", type=Path, help="a bag of the drive")
    parser.add_argument("-o", "--output", type=Path, default=Path("robot.toml"))
    group = parser.add_argument_group("the reference")
    sources = group.add_mutually_exclusive_group(required=True)
    sources.add_argument(
        "--gps-topic", metavar="TOPIC", help="sensor_msgs/NavSatFix: the antenna's positions"
    )
    sources.add_argument(
        "--pose-topic",
        metavar="TOPIC",
        help="nav_msgs/Odometry or PoseWithCovarianceStamped: a camera's or localiser's poses",
    )
    group.add_argument(
        "--reference-noise",
        type=float,
        nargs="+",
        metavar="SIGMA",
        help="the reference's noise, held: M for GPS; M RAD for poses (default: identified "
        "from the log, starting at the median of the covariances the readings report)",
    )
    group.add_argument(
        "--hold",
        nargs="+",
        choices=PARAMETERS,
        metavar="PARAMETER",
        help="leave these out of the calibration, at the robot's geometry or 0 (one the log "
        f"does not determine, say): {', '.join(PARAMETERS)}",
    )
    add_datum_option(group)
    gyro = parser.add_argument_group("a gyro (a bag's IMU topic), and the noises held")
    add_imu_options(gyro)
    add_gyro_noise_options(gyro, "held where given; else identified from the drive")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")


EPILOG = """examples:
  diffdrive calibrate-driving husky.bag --wheel-topic /husky_velocity_controller/odom \\
      --robot husky.toml --gps-topic /fix --gyro-topic /imu/data --imu-mount 1.5707963 0 0 \\
      -o robot.toml

From ordinary driving: the wheels' scale and track, the antenna's or camera's lever arm and
clock offset, the gyro's scale and bias, each noise identified from the drive unless held. A
parameter the drive does not determine is refused by name (--hold leaves it out)."""


def run_calibrate_driving(args: argparse.Namespace) -> int:
    """Calibrate one bag's wheels (and gyro) against its GPS or pose topic; write the robot,
    print the report. A parameter the drive did not determine is refused, nothing written."""
    refuse_assumed_robot(args, "calibration from driving starts from the nominal geometry")
    for value in args.reference_noise or ():  # before any file is read
        positive("--reference-noise (m, and rad for poses)", value)
    nominal, ticks = robot_from(args)
    path = args.input
    if not is_bag(path):
        raise TableError(f"{path}: calibrate-driving calibrates a bag's drive; this is no bag")
    if not isinstance(nominal.equivalent, DiffDrive):
        raise TableError("calibration from driving fits a DiffDrive's geometry")
    log = read_log_of(args, path)
    ticks = ticks or log.ticks_per_revolution
    # Refused where they cannot be this robot's wheels (a counter's width, a unit).
    increments, speed = log.checked_increments(nominal, ticks, args.counter_bits)
    stamps, readings, sigma, said = _reference(args, path)
    gyro = gyro_of(args, log, path)
    lines = [speed, said]
    gyro_noise, gyro_held = None, False
    if gyro is not None:
        gyro_noise, gyro_held, line = _gyro_noise(args, log, gyro, ticks)
        lines.append(line)
    wheels, line = _wheel_noise(args)
    lines.append(line)
    # What no flag gave is found from the log: no noise figure set by hand.
    held = {"wheels": args.k is not None, "gyro": gyro_held}
    held["reference"] = held["reference_heading"] = args.reference_noise is not None
    held["gyro"] |= gyro is None  # what the log has not, nothing to find
    held["reference_heading"] |= args.gps_topic is not None
    unknown = tuple(name for name, given in held.items() if not given)
    estimate = _estimate(args, gyro is not None)
    try:
        found = calibrate_to_reference(
            nominal.equivalent,
            log.times,
            increments,
            stamps,
            readings,
            sigma=sigma,
            gyro=gyro,
            gyro_noise=gyro_noise,
            wheel_noise=wheels,
            settings=ReferenceSettings(estimate=estimate, identify_noise=unknown),
        )
    except UndeterminedError as refused:
        raise UndeterminedError(
            f"{refused} (here: --hold {' '.join(refused.parameters)})", refused.parameters
        ) from None
    settings = found.robot.settings()
    if ticks is not None:
        settings["ticks_per_revolution"] = ticks
    source = args.gps_topic or args.pose_topic
    noise, said = _noise_found(found, wheels if args.k is not None else None, gyro_noise, gyro_held)
    comment = [f"calibrated by diffdrive from driving: {path} against {source}", *found.report]
    write_robot(args.output, settings, "\n".join([*comment, said]), noise)
    if not args.quiet:
        for line in lines:
            print(line)
        print(
            f"calibration on {found.readings} readings (chi-square per degree of freedom "
            f"{found.chi2:.2f}{', standard errors inflated by it' if found.chi2 > 1 else ''}):"
        )
        for line in found.report:
            print(f"  {line}")
        print(said)
        print(f"calibrate: wrote the robot to {args.output}")
    return 0


def _estimate(args: argparse.Namespace, with_gyro: bool) -> tuple[str, ...]:
    """What the reference and gyro can calibrate, less --hold's; ``ValueError`` for a held
    parameter they do not calibrate anyway."""
    allowed = estimable(args.pose_topic is not None, with_gyro)
    held = args.hold or []
    stray = [name for name in held if name not in allowed]
    if stray:
        raise ValueError(
            f"--hold {' '.join(stray)}: not calibrated against this reference"
            f"{' and gyro' if with_gyro else ''} (it calibrates {', '.join(allowed)})"
        )
    return tuple(name for name in allowed if name not in held)


def _reference(args, path):
    """The reference's stamps, readings (positions or poses), noise and a line on it."""
    from diffdrive.io import ros

    given = args.reference_noise
    if args.gps_topic:
        fixes = ros.read_navsatfix(path, args.gps_topic, args.datum)
        if given is not None:
            if len(given) != 1:
                raise ValueError(f"--reference-noise for GPS is one noise (m), got {given}")
            sigma, source = given[0], "given by --reference-noise, held"
        else:
            reported = fixes.variance[np.isfinite(fixes.variance) & (fixes.variance > 0)]
            if len(reported) < len(fixes.variance) / 2:
                sigma = START_GPS
                source = "most fixes report no covariance: identified from the drive, from this"
            else:
                sigma = float(np.sqrt(np.median(reported)))
                source = "the median the fixes report: the start of its identification"
        said = f"{len(fixes.times)} fixes from {args.gps_topic}, noise {sigma:.3g} m ({source})"
        return fixes.times, fixes.positions, sigma, said
    topic = ros.read_odometry(path, args.pose_topic)
    if given is not None:
        if len(given) != 2:
            raise ValueError(f"--reference-noise for poses is M RAD, got {given}")
        sigma3 = (given[0], given[0], given[1])
        source = "given by --reference-noise, held"
    else:
        diagonal = topic.covariances[:, [0, 1, 2], [0, 1, 2]]
        usable = np.all(np.isfinite(diagonal) & (diagonal > 0), axis=1)
        if np.count_nonzero(usable) < len(diagonal) / 2:
            sigma3 = (START_POSE[0], START_POSE[0], math.radians(START_POSE[1]))
            source = "most poses report no covariance: identified from the drive, from this"
        else:
            spread = np.sqrt(np.median(diagonal[usable], axis=0))
            sigma3 = (float(spread[0]), float(spread[1]), float(spread[2]))
            source = "the median the poses report: the start of its identification"
    said = (
        f"{len(topic.times)} poses from {args.pose_topic}, noise {sigma3[0]:.3g} m and "
        f"{math.degrees(sigma3[2]):.3g} deg ({source})"
    )
    return topic.times, topic.poses, sigma3, said


def _gyro_noise(args, log, gyro, ticks) -> tuple[GyroNoise, bool, str]:
    """The gyro's noise, whether it is held, and a line saying which: --gyro-arw, or the
    log's standing stretch's (held: driving, the gyro's noise shows only beside the wheels'
    slip, which it would take up); else identified from the drive, starting at the library's
    default."""
    from diffdrive.estimation.standing import warm_up

    if args.gyro_arw is not None:
        arw = args.gyro_arw
        line = f"gyro noise {arw:g} rad/s/sqrt(Hz) (--gyro-arw, held)"
        return GyroNoise(angle_random_walk=arw), True, line
    inside = (log.times >= gyro.times[0]) & (log.times <= gyro.times[-1])
    part = log.rows(inside)
    standing = warm_up(part.times, part.increments(ticks, args.counter_bits), gyro)
    if standing is None:
        noise = GyroNoise(angle_random_walk=DEFAULT_GYRO.angle_random_walk)
        return (
            noise,
            False,
            (
                f"gyro noise: identified from the drive, as the log never stands still, starting "
                f"at the library's default {noise.angle_random_walk:.3g} rad/s/sqrt(Hz)"
            ),
        )
    noise = standing.noise
    return (
        noise,
        True,
        (
            f"gyro noise {noise.angle_random_walk:.3g} rad/s/sqrt(Hz), identified from the log's "
            f"standing stretch ({standing.longest:.3g} s), held"
        ),
    )


def _noise_found(
    found: ReferenceCalibration,
    wheels: WheelNoise | None,
    gyro: GyroNoise | None,
    gyro_held: bool,
) -> tuple[dict[str, WheelNoise | GyroNoise], str]:
    """The noise a robot file keeps for the other commands (``odometry``, ``estimate``,
    ``export``), and a line saying what: each term the drive determined, or held at a figure
    given (``wheels`` from --k; the ``gyro`` from --gyro-arw or a standing stretch). A term
    the drive left undetermined is not written: its figure only weighed the fit. The gyro's
    bias prior is the library's default, not this log's: a bias is each run's own."""
    identified = {} if found.noise is None else dict(found.noise.values)
    for name in () if found.noise is None else found.noise.undetermined:
        identified.pop(name)
    noise: dict[str, WheelNoise | GyroNoise] = {}
    if "wheels" in identified:
        noise["wheel_noise"] = WheelNoise.symmetric(identified["wheels"])
    elif wheels is not None:
        noise["wheel_noise"] = wheels
    if gyro is not None and ("gyro" in identified or gyro_held):
        noise["gyro_noise"] = GyroNoise(
            angle_random_walk=identified.get("gyro", gyro.angle_random_walk),
            rate_random_walk=gyro.rate_random_walk or DEFAULT_GYRO.rate_random_walk,
            initial_bias_sigma=DEFAULT_GYRO.initial_bias_sigma,
            bias_instability=gyro.bias_instability,
            correlation_time=gyro.correlation_time,
        )
    kept = ", ".join(f"[noise.{name}]" for name in noise) or "no noise"
    return noise, f"kept for odometry, estimate and export: {kept}"


def _wheel_noise(args) -> tuple[WheelNoise, str]:
    """--k (held), else the start of its identification, and a line saying which."""
    if args.k is not None:
        return WheelNoise.symmetric(args.k), f"wheel noise {args.k:g} m (--k, held)"
    return DEFAULT, (
        f"wheel noise: identified from the drive, starting at the library's default "
        f"{DEFAULT.left:g} m"
    )
