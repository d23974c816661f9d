"""Absolute measurements for ``PoseEstimator``: a pose ``(x, y, theta)`` (camera, AprilTag,
localiser), a position ``(x, y)`` (GPS in a local east-north frame) or a heading ``(theta,)``
(a compass, or a gyro's integrated angle whose noise is white in the angle), each with its own
time stamp, covariance and lever arm, checked once where they are made.

A covariance is given as a ``k x k`` matrix (symmetric positive definite), or as ``k``
standard deviations (m, m, rad), or one standard deviation for every axis of a position.
The lever arm ``(x, y)`` (m, body frame) is where the sensor sits on the robot: a position
sensor measures that point, a pose sensor that point and the body's heading.

``start_in_frame`` places a dead-reckoned path in the measurements' frame: the start an
estimator takes when the log gives none there.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from diffdrive import batch
from diffdrive._stats import chi2_quantile
from diffdrive._validate import finite, floats
from diffdrive.evaluation import align, interpolate

__all__ = [
    "MEASUREMENT_KINDS",
    "Measurement",
    "chi2_quantile",
    "measurements_of",
    "start_in_frame",
]

MeasurementKind = Literal["pose", "position", "heading"]
MEASUREMENT_KINDS: tuple[MeasurementKind, ...] = ("pose", "position", "heading")
_SIZE = {"pose": 3, "position": 2, "heading": 1}


def _floats(given: object, what: str, where: str) -> np.ndarray:
    """``given`` as a float array; ``ValueError`` or ``TypeError`` naming it otherwise."""
    return floats(f"{where}: {what}", given)


# A Cholesky pivot below this share of its diagonal entry marks a singular covariance.
SINGULAR = 1e-12


def _covariance(given: object, size: int, where: str) -> np.ndarray:
    matrix = _floats(given, "covariance", where)
    if matrix.ndim == 0 and size < 3:  # one standard deviation for every axis
        matrix = np.full(size, float(matrix))
    if matrix.shape == (size,):
        with np.errstate(over="ignore", under="ignore", invalid="ignore"):
            variances = matrix * matrix
        if not (np.all(np.isfinite(variances)) and np.all(matrix > 0.0) and np.all(variances > 0)):
            raise ValueError(
                f"{where}: standard deviations must be > 0 and square to a finite float > 0, "
                f"got {matrix}"
            )
        return np.diag(variances)
    if matrix.shape != (size, size):
        raise ValueError(
            f"{where}: covariance must be {size}x{size} or {size} standard deviations, "
            f"got shape {matrix.shape}"
        )
    if not np.all(np.isfinite(matrix)):
        raise ValueError(f"{where}: covariance must be finite")
    if not np.allclose(matrix, matrix.T, rtol=1e-9, atol=0.0):
        raise ValueError(f"{where}: covariance is not symmetric")
    try:
        factor = np.linalg.cholesky(matrix)
    except np.linalg.LinAlgError:
        raise ValueError(f"{where}: covariance is not positive definite") from None
    # A pivot at rounding's size is a singular matrix that rounding made pass: refused, as the
    # C core refuses it (the same rule there).
    if np.any(np.diag(factor) ** 2 <= SINGULAR * np.diag(matrix)):
        raise ValueError(f"{where}: covariance is singular (not positive definite)")
    return 0.5 * (matrix + matrix.T)


@dataclass(frozen=True, eq=False)
class Measurement:
    """One absolute measurement, checked: ``kind`` ``"pose"``, ``"position"`` or
    ``"heading"``, its time stamp ``t`` (s), ``value`` ``(k,)`` (3, 2 or 1 numbers),
    ``covariance`` ``(k, k)`` and ``lever_arm`` ``(2,)`` m. Build it with
    ``Measurement.make``."""

    kind: MeasurementKind
    t: float
    value: np.ndarray
    covariance: np.ndarray
    lever_arm: tuple[float, float]

    @classmethod
    def make(
        cls,
        kind: str,
        t: object,
        value: object,
        covariance: object,
        lever_arm: object = None,
    ) -> Measurement:
        """A checked measurement; ``ValueError`` naming it (kind and stamp) if anything is
        wrong: a stamp or value that is not finite, a covariance that is not symmetric
        positive definite, a lever arm that is not two finite numbers."""
        if kind not in MEASUREMENT_KINDS:
            raise ValueError(f"kind must be one of {', '.join(MEASUREMENT_KINDS)}, got {kind!r}")
        stamp = finite(f"{kind} measurement time", t)
        where = f"{kind} measurement at t = {stamp!r} s"
        size = _SIZE[kind]
        values = _floats(value, "value", where)
        if values.shape != (size,):
            raise ValueError(f"{where}: value must have {size} numbers, got shape {values.shape}")
        if not np.all(np.isfinite(values)):
            raise ValueError(f"{where}: value must be finite, got {values}")
        arm = np.zeros(2) if lever_arm is None else _floats(lever_arm, "lever_arm", where)
        if arm.shape != (2,) or not np.all(np.isfinite(arm)):
            raise ValueError(f"{where}: lever_arm must be two finite numbers (m), got {arm}")
        matrix = _covariance(covariance, size, where)
        values.flags.writeable = matrix.flags.writeable = False
        return cls(kind, stamp, values, matrix, (float(arm[0]), float(arm[1])))

    @property
    def order(self) -> tuple:
        """A total order: by stamp, then kind and values, so that measurements at one stamp
        are applied the same way whatever order they came in."""
        return (self.t, self.kind, tuple(self.value.tolist()), tuple(self.covariance.ravel()))


def start_in_frame(
    times: object, poses: object, measurements: Sequence[Measurement]
) -> tuple[np.ndarray, np.ndarray, float]:
    """Where a dead-reckoned path ``poses`` ``(T+1, 3)`` at ``times`` ``(T+1,)`` s starts in
    the frame of absolute ``measurements`` (``estimation.Measurement``: GPS fixes, poses): its
    start pose ``(3,)`` with the path fitted onto their positions (each where its sensor sits:
    the pose moved by its lever arm; one fix, or no travel, a translation only, or a pose's
    own heading), a covariance ``(3, 3)`` from the fit's residual, and that residual's RMS
    (m). What an estimator starts from when the log gives no start in that frame."""
    times, poses = np.asarray(times, dtype=float), np.asarray(poses, dtype=float)
    stamps = np.array([m.t for m in measurements])
    seen = np.array([[*m.value[:2], 0.0] for m in measurements])
    path = interpolate(times, poses, stamps)
    arms = np.array([[*m.lever_arm, 0.0] for m in measurements])
    sensors = batch.compose(path, arms)
    flat = np.column_stack([sensors[:, :2], np.zeros(len(path))])
    if len(measurements) == 1 or np.ptp(flat[:, :2], axis=0).max() < 1e-9:
        shift = seen[0, :2] - flat[0, :2]  # one point, or no travel: a translation only
        moved = np.array([*shift, 0.0])
        first = measurements[0]
        if first.kind == "pose":  # the robot's pose the sensor's pose implies
            heading = first.value[2]
            c, s = math.cos(heading), math.sin(heading)
            arm_x, arm_y = first.lever_arm[0], first.lever_arm[1]
            body = np.array(
                [
                    first.value[0] - c * arm_x + s * arm_y,
                    first.value[1] - s * arm_x - c * arm_y,
                    heading,
                ]
            )
            moved = batch.compose(body, batch.inverse(path[0]))
    else:
        fitted = align(flat, seen)
        moved = batch.compose(fitted[0], batch.inverse(flat[0]))
    start = batch.compose(moved, poses[0])
    placed = batch.compose(moved, flat)
    rms = float(np.sqrt(np.mean(np.sum((placed[:, :2] - seen[:, :2]) ** 2, axis=1))))
    spread = max(rms, 0.01)
    extent = max(float(np.ptp(seen[:, :2], axis=0).max()), 1.0)
    covariance = np.diag([spread**2, spread**2, min((spread / extent) ** 2 * 4, math.pi**2)])
    return start, covariance, rms


def measurements_of(
    kind: str,
    times: object,
    values: object,
    covariance: object,
    lever_arm: object = None,
    kept: object = None,
) -> list[Measurement]:
    """``Measurement``s from arrays: ``times`` ``(M,)`` s, ``values`` ``(M, 3)`` poses or
    ``(M, 2)`` positions, one ``covariance`` for all (as ``Measurement.make`` takes it) or one
    per row ``(M, k, k)``; ``kept`` ``(M,)`` bool leaves rows out (a sensor's dropouts). A bad
    row raises ``ValueError`` naming it."""
    stamps = np.asarray(times, dtype=float)
    rows = np.asarray(values, dtype=float)
    if stamps.ndim != 1 or len(rows) != len(stamps):
        raise ValueError(f"times {stamps.shape} and values {rows.shape} must have M rows each")
    size = {"pose": 3, "position": 2, "heading": 1}.get(kind, 3)
    if rows.ndim == 1:
        rows = rows[:, None]
    rows = rows[:, :size] if kind != "heading" else rows[:, -1:]
    matrices = np.asarray(covariance, dtype=float)
    each = matrices.ndim == 3
    if each and len(matrices) != len(stamps):
        raise ValueError(
            f"covariance must be one, or one per row ({len(stamps)}), got {len(matrices)}"
        )
    chosen = np.ones(len(stamps), dtype=bool) if kept is None else np.asarray(kept, dtype=bool)
    made = []
    for k in np.flatnonzero(chosen):
        try:
            made.append(
                Measurement.make(
                    kind, stamps[k], rows[k], matrices[k] if each else matrices, lever_arm
                )
            )
        except ValueError as exc:
            raise ValueError(f"row {k}: {exc}") from None
    return made
