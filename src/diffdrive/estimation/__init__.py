"""Estimation: where the robot is, and how sure.

- ``odometry``: ``Odometry``, streaming dead reckoning from wheel encoders with covariance (its
  core in C, ``diffdrive.backends``);
- ``gyro``: ``Gyro``, ``GyroOdometry`` and ``gyro_odometry``: the heading from the wheels, the
  gyro or both, and slip detection.

Every estimator runs the robot model's equivalent drive through ``diffdrive._step`` and keeps
the pose ``(x, y, theta)`` first in its state and covariance.
"""

from diffdrive.estimation.gyro import (
    HEADINGS,
    Gyro,
    GyroNoise,
    GyroOdometry,
    GyroTrajectory,
    gyro_odometry,
    rotation_from_rpy,
)
from diffdrive.estimation.odometry import (
    COMPILED,
    UPDATE_KINDS,
    Odometry,
    PythonOdometry,
    RefusedUpdateError,
    odometry_of_run,
    offset_jacobian,
)

__all__ = [
    "COMPILED",
    "HEADINGS",
    "UPDATE_KINDS",
    "Gyro",
    "GyroNoise",
    "GyroOdometry",
    "GyroTrajectory",
    "Odometry",
    "PythonOdometry",
    "RefusedUpdateError",
    "gyro_odometry",
    "odometry_of_run",
    "offset_jacobian",
    "rotation_from_rpy",
]
