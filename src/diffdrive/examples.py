"""Built-in example robots, so that every entry point has something to run on."""

from __future__ import annotations

from diffdrive.model import DiffDrive


def example_robot() -> DiffDrive:
    """A small indoor robot: the OptiOdom platform's nominal geometry (84 mm wheels, 0.2 m)."""
    return DiffDrive(wheel_radius=0.042, track_width=0.200)
