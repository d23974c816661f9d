"""``diffdrive calibrate-gyro``: the track from one log's wheels against its gyro
(``calibration.track_from_gyro``), the wheel radii the robot's."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from diffdrive.cli.options import (
    LOG_COLUMNS,
    Command,
    Parents,
    add_gyro_noise_options,
    add_imu_options,
    checked_ticks,
    gyro_of,
    read_log_of,
    robot_files,
    robot_settings,
    within_gyro,
)
from diffdrive.io import TableError, robot_from_settings, write_robot
from diffdrive.model import DiffDrive, Robot
from diffdrive.sensor_noise import GyroNoise

GYRO_ARW = 2e-3  # --gyro-arw's default, rad/s/sqrt(Hz)


def run_calibrate_gyro(args: argparse.Namespace) -> int:
    """The track from one log's wheels and gyro, the radii the robot's."""
    from diffdrive.calibration import track_from_gyro

    nominal, ticks = _radii_robot(args)
    if not isinstance(nominal, DiffDrive):
        raise TableError("calibrate-gyro calibrates a DiffDrive's track; the robot is not one")
    path = args.input
    log = read_log_of(args, path)
    gyro = gyro_of(args, log, path)
    if gyro is None:
        raise TableError(f"{path}: calibrate-gyro needs a gyro: --gyro-topic, or a gyro_z column")
    log, _ = within_gyro(log, gyro, "")
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
    """The robot: its wheel radii given (a gyro sees the track over the
    radii), its track what is estimated, so not needed (1 m stands in until then)."""
    settings = robot_settings(args)
    ticks = checked_ticks(settings.pop("ticks_per_revolution", None))
    radii = {"wheel_radius", "left_wheel_radius", "right_wheel_radius"} & settings.keys()
    if not radii:
        raise ValueError(
            "calibrate-gyro keeps the wheel radii (a gyro sees the track over them): give "
            "--wheel-radius, or --robot left_wheel_radius=M,right_wheel_radius=M, or --robot FILE"
        )
    if not {"track_width", "half_track", "icr_left", "icr_right"} & settings.keys():
        settings["track_width"] = 1.0
    return robot_from_settings(settings, robot_files(args)), ticks


EPILOG = f"""examples:
  diffdrive calibrate-gyro run.bag --joints L R --wheel-radius 0.033 --gyro-topic /imu \\
      -o robot.toml

One log's wheels against its gyro, no ground truth: the track whose turns match the gyro's,
errors in both weighed; the radii are the robot's (a gyro sees the track over them).
{LOG_COLUMNS}"""


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive calibrate-gyro``."""
    cal = command(
        "calibrate-gyro",
        "the track width from one log's wheels against its gyro, without ground truth",
        [parents.robot, parents.logs],
        run_calibrate_gyro,
        EPILOG,
    )
    cal.add_argument("input", type=Path, help="a log with a gyro (a bag, or a gyro_z column)")
    cal.add_argument("-o", "--output", type=Path, default=Path("robot.toml"))
    add_imu_options(cal)
    add_gyro_noise_options(cal, f"defaults: {GYRO_ARW} for the gyro, 0 m for the wheels")
    cal.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
