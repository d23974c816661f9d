"""diffdrive: kinematics, odometry and simulation for differential-drive mobile robots.

Scalar value types and the robot models work on floats; ``diffdrive.batch`` holds the same
operations over arrays; ``estimation`` the estimators, ``control`` the commands, ``io`` every
file format. Conventions: docs/conventions.md. The heavier parts (``calibration``,
``evaluation``, ``io``, ``plot``, ...) load on first use as attributes, so ``import diffdrive``
stays light.
"""

from typing import TYPE_CHECKING

from diffdrive import integrate, se2
from diffdrive._lazy import attach
from diffdrive.angles import wrap_angle
from diffdrive.estimation.odometry import Odometry
from diffdrive.model import DiffDrive
from diffdrive.simulation import simulate
from diffdrive.skid_steer import SkidSteer
from diffdrive.trajectory import Trajectory
from diffdrive.types import Pose, Twist, WheelPositions, WheelVelocities

__version__ = "0.1.0"
"""The package's version (PEP 440), as its metadata gives it."""

# The control names load diffdrive.control's modules on first use; the submodules below are
# loaded when first reached as attributes (dd.calibration, dd.plot, ...).
__getattr__, __dir__ = attach(
    __name__,
    dict.fromkeys(
        ["Limiter", "Limits", "OpenLoopOdometry", "desaturate", "drive_commands"], "control"
    ),
    (
        "batch",
        "calibration",
        "control",
        "demo",
        "distributed",
        "dynamics",
        "encoders",
        "estimation",
        "evaluation",
        "io",
        "learn",
        "montecarlo",
        "plot",
        "sensors",
        "sensor_noise",
    ),
)

if TYPE_CHECKING:  # what the names are, for type checkers
    from diffdrive import batch, control, estimation
    from diffdrive.control import Limiter, Limits, OpenLoopOdometry, desaturate, drive_commands

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
