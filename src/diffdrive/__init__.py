"""diffdrive: kinematics, odometry and simulation for differential-drive mobile robots.

Scalar value types and the robot model work on floats; ``diffdrive.batch`` holds the same
operations over arrays; ``diffdrive.io`` every file format. Conventions: docs/conventions.md.
The heavier parts (``calibration``, ``evaluation``, ``io``, ``plot``, ...) load on first use
as attributes, so ``import diffdrive`` stays light.
"""

import importlib

from diffdrive import batch, integrate, se2
from diffdrive.angles import wrap_angle
from diffdrive.commands import desaturate
from diffdrive.limiter import Limiter, Limits
from diffdrive.model import DiffDrive
from diffdrive.odometry import Odometry
from diffdrive.open_loop import OpenLoopOdometry, drive_commands
from diffdrive.simulation import simulate
from diffdrive.skid_steer import SkidSteer
from diffdrive.trajectory import Trajectory
from diffdrive.types import Pose, Twist, WheelPositions, WheelVelocities

__version__ = "0.1.0"

# Submodules loaded when first reached as attributes (dd.calibration, dd.plot, ...).
_LAZY = (
    "calibration",
    "distributed",
    "encoders",
    "evaluation",
    "examples",
    "gyro",
    "io",
    "learn",
    "montecarlo",
    "plot",
)


def __getattr__(name: str):
    if name in _LAZY:
        return importlib.import_module(f"diffdrive.{name}")
    raise AttributeError(f"module 'diffdrive' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])


__all__ = [
    "DiffDrive",
    "Limiter",
    "Limits",
    "Odometry",
    "OpenLoopOdometry",
    "Pose",
    "SkidSteer",
    "Trajectory",
    "Twist",
    "WheelPositions",
    "WheelVelocities",
    "__version__",
    "batch",
    "desaturate",
    "drive_commands",
    "integrate",
    "se2",
    "simulate",
    "wrap_angle",
]
