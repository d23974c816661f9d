"""The covariances ROS messages carry, stated once for the bags ``diffdrive`` writes and the
parameters it exports (``diffdrive.export``).

- A planar robot estimates x, y and yaw (or their rates). ROS's messages hold a row-major 6x6
  over (x, y, z, roll, pitch, yaw); the axes a planar robot does not estimate get
  ``UNESTIMATED`` (1e6: unknown), as ROS's diff_drive_controller configures them.
- A covariance a fuser inverts must be positive definite. robot_localization and its peers
  invert the blocks they fuse, and a variance of exactly 0 (a differential drive's sideways
  velocity, an exact starting pose, a trajectory written as ground truth) makes them singular.
  ``floored`` raises every eigenvalue below ``FLOOR`` (1e-9, in the units squared: m^2, rad^2,
  (m/s)^2) to it along its own direction, and leaves the matrix unchanged where none is: a
  known-zero axis gets 1e-9, the rest of the matrix keeps its values.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FLOOR", "UNESTIMATED", "floored", "planar_6x6"]

UNESTIMATED = 1e6
"""The variance of an axis a planar robot does not estimate (z, roll, pitch, their rates):
unknown, as ROS's diff_drive_controller writes it."""
FLOOR = 1e-9
"""The least eigenvalue of a written covariance, in its units squared (m^2, rad^2, (m/s)^2)."""
_PLANAR = (0, 1, 5)  # x, y, yaw in the 6x6 (x, y, z, roll, pitch, yaw)


def floored(covariance: object) -> np.ndarray:
    """Symmetric covariances ``(..., n, n)`` with every eigenvalue below ``FLOOR`` raised to it,
    each along its eigenvector (the nearest such matrix in the Frobenius norm); unchanged where
    all are ``FLOOR`` or more."""
    matrix = np.asarray(covariance, dtype=float)
    if matrix.ndim < 2 or matrix.shape[-1] != matrix.shape[-2]:
        raise ValueError(f"covariances must be square (..., n, n), got shape {matrix.shape}")
    if not np.isfinite(matrix).all():
        raise ValueError("covariances must be finite")
    values, vectors = np.linalg.eigh(matrix)
    lift = np.maximum(FLOOR - values, 0.0)
    raised = np.einsum("...ik,...k,...jk->...ij", vectors, lift, vectors)
    changed = np.any(lift > 0.0, axis=-1, keepdims=True)[..., None]
    return np.where(changed, matrix + raised, matrix)


def planar_6x6(covariance: object) -> np.ndarray:
    """A 3x3 over (x, y, yaw) or their rates as ROS's row-major 6x6, 36 values: ``floored``,
    and the axes a planar robot does not estimate at ``UNESTIMATED``."""
    full = np.zeros((6, 6))
    full[2, 2] = full[3, 3] = full[4, 4] = UNESTIMATED
    full[np.ix_(_PLANAR, _PLANAR)] = floored(covariance)
    return full.ravel()
