"""Signatures of the C extension ``diffdrive.backends._odometry`` (``_odometry.c``,
``_estimator.c``, ``_partition.c``), for type checkers and editors. Its two cores are held to
their pure-Python twins by the table tests, so the twins' signatures are theirs. Use
``diffdrive.Odometry`` and ``diffdrive.PoseEstimator``, which subclass them."""

from typing import Any

from diffdrive.estimation._estimator_python import EstimatorCore as EstimatorCore
from diffdrive.estimation._odometry_python import OdometryCore as OdometryCore

def _partition(
    along: Any,  # (n, 2) float64, C-contiguous
    weight: Any,  # the same
    penalty: float,
    edge_cost: float,
    longest: int,
    start: Any,  # (n + 1,) float64, filled
) -> None:
    """``diffdrive.estimation.episodes.partition``'s dynamic programme."""
