"""How far an odometry trajectory is from the ground truth.

- ``run_errors``: the OptiOdom paper's measures of one run (Sousa et al. 2022): the maximum
  and the final position error (m) and heading error (deg) over the run; ``worst`` takes the
  largest of each over an experiment's runs.
- ``ate``: the absolute trajectory error as evo's APE on the translation part: the RMSE of the
  position errors, optionally after the rigid SE(2) alignment that minimises it (Umeyama 1991,
  without scale).
- ``rpe``: the relative pose error as evo defines it: for pose pairs ``(i, j)`` a fixed
  distance or time apart, the error of the estimated motion from i to j against the true one,
  ``(Q_i^-1 Q_j)^-1 (P_i^-1 P_j)``; the RMSE of its translation (m) and of its rotation (deg).

Trajectories are pose arrays ``(T+1, 3)`` ``[x, y, theta]`` sampled at the same times.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from diffdrive import batch

__all__ = ["RunErrors", "align", "ate", "rpe", "run_errors", "worst"]


@dataclass(frozen=True)
class RunErrors:
    """The paper's four measures: position errors in m, heading errors in degrees."""

    max_position: float
    max_heading: float
    final_position: float
    final_heading: float

    def to_array(self) -> np.ndarray:
        return np.array([self.max_position, self.max_heading, self.final_position,
                         self.final_heading])  # fmt: skip


def _check(estimate: object, truth: object) -> tuple[np.ndarray, np.ndarray]:
    estimate, truth = np.asarray(estimate, dtype=float), np.asarray(truth, dtype=float)
    if estimate.ndim != 2 or estimate.shape[1] != 3 or estimate.shape != truth.shape:
        raise ValueError(
            f"estimate and truth must both have shape (T+1, 3), got {estimate.shape} and "
            f"{truth.shape}"
        )
    return estimate, truth


def run_errors(estimate: object, truth: object) -> RunErrors:
    """Maximum and final position (m) and heading (deg) errors of one run."""
    estimate, truth = _check(estimate, truth)
    position = np.hypot(*(estimate[:, :2] - truth[:, :2]).T)
    heading = np.degrees(np.abs(batch.wrap_angle(estimate[:, 2] - truth[:, 2])))
    return RunErrors(position.max(), heading.max(), position[-1], heading[-1])


def worst(errors: list[RunErrors]) -> RunErrors:
    """The largest of each measure over runs (an experiment's figure in the paper)."""
    return RunErrors(*np.max([e.to_array() for e in errors], axis=0))


def align(estimate: object, truth: object) -> np.ndarray:
    """``estimate`` moved by the rigid motion that best fits its positions onto ``truth``'s.

    Least squares over the positions (Umeyama's method without scale); returns ``(T+1, 3)``.
    """
    estimate, truth = _check(estimate, truth)
    p, q = estimate[:, :2], truth[:, :2]
    p_mean, q_mean = p.mean(axis=0), q.mean(axis=0)
    cross = (q - q_mean).T @ (p - p_mean)
    u, _, vt = np.linalg.svd(cross)
    d = np.sign(np.linalg.det(u @ vt))
    rotation = u @ np.diag([1.0, d]) @ vt
    angle = np.arctan2(rotation[1, 0], rotation[0, 0])
    offset = q_mean - rotation @ p_mean
    return batch.compose(np.array([*offset, angle]), estimate)


def ate(estimate: object, truth: object, aligned: bool = False) -> float:
    """Absolute trajectory error, m: RMSE of the position errors (after ``align`` if asked)."""
    estimate, truth = _check(estimate, truth)
    if aligned:
        estimate = align(estimate, truth)
    return float(np.sqrt(np.mean(np.sum((estimate[:, :2] - truth[:, :2]) ** 2, axis=1))))


def rpe(
    estimate: object,
    truth: object,
    delta: float,
    unit: Literal["m", "s", "poses"] = "m",
    times: object = None,
) -> tuple[float, float]:
    """Relative pose error over pairs ``delta`` apart: RMSE of translation (m), rotation (deg).

    ``unit`` is ``"m"`` (ground-truth distance travelled), ``"s"`` (needs ``times``) or
    ``"poses"``. Each pose i pairs with the first j at least ``delta`` further on.
    """
    estimate, truth = _check(estimate, truth)
    if not (np.isfinite(delta) and delta > 0):
        raise ValueError(f"delta must be finite and > 0, got {delta!r}")
    if unit == "m":
        along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(truth[:, :2], axis=0).T))])
    elif unit == "s":
        if times is None:
            raise ValueError("rpe with unit 's' needs the times")
        along = np.asarray(times, dtype=float)
        if along.shape != (len(truth),):
            raise ValueError(f"times must have shape ({len(truth)},), got {along.shape}")
    elif unit == "poses":
        along = np.arange(len(truth), dtype=float)
    else:
        raise ValueError(f"unit must be 'm', 's' or 'poses', got {unit!r}")
    first = np.arange(len(truth))
    second = np.searchsorted(along, along + delta - 1e-12 * max(1.0, delta))
    keep = second < len(truth)
    if not keep.any():
        raise ValueError(f"no pair of poses is {delta} {unit} apart")
    i, j = first[keep], second[keep]
    moved = batch.relative_to(estimate[j], estimate[i])
    true_moved = batch.relative_to(truth[j], truth[i])
    error = batch.relative_to(moved, true_moved)
    translation = np.sqrt(np.mean(np.sum(error[:, :2] ** 2, axis=1)))
    rotation = np.degrees(np.sqrt(np.mean(batch.wrap_angle(error[:, 2]) ** 2)))
    return float(translation), float(rotation)
