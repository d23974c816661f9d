"""Calibration: the geometry that makes odometry match a reference.

- ``offline``: ``calibrate`` on whole runs with ground truth (UMBmark, robust least squares,
  minimax, increments), and its refusals (``CalibrationError``);
- ``cross_validation``: ``cross_validate``, held-out scores of a calibration;
- ``online``: ``OnlineCalibrator``, recursive least squares while the robot drives;
- ``gyro_track``: ``track_from_gyro``, the track width from a gyro, without a pose reference;
- ``reference``: ``calibrate_to_reference``, the wheels, a sensor's mount and clock and a
  gyro's terms from ordinary driving against a reference that is not ground truth (a
  camera's poses, GPS positions), on ``_reference_model``'s residuals, with the noise found
  from the log by ``_reference_noise``;
- ``noise``: the odometry's noise model fitted to runs against a reference (``identify``,
  ``covariances``), and the gyro's noise from its Allan deviation (``identify_gyro``, from
  ``estimation.standing``).
"""

from diffdrive.calibration import noise
from diffdrive.calibration.cross_validation import CrossValidation, Fold, cross_validate
from diffdrive.calibration.gyro_track import GyroTrack, track_from_gyro
from diffdrive.calibration.offline import (
    CALIBRATION_METHODS,
    DEFAULT_EXTRA,
    EXTRAS,
    PARAMETERS,
    CalibrationError,
    CalibrationMethod,
    CalibrationResult,
    Increments,
    LeastSquares,
    MethodOptions,
    UMBmark,
    calibrate,
    checked_runs,
    run_names,
)
from diffdrive.calibration.online import OnlineCalibrator
from diffdrive.calibration.reference import (
    ReferenceCalibration,
    ReferenceSettings,
    UndeterminedError,
    calibrate_to_reference,
    estimable,
)

__all__ = [
    "CALIBRATION_METHODS",
    "DEFAULT_EXTRA",
    "EXTRAS",
    "PARAMETERS",
    "CalibrationError",
    "CalibrationMethod",
    "CalibrationResult",
    "CrossValidation",
    "Fold",
    "GyroTrack",
    "Increments",
    "LeastSquares",
    "MethodOptions",
    "OnlineCalibrator",
    "ReferenceCalibration",
    "ReferenceSettings",
    "UMBmark",
    "UndeterminedError",
    "calibrate",
    "calibrate_to_reference",
    "checked_runs",
    "cross_validate",
    "estimable",
    "noise",
    "run_names",
    "track_from_gyro",
]
