"""diffdrive: kinematics, odometry and simulation for differential-drive mobile robots.

Scalar value types and the robot model work on floats; ``diffdrive.batch`` holds the same
operations over arrays. Conventions: docs/conventions.md.
"""

from diffdrive import batch, integrate, se2
from diffdrive.angles import wrap_angle
from diffdrive.commands import desaturate
from diffdrive.limiter import Limiter, Limits
from diffdrive.model import DiffDrive
from diffdrive.odometry import Odometry
from diffdrive.open_loop import OpenLoopOdometry, drive_commands
from diffdrive.simulation import simulate
from diffdrive.trajectory import Trajectory
from diffdrive.types import Pose, Twist, WheelPositions, WheelVelocities

__version__ = "0.1.0"

__all__ = [
    "DiffDrive",
    "Limiter",
    "Limits",
    "Odometry",
    "OpenLoopOdometry",
    "Pose",
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
