"""The first-order lag: a wheel's velocity approaching a held target with a time constant.

Over ``dt`` s toward a held target ``u`` from ``w``, a lag of time constant ``tau`` ends at
``u + (w - u) a`` with ``a = exp(-dt / tau)``, and its mean over the period is
``u + (w - u) (tau / dt) (1 - a)``. A time constant of 0 is no lag: the target at once.
Every model of the drive (``DriveModel``, ``follow``, the ``Predictive`` tracker's picture of
commands in flight) steps through these two functions.
"""

from __future__ import annotations

import numpy as np

__all__ = ["decay", "first_order"]


def decay(dt: object, time_constant: float) -> np.ndarray:
    """What remains of the distance to a held target after ``dt`` s (s, any shape): ``exp(-dt
    / time_constant)``, 0 where the time constant is 0."""
    pieces = np.asarray(dt, dtype=float)
    if time_constant == 0.0:
        return np.zeros_like(pieces)
    return np.exp(-pieces / time_constant)


def first_order(
    state: np.ndarray, target: np.ndarray, dt: float, time_constant: float
) -> tuple[np.ndarray, np.ndarray]:
    """The lag after ``dt`` s from ``state`` toward a held ``target`` (the same shapes): the
    value at the end of the period, and its mean over the period (what the robot moves with).
    Exact for a held target."""
    if time_constant == 0.0:
        return target, target
    remaining = decay(dt, time_constant)
    mean = target + (state - target) * time_constant / dt * (1.0 - remaining)
    return target + (state - target) * remaining, mean
