"""``diffdrive fk`` and ``diffdrive ik``: the kinematics of one set of numbers."""

from __future__ import annotations

import argparse

from diffdrive.cli.options import print_values, robot_from
from diffdrive.types import Twist, WheelVelocities


def run_fk(args: argparse.Namespace) -> int:
    robot, _ = robot_from(args)
    wheels = WheelVelocities(args.left, args.right)
    twist = robot.to_twist(wheels)
    values = {
        "vx": twist.vx, "vy": twist.vy, "omega": twist.omega,
        "turning_radius": robot.turning_radius(wheels),
    }  # fmt: skip
    units = {"vx": "m/s", "vy": "m/s", "omega": "rad/s", "turning_radius": "m"}
    print_values(values, args.json, units)
    return 0


def run_ik(args: argparse.Namespace) -> int:
    robot, _ = robot_from(args)
    wheels = robot.to_wheel_velocities(Twist(args.vx, 0.0, args.omega))
    values = {"left": wheels.left, "right": wheels.right}
    print_values(values, args.json, {"left": "rad/s", "right": "rad/s"})
    return 0
