"""The one place that chooses the cores of ``Odometry`` and ``PoseEstimator``: the C
extension (``diffdrive.backends._odometry``, the C core of ``c/`` bound for Python) where pip
built it, else their pure-Python twins, imported only then (``import diffdrive`` stays light);
``DIFFDRIVE_PURE_PYTHON=1`` asks for the twins anyway. ``COMPILED`` says which."""

from __future__ import annotations

import os

__all__ = ["COMPILED", "EstimatorCore", "OdometryCore"]

try:
    if os.environ.get("DIFFDRIVE_PURE_PYTHON") == "1":
        raise ImportError("DIFFDRIVE_PURE_PYTHON=1")
    from diffdrive.backends._odometry import EstimatorCore, OdometryCore

    COMPILED: bool = True
    """Whether ``Odometry`` and ``PoseEstimator`` run the C core (True) or the Python twins."""
except ImportError:
    from diffdrive.estimation._estimator_python import EstimatorCore
    from diffdrive.estimation._odometry_python import OdometryCore

    COMPILED = False
