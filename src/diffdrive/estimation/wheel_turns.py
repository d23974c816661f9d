"""The wheels' noise from a whole log, where it was not given: their turn against the gyro's.

Over an interval the wheels' turn ``(r_r dr - r_l dl) / track`` less the gyro's turn is the
gyro's bias times the interval, plus three noises: the gyro's angle random walk (variance
``arw^2 dt``), the wheels' random walk (``k (|r_l dl| + |r_r dr|) / track^2``, the estimator's
own model) and what only the ends of a stretch carry (each counter's rounding, a sampled
gyro's error where the rate steps), which does not grow with it; the gyro's turn between its
samples adds its own variance ``S`` (``Gyro.interpolation_variances``). So over consecutive
windows of ``n`` intervals, the difference ``E`` of two neighbours' disagreements (the second
scaled by the ratio of their durations) leaves the bias out, and

    E[E^2] = arw^2 (T_1 + a^2 T_2) + (S_1 + a^2 S_2) + k (A_1 + a^2 A_2) + c (1 + a^2)

with ``T`` a window's duration, ``A`` its wheels' travel over ``track^2``, ``a = T_1 / T_2``
and ``c`` the ends' share. With the gyro's ``arw`` and ``S`` held (given, from the log's standing
stretches, or the default), ``k`` and ``c`` are the non-negative least-squares fit over windows
of 1 to 32 intervals, each pair weighted by its predicted variance (``E^2`` of a Gaussian
``E`` has a standard deviation twice its mean), and pairs past 25 times their prediction
(a slip, a bump) left out, the fit then repeated.

Where the log is too short or the wheels hardly move to tell ``k`` (fewer than ``LEAST``
intervals that move), ``identify_wheel_turns`` returns None and the caller says which default
it took. A random walk describes wheels whose turn is the gyro's on average; where it is not
(``WheelTurnFit.mismatch``: the wheels' turn less the gyro's per radian of it, a least-squares
fit beside the bias over windows of a second, more than three standard errors from 0: a track
or radii that are not the robot's, a skid-steer's turns), the difference is the wheels'
scale, not their noise, and the caller takes the default instead and says why. The fit is one
``k`` for both wheels: their turn tells the sum of their noises, not each one's.

The counters' rounding under the wheels' noise, and the step that tells their counts where a
log gives wheel angles, are ``diffdrive.encoders``' (``rounding_variance``, ``wheel_quantum``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive._stats import nonnegative_least_squares
from diffdrive.model import Robot, geometry_of
from diffdrive.sensor_noise import WheelNoise

__all__ = ["LEAST", "WheelTurnFit", "identify_wheel_turns"]

LEAST = 50
"""The fewest intervals in which a wheel moves that ``identify_wheel_turns`` fits."""

SCALES = (1, 2, 4, 8, 16, 32)  # windows, in intervals: short enough that the bias holds
ROUNDS = 20  # of reweighting, at most
MISMATCH_WINDOW = 1.0  # s: the wheels' turn against the gyro's, a scale, over windows this long
OUTLIER = 25.0  # a pair's E^2 past this many times its prediction: 5 standard deviations of E


@dataclass(frozen=True)
class WheelTurnFit:
    """``identify_wheel_turns``' result: the wheels' ``noise`` (one ``k`` (m) for both) and
    its standard error ``k_error`` (m), the wheels' turn less the gyro's per radian of it,
    ``mismatch``, and its standard error ``mismatch_error``, the ends' share ``ends``
    (rad^2), the windows' pairs ``used`` and ``left_out`` (past ``OUTLIER`` times their
    prediction), and ``report``, a line on what it is and where from."""

    noise: WheelNoise
    k_error: float
    mismatch: float
    mismatch_error: float
    ends: float
    used: int
    left_out: int
    report: str

    @property
    def scaled(self) -> bool:
        """Whether the wheels' turn differs from the gyro's by a scale (``mismatch`` more
        than three standard errors from 0): then not their noise."""
        return abs(self.mismatch) > 3.0 * self.mismatch_error


def _windows(n: int, *per_interval: np.ndarray) -> list[np.ndarray]:
    """Each of ``per_interval`` ``(N,)`` summed over consecutive windows of ``n`` intervals
    (the last ``N mod n`` left out): ``(N // n,)`` each."""
    m = len(per_interval[0]) // n
    return [values[: m * n].reshape(m, n).sum(axis=1) for values in per_interval]


def _pairs(dt, disagreement, travel, spread) -> tuple[np.ndarray, np.ndarray, int]:
    """The regressors ``(P, 4)`` ``[time, spread, travel, ends]`` and ``E^2`` ``(P,)`` of
    neighbouring windows at every scale (see the module), and how many scales there were."""
    rows, squares = [], []
    for n in SCALES:
        if len(dt) // n < 4:
            break
        durations, turns, moved, open_ = _windows(n, dt, disagreement, travel, spread)
        ratio = durations[:-1] / durations[1:]
        e = turns[:-1] - ratio * turns[1:]
        ratio2 = ratio * ratio
        rows.append(
            np.column_stack(
                [
                    durations[:-1] + ratio2 * durations[1:],
                    open_[:-1] + ratio2 * open_[1:],
                    moved[:-1] + ratio2 * moved[1:],
                    1 + ratio2,
                ]
            )
        )
        squares.append(e * e)
    return np.vstack(rows), np.concatenate(squares), len(rows)


def identify_wheel_turns(
    robot: Robot,
    times: object,
    increments: object,
    turned: object,
    arw: float,
    spread: object = None,
) -> WheelTurnFit | None:
    """The wheels' noise ``k`` (m) from their turn against the gyro's (see the module):
    wheel-angle ``increments`` ``(N-1, 2)`` rad and the gyro's ``turned`` ``(N-1,)`` rad (bias
    included) between ``times`` ``(N,)`` s, the gyro's angle random walk ``arw``
    (rad/s/sqrt(Hz)) held, and with it ``spread`` ``(N-1,)`` rad^2, the gyro turns' variance
    beyond it (``Gyro.interpolation_variances``; default 0). None where fewer than ``LEAST``
    intervals move a wheel."""
    t = np.asarray(times, dtype=float)
    increments = np.asarray(increments, dtype=float)
    turned = np.asarray(turned, dtype=float)
    spread = np.zeros(len(turned)) if spread is None else np.asarray(spread, dtype=float)
    r_l, r_r, track, _ = geometry_of(robot)
    keep = np.isfinite(turned)
    dt = np.diff(t)[keep]
    left, right = r_l * increments[keep, 0], r_r * increments[keep, 1]
    if np.count_nonzero((left != 0.0) | (right != 0.0)) < LEAST:
        return None
    disagreement = (right - left) / track - turned[keep]
    travel = (np.abs(left) + np.abs(right)) / (track * track)
    design, squares, scales = _pairs(dt, disagreement, travel, spread[keep])
    held = arw * arw * design[:, 0] + design[:, 1]  # the gyro's share of each pair's E^2
    design, excess = design[:, 2:], squares - held
    kept = np.ones(len(squares), dtype=bool)
    weights = np.ones(len(squares))
    fitted = np.full(2, np.nan)
    for _ in range(ROUNDS):  # reweighted until the fit and the pairs it keeps hold still
        found = nonnegative_least_squares(*_square(design, excess, kept / (weights * weights)))
        predicted = held + design @ found
        # a perfect log predicts 0 somewhere: the smallest positive prediction instead
        least = float(predicted[predicted > 0].min()) if np.any(predicted > 0) else 1.0
        weights = np.maximum(predicted, least)
        within = squares <= OUTLIER * weights
        if np.allclose(found, fitted, rtol=1e-6, atol=0.0) and np.array_equal(within, kept):
            break
        fitted, kept = found, within
    fit, ends = (float(v) for v in fitted)
    # E^2 of a Gaussian E has a variance of twice its mean squared. Each window sits in two
    # neighbouring pairs and every scale reads the same intervals again: the standard error
    # is widened by the root of twice the scales (seeds drawn at a known k scatter so).
    scaled = design[kept] / weights[kept, None]
    information = scaled.T @ scaled
    k_error = math.sqrt(2.0 * float(np.linalg.pinv(information)[0, 0]) * 2 * scales)
    left_out = int(np.count_nonzero(~kept))
    report = (
        f"wheel noise: k = {fit:.3g} m on both wheels (standard error {k_error:.2g}), from their "
        f"turn against the gyro's over {len(dt)} intervals (the gyro's angle random walk held "
        f"at {arw:.3g} and its samples' interpolation; {left_out} of {len(squares)} windows "
        "left out as slips)"
    )
    mismatch, mismatch_error = _mismatch((right - left) / track, disagreement, dt)
    return WheelTurnFit(
        WheelNoise.symmetric(fit),
        k_error,
        mismatch,
        mismatch_error,
        ends,
        int(kept.sum()),
        left_out,
        report,
    )


def _square(
    design: np.ndarray, target: np.ndarray, weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The weighted ``sum(weights (design x - target)^2)`` as a square problem with the same
    minimiser over any set of ``x`` (the triangular factor of the weighted normal matrix, and
    ``target`` turned into it): the non-negative fit then solves 2 x 2 systems, not thousands
    of rows. The rows themselves, weighted, where that matrix is singular."""
    weighted = design.T * weights
    try:
        upper = np.linalg.cholesky(weighted @ design).T
    except np.linalg.LinAlgError:
        root = np.sqrt(weights)
        return design * root[:, None], target * root
    return upper, np.linalg.solve(upper.T, weighted @ target)


def _mismatch(wheel_turn, disagreement, dt) -> tuple[float, float]:
    """The disagreement per radian of the wheels' turn (least squares beside a bias over
    windows of a second or more, where the gyro's clock against the wheels' matters little;
    the windows past five robust standard deviations of the first fit left out: slips) and
    its standard error."""
    n = max(1, min(len(dt) // 8, math.ceil(MISMATCH_WINDOW / float(np.median(dt)))))
    wheel_turn, disagreement, dt = _windows(n, wheel_turn, disagreement, dt)
    design = np.column_stack([wheel_turn, dt])
    kept = np.ones(len(dt), dtype=bool)
    for _ in range(2):
        found, *_ = np.linalg.lstsq(design[kept], disagreement[kept], rcond=None)
        residuals = disagreement - design @ found
        spread = 1.4826 * float(np.median(np.abs(residuals[kept])))
        kept = np.abs(residuals) <= 5.0 * spread if spread > 0 else kept
    variance = float(np.mean(residuals[kept] ** 2))
    covariance = np.linalg.pinv(design[kept].T @ design[kept]) * variance
    return float(found[0]), math.sqrt(float(covariance[0, 0]))
