"""diffdrive: kinematics, odometry and simulation for differential-drive mobile robots.

Scalar value types and the robot models work on floats; ``diffdrive.batch`` holds the same
operations over arrays; ``estimation`` the estimators, ``control`` the commands, ``io`` every
file format. Conventions: docs/conventions.md. The heavier parts (``calibration``,
``evaluation``, ``io``, ``plot``, ...) load on first use as attributes, so ``import diffdrive``
stays light.
"""

import importlib as _importlib

from diffdrive import batch, control, estimation, integrate, se2
from diffdrive.angles import wrap_angle
from diffdrive.control import Limiter, Limits, OpenLoopOdometry, desaturate, drive_commands
from diffdrive.estimation import Odometry
from diffdrive.model import DiffDrive
from diffdrive.simulation import simulate
from diffdrive.skid_steer import SkidSteer
from diffdrive.trajectory import Trajectory
from diffdrive.types import Pose, Twist, WheelPositions, WheelVelocities

__version__ = "0.1.0"

# Submodules loaded when first reached as attributes (dd.calibration, dd.plot, ...).
_LAZY = (
    "calibration",
    "demo",
    "distributed",
    "dynamics",
    "encoders",
    "evaluation",
    "io",
    "learn",
    "montecarlo",
    "noise",
    "plot",
    "sensors",
)


def __getattr__(name: str):
    if name in _LAZY:
        return _importlib.import_module(f"diffdrive.{name}")
    raise AttributeError(f"module 'diffdrive' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The public names and the submodules that load on first use, each once."""
    return sorted({*__all__, *_LAZY})


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
    "control",
    "desaturate",
    "drive_commands",
    "estimation",
    "integrate",
    "se2",
    "simulate",
    "wrap_angle",
]
