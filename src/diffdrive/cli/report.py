"""The main job's reports: the example robot's kinematics and its simulated history."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from diffdrive import se2
from diffdrive.cli.options import example_trajectory
from diffdrive.demo import (
    EXAMPLE_DURATION,
    example_wheel_velocities,
)
from diffdrive.evaluation import run_errors
from diffdrive.integrate import METHODS
from diffdrive.io import atomic_output, write_trajectory
from diffdrive.model import DiffDrive, Robot
from diffdrive.simulation import simulate
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


def simulation_report(robot: DiffDrive, steps: int = 2000) -> str:
    """Simulate the built-in driving history with each method; compare the final poses."""
    lines = [
        f"simulated {EXAMPLE_DURATION:g} s of the built-in driving history in {steps} steps:",
        f"{'method':8} {'x m':>9} {'y m':>9} {'theta deg':>10} {'distance m':>11}",
    ]
    for method in METHODS:
        trajectory = simulate(
            robot,
            example_wheel_velocities,
            dt=EXAMPLE_DURATION / steps,
            duration=EXAMPLE_DURATION,
            method=method,
        )
        x, y, theta = trajectory.final_pose
        lines.append(
            f"{method:8} {x:9.4f} {y:9.4f} {math.degrees(theta):10.2f} "
            f"{trajectory.distance[-1]:11.4f}"
        )
    return "\n".join(lines)


def error_summary(poses: np.ndarray, truth: np.ndarray) -> str:
    """Maximum and final position (m) and heading (deg) errors of ``poses`` against ``truth``."""
    errors = run_errors(poses, truth)
    return (
        f"against the ground truth: position error max {errors.max_position:.4f} m, "
        f"final {errors.final_position:.4f} m; heading error max {errors.max_heading:.3f} deg, "
        f"final {errors.final_heading:.3f} deg"
    )


def example_outputs(robot: Robot, folder: Path) -> str:
    """Write the built-in trajectory (CSV, and a picture if matplotlib is there) to ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    trajectory = example_trajectory(robot)
    table = folder / "trajectory.csv"
    write_trajectory(table, trajectory.times, trajectory.poses)
    written = [str(table)]
    try:
        from diffdrive.plot import plot_trajectory

        picture = folder / "trajectory.png"
        with atomic_output(picture) as temporary:
            plot_trajectory(robot, trajectory.times, trajectory.poses, temporary)
        written.append(str(picture))
    except ImportError:
        written.append("(no picture: pip install 'diffdrive[plot]')")
    return "outputs: " + ", ".join(written)
