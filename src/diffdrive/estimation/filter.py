"""The extended Kalman filter under ``PoseEstimator``: one wheel interval, one absolute
measurement, on the step and Jacobians of ``diffdrive._step`` (the ones ``Odometry`` uses).

State ``(x, y, theta, bias, turn_scale, distance_scale, offset_x, offset_y)``: the pose of
the robot model's equivalent drive's reference point, the gyro bias (rad/s), the turn scale,
the true turn per radian of the wheels' turn (an effective track: ``track / turn_scale``; 1 for
wheels that turn as far as the robot), the distance scale, the true forward travel per metre
of the wheels' (a common scale of both radii; 1 for true radii), and the offset (m, world
frame) of the position fixes from the point they are fixed to: a random walk (a receiver's
wander), added to every ``"position"`` measurement's prediction when estimated. A state that
is not estimated has zero variance and stays where it starts.

One interval: the wheels move ``dl``, ``dr`` rad (true = measured + noise ``n_l``, ``n_r``,
variances ``k |r dl| / r^2`` as ``Odometry``, plus ``wheel_floor``: a counter's rounding, so
that an interval in which a counter stood still is not read as an exact zero) and the gyro
turns ``g`` rad (noise ``n_g``, variance ``arw^2 dt``). The turn is ``turn_scale`` times the
wheels' (heading ``"wheels"``) or the gyro's less ``bias dt`` (``"gyro"``, ``"fused"``). With
``"fused"`` the wheels' turn is then a measurement of the heading change: the filter works on
the joint of the state after, the state before (a clone, as in Roumeliotis and Burdick, ICRA
2002) and the noises, so the wheel noise that moved the pose and the wheel noise in that
measurement are the same noise. That joint, before any absolute measurement, is what the
Rauch-Tung-Striebel smoother needs (``Step``): the state before given the state after is
Gaussian with gain ``C``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive._step import method_flags, move_jacobians, wheel_move
from diffdrive.angles import wrap_angle
from diffdrive.backends.settings import BIAS, DISTANCE, OFFSET, SCALE, Config, N
from diffdrive.estimation.measurements import Measurement

# chi-square, one degree of freedom: P(score > 10.83) = 0.001.
SLIP_THRESHOLD = 10.83
# chi-square, two degrees of freedom (both wheels): P(score > 13.82) = 0.001.
COMMAND_THRESHOLD = 13.82


@dataclass(frozen=True, eq=False)
class Step:
    """The smoother's record of one interval: ``before`` ``(8,)`` and ``before_cov`` the state
    at its start given the data up to its end, ``after`` and ``after_cov`` at its end (no
    absolute measurement yet), and ``gain`` ``C`` ``(8, 8)``."""

    before: np.ndarray
    before_cov: np.ndarray
    after: np.ndarray
    after_cov: np.ndarray
    gain: np.ndarray


# A record's row as the cores write it: before (8), before_cov (64), after (8), after_cov (64),
# gain (64), in Step's order (the C core's Step struct, 208 doubles).
RECORD_WIDTH = 2 * N + 3 * N * N


@dataclass(frozen=True, eq=False)
class SmootherRecords:
    """The smoother's record of every step of a whole log, in time order, as the
    Rauch-Tung-Striebel pass reads it (``estimate_trajectory(..., records=True)``): each
    interval is one step, or one per distinct measurement stamp inside it and one to its end.

    ``interval`` ``(S,)``: the interval (1 to N-1, ending at ``times[interval]``) of each
    step; ``before`` ``(S, 8)`` and ``before_covariance`` ``(S, 8, 8)``: the filtered state at
    the step's start; ``after`` ``(S, 8)`` and ``after_covariance`` ``(S, 8, 8)``: the state
    the step predicts at its end, before any measurement there; ``gain`` ``(S, 8, 8)``: the
    step's smoother Jacobian ``C`` (``d before_smoothed / d after_smoothed``), so that
    ``before_smoothed = before + C (after_smoothed - after)`` and ``P_before_smoothed =
    before_covariance + C (P_after_smoothed - after_covariance) C^T``."""

    interval: np.ndarray
    before: np.ndarray
    before_covariance: np.ndarray
    after: np.ndarray
    after_covariance: np.ndarray
    gain: np.ndarray

    @classmethod
    def from_rows(cls, interval: np.ndarray, rows: np.ndarray) -> SmootherRecords:
        """From the cores' rows ``(S, RECORD_WIDTH)`` (see ``RECORD_WIDTH``)."""
        cut = np.cumsum([N, N * N, N, N * N])
        before, before_cov, after, after_cov, gain = np.split(rows, cut, axis=1)
        square = (-1, N, N)
        return cls(
            interval,
            before,
            before_cov.reshape(square),
            after,
            after_cov.reshape(square),
            gain.reshape(square),
        )


def record_steps(times: np.ndarray, stamps: np.ndarray) -> np.ndarray:
    """How many smoother steps each interval of ``times`` ``(n,)`` has with measurements at
    ``stamps`` ``(M,)`` (sorted, inside the log): one per distinct stamp strictly inside it,
    and one to its end. ``(n-1,)`` ints."""
    inside = np.unique(stamps[(stamps > times[0]) & (stamps < times[-1])])
    inside = inside[~np.isin(inside, times)]
    return 1 + np.bincount(np.searchsorted(times, inside), minlength=len(times))[1:]


def slip_innovation(c: Config, x, P, dl, dr, g, gv, dt) -> tuple:
    """The wheels' turn less the gyro's over one interval (rad; the gyro's of variance ``gv``
    beyond its random walk's, rad^2), its variance while neither wheel slips (rad^2), and how
    far it moves per unit of the left and the right wheel's slip fraction (``ratio / (1 +
    ratio)``: the share of the measured turn the ground did not make).
    One interval (floats; ``x`` ``(8,)``, ``P`` ``(8, 8)``) or many (arrays ``(n,)``; ``x``
    ``(n, 8)``, ``P`` ``(n, 8, 8)``)."""
    r_l, r_r, track, offset = c.drive
    wheel_turn = wheel_move(r_l, r_r, track, offset, dl, dr)[2]
    scale = x[..., SCALE]
    spread = (
        c.k[0] * np.abs(r_l * dl)
        + c.k[1] * np.abs(r_r * dr)
        + c.wheel_floor * (r_l * r_l + r_r * r_r)
    )
    innovation = scale * wheel_turn - (g - x[..., BIAS] * dt)
    variance = (
        scale * scale * spread / (track * track)
        + c.arw2 * dt
        + gv
        + dt * dt * P[..., BIAS, BIAS]
        + wheel_turn * wheel_turn * P[..., SCALE, SCALE]
        + 1e-18
    )
    return innovation, variance, -scale * r_l * dl / track, scale * r_r * dr / track


def slip_score(
    c: Config, x: np.ndarray, P: np.ndarray, dl: float, dr: float, g: float, gv: float, dt: float
):
    """The wheels' turn against the gyro's over one interval, squared over its variance:
    chi-square with one degree of freedom while neither slips."""
    innovation, variance, _, _ = slip_innovation(c, x, P, dl, dr, g, gv, dt)
    return innovation * innovation / variance


def advance(
    c: Config,
    x: np.ndarray,
    P: np.ndarray,
    dl: float,
    dr: float,
    g: float,
    gv: float,
    dt: float,
    slip: bool,
    smoother: bool = False,
) -> tuple[np.ndarray, np.ndarray, Step | None]:
    """The state and covariance after one interval (``g`` is NaN without a gyro; ``gv`` its
    variance beyond the random walk's, rad^2), and, if ``smoother``, the smoother's ``Step``."""
    r_l, r_r, track, offset = c.drive
    travelled, _, wheel_turn = wheel_move(r_l, r_r, track, offset, dl, dr)
    scale, distance = x[SCALE], x[DISTANCE]
    forward = distance * travelled
    inflation = c.slip_inflation if slip else 1.0
    noise = np.array(
        [
            inflation * (c.k[0] * abs(r_l * dl) / (r_l * r_l) + c.wheel_floor),
            inflation * (c.k[1] * abs(r_r * dr) / (r_r * r_r) + c.wheel_floor),
            c.arw2 * dt + gv if c.heading != "wheels" else 0.0,
        ]
    )
    by_noise_forward = np.array([0.5 * distance * r_l, 0.5 * distance * r_r, 0.0])
    by_state_forward, by_state_turn = np.zeros(N), np.zeros(N)
    by_state_forward[DISTANCE] = travelled
    if c.heading == "wheels":
        turn = scale * wheel_turn
        by_noise_turn = np.array([-scale * r_l / track, scale * r_r / track, 0.0])
        by_state_turn[SCALE] = wheel_turn
    else:
        turn = g - x[BIAS] * dt
        by_noise_turn = np.array([0.0, 0.0, 1.0])
        by_state_turn[BIAS] = -dt
    dx, dy, by_forward, by_turn = move_jacobians(
        forward, offset, turn, *method_flags(c.method), heading=x[2]
    )
    F = np.eye(N)
    F[0, 2], F[1, 2] = -dy, dx
    F[0] += by_forward[0] * by_state_forward + by_turn[0] * by_state_turn
    F[1] += by_forward[1] * by_state_forward + by_turn[1] * by_state_turn
    F[2] += by_state_turn
    G = np.zeros((N, 3))
    G[0] = by_forward[0] * by_noise_forward + by_turn[0] * by_noise_turn
    G[1] = by_forward[1] * by_noise_forward + by_turn[1] * by_noise_turn
    G[2] = by_noise_turn
    after = x.copy()
    after[:3] += (dx, dy, turn)
    FP, GQ = F @ P, G * noise
    moved = FP @ F.T + GQ @ G.T
    if c.estimate_bias and c.heading == "fused":
        moved[BIAS, BIAS] += c.rrw2 * dt
    if c.estimate_offset:
        moved[OFFSET, OFFSET] += c.offset_rate2 * dt
        moved[OFFSET + 1, OFFSET + 1] += c.offset_rate2 * dt
    measured = c.heading == "fused" and not slip
    if not (measured or smoother):  # nothing needs the joint below
        return after, 0.5 * (moved + moved.T), None
    # The joint of (state after, state before, noises), 19 x 19.
    joint = np.zeros((2 * N + 3, 2 * N + 3))
    joint[:N, :N] = moved
    joint[:N, N : 2 * N] = FP
    joint[N : 2 * N, :N] = FP.T
    joint[N : 2 * N, N : 2 * N] = P
    joint[:N, 2 * N :] = GQ
    joint[2 * N :, :N] = GQ.T
    joint[2 * N :, 2 * N :] = np.diag(noise)
    mean = np.concatenate([after, x, np.zeros(3)])
    if measured:
        # The wheels measure the turn over the scale, less their own noise.
        H = np.zeros(2 * N + 3)
        H[2], H[N + 2] = 1.0 / scale, -1.0 / scale
        H[SCALE] = -turn / (scale * scale)
        H[2 * N], H[2 * N + 1] = r_l / track, -r_r / track
        spread = joint @ H
        s = float(H @ spread) + 1e-18
        gain = spread / s
        mean = mean + gain * (wheel_turn - turn / scale)
        joint = joint - np.outer(gain, spread)
    joint = 0.5 * (joint + joint.T)
    after, after_cov = mean[:N], joint[:N, :N]
    if not smoother:
        return after.copy(), after_cov.copy(), None
    step = Step(
        mean[N : 2 * N],
        joint[N : 2 * N, N : 2 * N],
        after,
        after_cov,
        _solve_right(joint[N : 2 * N, :N], after_cov, c.active),
    )
    return after.copy(), after_cov.copy(), step


def _solve_right(cross: np.ndarray, covariance: np.ndarray, active: list[int]) -> np.ndarray:
    """``cross @ inverse(covariance)`` over the estimated states (a pseudo-inverse, scaled to
    unit variances first, for a covariance that is singular at the start)."""
    gain = np.zeros((N, N))
    block = covariance[np.ix_(active, active)]
    sigma = np.sqrt(np.maximum(np.diag(block), 0.0))
    sigma[sigma == 0.0] = 1.0
    inverse = np.linalg.pinv(block / np.outer(sigma, sigma), rcond=1e-12, hermitian=True)
    gain[np.ix_(active, active)] = cross[np.ix_(active, active)] @ (
        inverse / np.outer(sigma, sigma)
    )
    return gain


def absolute_update(
    x: np.ndarray,
    P: np.ndarray,
    m: Measurement,
    offset: float,
    gate: dict[int, float],
    fix_offset: bool = False,
    inflate: bool = False,
) -> tuple[np.ndarray, np.ndarray, bool, float, float]:
    """The state and covariance after measurement ``m`` (unchanged if the gate refuses it),
    whether it was taken, its squared Mahalanobis distance and the log determinant of its
    innovation's covariance (the two terms of its likelihood). ``offset`` (m) is how far left
    of the body origin the state's reference point lies; ``fix_offset``: a ``"position"``
    measurement carries the offset state (see the module); ``inflate``: a measurement past
    the gate is taken with its covariance grown until its score lies on the gate (``R + (a -
    1) S``, ``a`` = score / gate: a Huber-like weight), not refused."""
    size = len(m.value)
    H = np.zeros((size, N))
    innovation = np.empty(size)
    if m.kind == "heading":
        H[0, 2] = 1.0
        innovation[0] = wrap_angle(m.value[0] - x[2])
    else:
        arm_x, arm_y = m.lever_arm[0], m.lever_arm[1] - offset
        c, s = math.cos(x[2]), math.sin(x[2])
        H[0, 0] = H[1, 1] = 1.0
        H[0, 2], H[1, 2] = -s * arm_x - c * arm_y, c * arm_x - s * arm_y
        innovation[0] = m.value[0] - (x[0] + c * arm_x - s * arm_y)
        innovation[1] = m.value[1] - (x[1] + s * arm_x + c * arm_y)
        if fix_offset and m.kind == "position":
            H[0, OFFSET], H[1, OFFSET + 1] = 1.0, 1.0
            innovation -= x[OFFSET : OFFSET + 2]
    if size == 3:
        H[2, 2] = 1.0
        innovation[2] = wrap_angle(m.value[2] - x[2])
    with np.errstate(over="ignore", invalid="ignore"):
        S = H @ P @ H.T + m.covariance
        finite = bool(np.all(np.isfinite(S)) and np.all(np.isfinite(innovation)))
    if not finite:  # a lever arm of 1e300 m: gated out, as the C core's Cholesky refuses it
        return x, P, False, math.inf, math.nan
    try:
        factor = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return x, P, False, math.inf, math.nan
    whitened = np.linalg.solve(factor, innovation)
    score = float(whitened @ whitened)
    log_det = float(2.0 * np.sum(np.log(np.diag(factor))))
    grow = 1.0
    if score > gate[size]:
        if not inflate:
            return x, P, False, score, log_det
        grow = score / gate[size]
    gain = np.linalg.solve(S, H @ P).T / grow  # P H^T (a S)^-1, S symmetric
    keep = np.eye(N) - gain @ H
    noise = m.covariance + (grow - 1.0) * S
    covariance = keep @ P @ keep.T + gain @ noise @ gain.T  # Joseph form
    return x + gain @ innovation, 0.5 * (covariance + covariance.T), True, score, log_det
