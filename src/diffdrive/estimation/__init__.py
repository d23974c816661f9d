"""Estimation: where the robot is, and how sure.

- ``odometry``: ``Odometry``, streaming dead reckoning from wheel encoders with covariance (its
  core in C, ``diffdrive.backends``);
- ``settings``: ``EstimatorSettings``, everything the pose estimator is set up with, one value
  of small checked parts (``Prior``, ``FixOffset``, ``Gate``, ``SlipTest``, ``Window``,
  ``Encoders``, ``SensorCalibration``, ``WholeLog``);
- ``fusion``: ``PoseEstimator``, one extended Kalman filter for wheels, a gyro and absolute
  measurements that arrive late (``measurements``: ``Measurement``), on ``filter``'s step;
- ``smoother``: ``estimate_trajectory``, a whole log forward and a Rauch-Tung-Striebel smoother
  back, with the slip ``episodes`` a whole log shows;
- ``imu``: ``Gyro`` streams and an IMU's mounting;
- ``gyro``: ``gyro_odometry`` (the estimator over a log with a gyro, for slip
  studies) and ``GyroOdometry`` (the estimator behind a per-interval ``update``);
- ``standing``: the gyro's noise and bias from where the wheels stand still
  (``identify_standing``, what ``estimate_trajectory`` takes when given none; ``warm_up`` for a
  streaming ``PoseEstimator``; ``identify_gyro`` and ``allan_deviation`` for one stretch);
- ``wheel_turns``: the wheels' noise from their turn against the gyro's
  (``identify_wheel_turns``, what ``estimate_trajectory`` takes when given none);
- ``fixes``: what position fixes are worth, from the fixes themselves (``identify_fixes``: their
  white noise, their offset's wander, the wheels' distance scale and the start in their frame;
  what ``estimate_trajectory`` takes with ``WholeLog(fixes="identified")``).

Every estimator runs the robot model's equivalent drive through ``diffdrive._step`` and keeps
the pose ``(x, y, theta)`` first in its state and covariance.
"""

from typing import TYPE_CHECKING

from diffdrive._lazy import attach

# Each name loads its module on first use: Odometry alone needs none of the filter's.
_NAMES = {
    **dict.fromkeys(["HEADINGS", "GyroNoise", "PoseEstimator"], "fusion"),
    **dict.fromkeys(["GyroOdometry", "GyroTrajectory", "gyro_odometry"], "gyro"),
    **dict.fromkeys(["Gyro", "rotation_from_rpy"], "imu"),
    **dict.fromkeys(["Measurement", "chi2_quantile", "measurements_of"], "measurements"),
    **dict.fromkeys(
        [
            "COMPILED",
            "UPDATE_KINDS",
            "Odometry",
            "RefusedUpdateError",
            "odometry_of_run",
        ],
        "odometry",
    ),
    **dict.fromkeys(["Estimate", "estimate_trajectory"], "smoother"),
    **dict.fromkeys(["StandingFit", "identify_standing", "warm_up"], "standing"),
    **dict.fromkeys(["FixFit", "identify_fixes"], "fixes"),
    **dict.fromkeys(["WheelTurnFit", "identify_wheel_turns"], "wheel_turns"),
    **dict.fromkeys(
        [
            "Encoders",
            "EstimatorSettings",
            "FixOffset",
            "Gate",
            "Prior",
            "SensorCalibration",
            "SlipTest",
            "WholeLog",
            "Window",
        ],
        "settings",
    ),
}
__getattr__, __dir__ = attach(__name__, _NAMES)
__all__ = [
    "COMPILED",
    "HEADINGS",
    "UPDATE_KINDS",
    "Encoders",
    "Estimate",
    "EstimatorSettings",
    "FixFit",
    "FixOffset",
    "Gate",
    "Gyro",
    "GyroNoise",
    "GyroOdometry",
    "GyroTrajectory",
    "Measurement",
    "Odometry",
    "PoseEstimator",
    "Prior",
    "RefusedUpdateError",
    "SensorCalibration",
    "SlipTest",
    "StandingFit",
    "WheelTurnFit",
    "WholeLog",
    "Window",
    "chi2_quantile",
    "estimate_trajectory",
    "gyro_odometry",
    "identify_fixes",
    "identify_standing",
    "identify_wheel_turns",
    "measurements_of",
    "odometry_of_run",
    "rotation_from_rpy",
    "warm_up",
]

if TYPE_CHECKING:  # what the names are, for type checkers
    from diffdrive.estimation.fixes import FixFit, identify_fixes
    from diffdrive.estimation.fusion import HEADINGS, GyroNoise, PoseEstimator
    from diffdrive.estimation.gyro import GyroOdometry, GyroTrajectory, gyro_odometry
    from diffdrive.estimation.imu import Gyro, rotation_from_rpy
    from diffdrive.estimation.measurements import Measurement, chi2_quantile, measurements_of
    from diffdrive.estimation.odometry import (
        COMPILED,
        UPDATE_KINDS,
        Odometry,
        RefusedUpdateError,
        odometry_of_run,
    )
    from diffdrive.estimation.settings import (
        Encoders,
        EstimatorSettings,
        FixOffset,
        Gate,
        Prior,
        SensorCalibration,
        SlipTest,
        WholeLog,
        Window,
    )
    from diffdrive.estimation.smoother import Estimate, estimate_trajectory
    from diffdrive.estimation.standing import StandingFit, identify_standing, warm_up
    from diffdrive.estimation.wheel_turns import WheelTurnFit, identify_wheel_turns
