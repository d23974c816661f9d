"""diffdrive: kinematics, odometry and simulation for differential-drive mobile robots.

Scalar value types and the robot model work on floats; ``diffdrive.batch`` holds the same
operations over arrays. Conventions: docs/conventions.md.
"""

from diffdrive import batch, integrate, se2
from diffdrive.angles import wrap_angle
from diffdrive.model import DiffDrive
from diffdrive.odometry import Odometry
from diffdrive.simulation import simulate
from diffdrive.trajectory import Trajectory
from diffdrive.types import Pose, Twist, WheelPositions, WheelVelocities

__version__ = "0.1.0"

__all__ = [
    "DiffDrive",
    "Odometry",
    "Pose",
    "Trajectory",
    "Twist",
    "WheelPositions",
    "WheelVelocities",
    "__version__",
    "batch",
    "integrate",
    "se2",
    "simulate",
    "wrap_angle",
]
