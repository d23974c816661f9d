"""The ``diffdrive`` command line. With no arguments it runs the main job on a built-in example."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence

import numpy as np

from diffdrive import se2
from diffdrive.examples import example_robot
from diffdrive.model import DiffDrive
from diffdrive.types import WheelVelocities

# (label, left, right) wheel velocities in rad/s that show the characteristic motions.
_EXAMPLE_WHEELS = (
    ("straight", 10.0, 10.0),
    ("gentle left", 8.0, 10.0),
    ("spin in place", -5.0, 5.0),
    ("pivot on right wheel", 6.0, 0.0),
)


def _matrix(m: np.ndarray) -> str:
    return "\n".join("    [" + "  ".join(f"{v:+10.5f}" for v in row) + " ]" for row in m)


def kinematics_report(robot: DiffDrive) -> str:
    """A text report of ``robot``'s kinematics: matrices and a few characteristic motions."""
    lines = [
        f"robot: {robot}",
        "",
        "seed 003: [vx, omega] = K @ [wl, wr]",
        _matrix(robot.to_twist_matrix()),
        "Modern Robotics: [wl, wr] = H @ (omega, vx, vy)",
        _matrix(robot.h_matrix()),
        "and back: (omega, vx, vy) = F @ [wl, wr]",
        _matrix(robot.f_matrix()),
        "",
        f"{'motion':22} {'wl':>7} {'wr':>7} {'vx m/s':>8} {'omega':>8} {'radius m':>9}"
        f"   pose after 1 s (x, y, theta deg)",
    ]
    for label, left, right in _EXAMPLE_WHEELS:
        wheels = WheelVelocities(left, right)
        twist = robot.to_twist(wheels)
        pose = se2.exp(twist, 1.0)
        lines.append(
            f"{label:22} {left:7.2f} {right:7.2f} {twist.vx:8.4f} {twist.omega:8.4f} "
            f"{robot.turning_radius(wheels):9.4f}   "
            f"({pose.x:+.4f}, {pose.y:+.4f}, {math.degrees(pose.theta):+.2f})"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    parser = argparse.ArgumentParser(
        prog="diffdrive",
        description="Kinematics of differential-drive robots. With no arguments, the "
        "kinematics of a built-in example robot.",
    )
    parser.parse_args(argv)
    print(kinematics_report(example_robot()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
