"""A whole log through ``PoseEstimator``, then a fixed-interval smoother.

``estimate_trajectory`` runs the log forward (wheel increments, a ``Gyro`` with its own
stamps, absolute measurements applied at their stamps) and, with ``smooth``, back again:
the Rauch-Tung-Striebel smoother (Rauch, Tung and Striebel, AIAA Journal 3(8), 1965) on the
filter's linearisation, the state before each interval moved by the gain ``C`` times the
smoothed correction after it (``diffdrive.estimation.filter.Step``). Every estimate then uses
every measurement, before and after it.

With a gyro, the whole log also finds slip episodes the per-interval test misses
(``diffdrive.estimation.episodes``) and runs forward again with them flagged as slipping.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from diffdrive._validate import increasing
from diffdrive.estimation import filter as ekf
from diffdrive.estimation.episodes import steady_episodes
from diffdrive.estimation.fusion import PythonPoseEstimator, _body_covariance, _body_pose
from diffdrive.estimation.imu import Gyro
from diffdrive.estimation.measurements import Measurement
from diffdrive.estimation.twists import interval_twists
from diffdrive.model import Robot

SLIP_TESTS = ("episodes", "interval")

__all__ = ["Estimate", "estimate_trajectory", "measurements_of"]


@dataclass(frozen=True, eq=False)
class Estimate:
    """``estimate_trajectory``'s result at the wheel stamps ``times`` ``(N,)``: the body's
    ``poses`` ``(N, 3)`` and ``covariances`` ``(N, 3, 3)``, the filter's ``states`` ``(N, 5)``
    (``x, y, theta, bias, turn_scale`` of the reference point) and ``state_covariances``
    ``(N, 5, 5)``; per row the ``slip`` flag and ``slip_score`` of the interval ending there;
    the ``measurements`` in stamp order with ``accepted`` ``(M,)`` and ``scores`` ``(M,)`` (the
    squared Mahalanobis distance in the forward pass); ``smoothed`` says which pass it is;
    ``twists`` ``(N, 3)`` ``[vx, vy, omega]`` and ``twist_covariances`` ``(N, 3, 3)``: the body
    twist over the interval ending at each row (row 0: the first interval's) and its
    covariance, from the wheels and the heading source with the estimated bias or turn scale
    (``diffdrive.estimation.twists``)."""

    times: np.ndarray
    poses: np.ndarray
    covariances: np.ndarray
    states: np.ndarray
    state_covariances: np.ndarray
    slip: np.ndarray
    slip_score: np.ndarray
    measurements: tuple[Measurement, ...]
    accepted: np.ndarray
    scores: np.ndarray
    smoothed: bool
    heading: str
    twists: np.ndarray
    twist_covariances: np.ndarray

    @property
    def rejected(self) -> int:
        """How many measurements the gate refused."""
        return int(np.count_nonzero(~self.accepted))


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


def estimate_trajectory(
    robot: Robot,
    times: object,
    increments: object,
    *,
    gyro: Gyro | None = None,
    measurements: Iterable[Measurement] = (),
    heading: str = "fused",
    initial_pose: object = None,
    initial_covariance: object = None,
    smooth: bool = True,
    commanded: object = None,
    slip_test: str = "episodes",
    **options,
) -> Estimate:
    """A whole log: wheel-angle ``increments`` ``(N-1, 2)`` rad between ``times`` ``(N,)`` s,
    the ``gyro`` (needed unless ``heading`` is ``"wheels"``), absolute ``measurements``
    stamped inside ``[times[0], times[-1]]``, and ``commanded`` wheel velocities ``(N-1, 2)``
    rad/s if known. ``options`` go to ``PoseEstimator``. With ``smooth``, the smoothed
    estimate; else the filter's. ``slip_test``: ``"episodes"`` flags, besides the intervals
    the streaming test flags, the runs of intervals that one slipping wheel explains
    (``diffdrive.estimation.episodes``; the log then runs again with them flagged);
    ``"interval"`` only the streaming test's."""
    times = np.asarray(times, dtype=float)
    increments = np.asarray(increments, dtype=float)
    if times.ndim != 1 or len(times) < 2:
        raise ValueError(f"times must be (N,) s with N >= 2, got shape {times.shape}")
    increasing("times", times)
    if increments.shape != (len(times) - 1, 2):
        raise ValueError(
            f"increments must be (N-1, 2) for {len(times)} times, got {increments.shape}"
        )
    if heading != "wheels" and gyro is None:
        raise ValueError(f"heading {heading!r} needs a gyro")
    if gyro is not None and not isinstance(gyro, Gyro):
        raise TypeError(f"gyro must be a Gyro (Gyro, Gyro.from_imu), got {type(gyro).__name__}")
    turned = None if gyro is None else np.diff(gyro.angles(times))
    wanted = None if commanded is None else np.asarray(commanded, dtype=float)
    if wanted is not None and wanted.shape != increments.shape:
        raise ValueError(f"commanded must be {increments.shape}, got {wanted.shape}")
    given = list(measurements)
    for m in given:
        if not isinstance(m, Measurement):
            raise TypeError(
                f"measurements must be Measurements (Measurement.make, measurements_of), got "
                f"{type(m).__name__}"
            )
    ordered = sorted(given, key=lambda m: m.order)
    for m in ordered:
        if not times[0] <= m.t <= times[-1]:
            raise ValueError(
                f"{m.kind} measurement at t = {m.t!r} s lies outside the log "
                f"[{times[0]:g}, {times[-1]:g}] s"
            )
    if slip_test not in SLIP_TESTS:
        raise ValueError(f"slip_test must be one of {SLIP_TESTS}, got {slip_test!r}")
    options.setdefault("history", float("inf"))
    log = (robot, heading, initial_pose, initial_covariance, times, increments, turned, wanted)
    estimator, states, covariances, slips, scores = _forward(log, ordered, smooth, options)
    forced = None
    # Again with the episodes' wheel turns left out, and once more if what they had pulled
    # into the estimate (the bias, in a fused heading) moved the episodes found.
    for _ in range(2 if slip_test == "episodes" and turned is not None else 0):
        found = _episodes(estimator)
        if forced is None and not np.any(found & ~slips[1:]):
            break
        if forced is not None and np.array_equal(found, forced):
            break
        forced = found
        estimator, states, covariances, slips, scores = _forward(
            log, ordered, smooth, options, forced
        )
    intervals = estimator._intervals
    outcomes = [o for i in intervals for o in i.outcomes]
    accepted = np.array([ok for ok, _ in outcomes], dtype=bool)
    distances = np.array([score for _, score in outcomes])
    head = ordered[: len(ordered) - len(outcomes)]  # applied at the start
    if head:
        accepted = np.concatenate([np.ones(len(head), dtype=bool), accepted])
        distances = np.concatenate([np.zeros(len(head)), distances])
    if smooth:
        states, covariances = _smooth(intervals, states[-1], covariances[-1], len(times))
    offset = robot.reference_offset
    poses = np.array([_body_pose(x, offset).to_array() for x in states])
    pose_covariances = np.array(
        [_body_covariance(x, P, offset) for x, P in zip(states, covariances, strict=True)]
    )
    twists, twist_covariances = _twists(robot, estimator.config, log, states, covariances, slips)
    return Estimate(
        times,
        poses,
        pose_covariances,
        states,
        covariances,
        slips,
        scores,
        tuple(ordered),
        accepted,
        distances,
        smooth,
        heading,
        twists,
        twist_covariances,
    )


def _twists(robot: Robot, c: ekf.Config, log, states, covariances, slips):
    """The body twist over each interval and its covariance (``interval_twists``): the
    wheels' turn times the estimated turn scale, or the gyro's turn less the estimated bias,
    each interval's wheel noise inflated as the filter inflated it."""
    times, increments, turned = log[4], log[5], log[6]
    inflation = np.where(slips[1:], c.slip_inflation, 1.0)
    if c.heading == "wheels":
        return interval_twists(
            robot,
            times,
            increments,
            *c.k,
            turn_scale=states[1:, ekf.SCALE],
            turn_scale_variances=covariances[1:, ekf.SCALE, ekf.SCALE],
            noise_scale=inflation,
        )
    dt = np.diff(times)
    return interval_twists(
        robot,
        times,
        increments,
        *c.k,
        turns=turned - states[1:, ekf.BIAS] * dt,
        turn_variances=c.arw2 * dt + dt * dt * covariances[1:, ekf.BIAS, ekf.BIAS],
        noise_scale=inflation,
    )


def _forward(log, ordered: list[Measurement], smooth: bool, options: dict, forced=None):
    """One pass forward: the estimator (its history whole) and per row the state, covariance,
    slip flag and score; ``forced`` ``(N-1,)`` flags intervals as slipping whatever their
    score."""
    robot, heading, initial_pose, initial_covariance, times, increments, turned, wanted = log
    estimator = PythonPoseEstimator(  # the Python core keeps the smoother's records
        robot,
        heading,
        initial_pose,
        initial_covariance,
        initial_time=float(times[0]),
        ahead=0.0,
        **options,
    )
    estimator._smoother = smooth
    first = 0
    while first < len(ordered) and ordered[first].t == times[0]:
        estimator.add(ordered[first])
        first += 1
    n = len(times)
    states, covariances = np.empty((n, ekf.N)), np.empty((n, ekf.N, ekf.N))
    slips, scores = np.zeros(n, dtype=bool), np.zeros(n)
    states[0], covariances[0] = estimator.state, estimator.state_covariance
    for k in range(1, n):
        last = first
        while last < len(ordered) and ordered[last].t <= times[k]:
            last += 1
        estimator._forced = forced is not None and bool(forced[k - 1])
        estimator._pending = ordered[first:last]  # applied inside this interval, at their stamps
        first = last
        try:
            estimator.update_increments(
                increments[k - 1, 0],
                increments[k - 1, 1],
                times[k],
                gyro_angle=None if turned is None else turned[k - 1],
                commanded=None if wanted is None else wanted[k - 1],
            )
        except ValueError as exc:
            where = f"interval {k - 1} ({times[k - 1]:g} to {times[k]:g} s)"
            raise ValueError(f"{where}: {exc}") from None
        states[k], covariances[k] = estimator.state, estimator.state_covariance
        slips[k], scores[k] = estimator.slip, estimator.slip_score
    return estimator, states, covariances, slips, scores


def _episodes(estimator: PythonPoseEstimator) -> np.ndarray:
    """``steady_episodes`` over the forward pass's intervals, each from its start state."""
    c = estimator.config
    r_l, r_r, track, _ = c.drive
    rows = []
    for i in estimator._intervals:
        innovation, variance, by_left, by_right = ekf.slip_innovation(
            c, *i.start, *i.wheels, i.gyro, i.t1 - i.t0
        )
        scale = i.start[0][ekf.SCALE]
        wheel_noise = (c.k[0] * abs(r_l * i.wheels[0]), c.k[1] * abs(r_r * i.wheels[1]))
        rows.append(
            (innovation, by_left, by_right, i.t1 - i.t0, *wheel_noise, scale * scale, variance)
        )
    table = np.array(rows)
    deviation = np.sqrt(table[:, -1])
    shared = table[:, 4:6] * (table[:, 6] / (track * track * table[:, -1]))[:, None]
    flagged = np.array([i.slip for i in estimator._intervals], dtype=bool)
    return steady_episodes(
        table[:, 0] / deviation,
        table[:, 1:3] / deviation[:, None],
        flagged,
        table[:, 3] / deviation,
        shared,
    )


def _smooth(intervals, last_state: np.ndarray, last_covariance: np.ndarray, n: int):
    """The Rauch-Tung-Striebel pass backwards: the smoothed state and covariance at the start
    of the log and at the end of each interval."""
    states, covariances = np.empty((n, ekf.N)), np.empty((n, ekf.N, ekf.N))
    x, P = last_state, last_covariance
    for k in range(n - 1, 0, -1):
        states[k], covariances[k] = x, P
        for step in reversed(intervals[k - 1].steps):
            x = step.before + step.gain @ (x - step.after)
            P = step.before_cov + step.gain @ (P - step.after_cov) @ step.gain.T
            P = 0.5 * (P + P.T)
    states[0], covariances[0] = x, P
    return states, covariances
