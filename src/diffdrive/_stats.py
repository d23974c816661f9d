"""Small statistics without SciPy: chi-square quantiles of 1 to 3 degrees of freedom in
closed form (the gates of the estimators, the ellipses of ``evaluation.consistency``), and
non-negative least squares of a few unknowns (the gyro's Allan terms, AMCL's alphas)."""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np

__all__ = ["chi2_quantile", "nonnegative_least_squares"]


def nonnegative_least_squares(design: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``x >= 0`` minimising ``|design @ x - target|^2``, ``design`` ``(m, n)`` with a few
    columns (n up to about 8): the best unconstrained fit on every subset of the columns
    whose solution is non-negative (the optimum is one of them; 2^n small solves)."""
    columns = design.shape[1]
    best, best_cost = np.zeros(columns), float(np.sum(target * target))
    for size in range(1, columns + 1):
        for used in combinations(range(columns), size):
            found, *_ = np.linalg.lstsq(design[:, used], target, rcond=None)
            if np.any(found < 0):
                continue
            trial = np.zeros(columns)
            trial[list(used)] = found
            cost = float(np.sum((design @ trial - target) ** 2))
            if cost < best_cost:
                best, best_cost = trial, cost
    return best


def _chi2_cdf(x: float, dof: int) -> float:
    """P(chi-square with ``dof`` (1, 2 or 3) degrees of freedom <= ``x``), in closed form."""
    if x <= 0.0:
        return 0.0
    if dof == 1:
        return math.erf(math.sqrt(0.5 * x))
    if dof == 2:
        return -math.expm1(-0.5 * x)
    return math.erf(math.sqrt(0.5 * x)) - math.sqrt(2.0 * x / math.pi) * math.exp(-0.5 * x)


def chi2_quantile(probability: float, dof: int) -> float:
    """The ``probability`` quantile of chi-square with ``dof`` (1 to 3) degrees of freedom,
    e.g. ``chi2_quantile(0.999, 2) = 13.82``: the gate a measurement's squared Mahalanobis
    distance must not pass."""
    if dof not in (1, 2, 3):
        raise ValueError(f"dof must be 1, 2 or 3, got {dof!r}")
    if not 0.0 < probability < 1.0:
        raise ValueError(f"probability must lie in (0, 1), got {probability!r}")
    low, high = 0.0, 1.0
    while _chi2_cdf(high, dof) < probability:
        high *= 2.0
    for _ in range(200):  # bisection to the float's resolution
        middle = 0.5 * (low + high)
        if middle in (low, high):
            break
        low, high = (middle, high) if _chi2_cdf(middle, dof) < probability else (low, middle)
    return 0.5 * (low + high)
