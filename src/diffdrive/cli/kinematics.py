"""``diffdrive fk`` and ``diffdrive ik``: the kinematics of one set of numbers."""

from __future__ import annotations

import argparse

from diffdrive.cli.options import (
    NEGATIVE_NUMBER,
    Command,
    Parents,
    print_values,
    robot_from,
)
from diffdrive.types import Twist, WheelVelocities


def run_fk(args: argparse.Namespace) -> int:
    robot, _ = robot_from(args)
    wheels = WheelVelocities(args.left, args.right)
    twist = robot.to_twist(wheels)
    values = {
        "vx": twist.vx,
        "vy": twist.vy,
        "omega": twist.omega,
        "turning_radius": robot.turning_radius(wheels),
    }
    units = {"vx": "m/s", "vy": "m/s", "omega": "rad/s", "turning_radius": "m"}
    print_values(values, args.json, units)
    return 0


def run_ik(args: argparse.Namespace) -> int:
    robot, _ = robot_from(args)
    wheels = robot.to_wheel_velocities(Twist(args.vx, 0.0, args.omega))
    values = {"left": wheels.left, "right": wheels.right}
    print_values(values, args.json, {"left": "rad/s", "right": "rad/s"})
    return 0


EPILOGS = {
    "fk": """example:
  diffdrive fk 8 10 --json      wheel velocities (rad/s) -> body twist
  diffdrive fk 1 -1e-3          (negative numbers are numbers, not options)""",
    "ik": """example:
  diffdrive ik 0.5 1.0          forward speed (m/s) and turn rate (rad/s) -> wheel velocities""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive fk and ik``."""
    fk = command("fk", "wheel velocities to the body twist", [parents.robot], run_fk, EPILOGS["fk"])
    fk._negative_number_matcher = NEGATIVE_NUMBER  # -1e-3 is a number, not an option
    fk.add_argument("left", type=float, help="rad/s")
    fk.add_argument("right", type=float, help="rad/s")
    fk.add_argument("--json", action="store_true")
    ik = command("ik", "a body twist to wheel velocities", [parents.robot], run_ik, EPILOGS["ik"])
    ik._negative_number_matcher = NEGATIVE_NUMBER
    ik.add_argument("vx", type=float, help="forward speed, m/s")
    ik.add_argument("omega", type=float, help="turn rate, rad/s")
    ik.add_argument("--json", action="store_true")
