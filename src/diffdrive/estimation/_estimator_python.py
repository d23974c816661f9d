"""The pure-Python twin of the C estimator core (``_odometry.c``'s companion ``_estimator.c``):
``PoseEstimator``'s readings, history and replay on ``diffdrive.estimation.filter``'s maths.
Both take the same arguments and give the same results; this one also keeps what the smoother
needs (``diffdrive.estimation.smoother``), and is what an installation without a C compiler
runs. See ``diffdrive.estimation.fusion`` for the rules.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from diffdrive._validate import finite
from diffdrive.backends.settings import CoreSettings, LogArrays, PassArrays
from diffdrive.estimation import filter as ekf
from diffdrive.estimation.imu import _interpolation_variance
from diffdrive.estimation.measurements import MEASUREMENT_KINDS, Measurement, _floats
from diffdrive.types import WheelVelocities

KINDS = ("update_ticks", "update_positions", "update_increments", "update_velocities")


@dataclass(eq=False)
class Interval:
    """One wheel interval ``(t0, t1]`` in the history: its data, the state and covariance at
    its start, the absolute measurements stamped inside it (in ``Measurement.order``), their
    outcomes, the slip test's, and the smoother's steps if kept. ``gyro_variance`` (rad^2):
    the gyro turn's variance beyond its random walk's (a whole log's, from its samples; a
    stream's one angle: 0)."""

    t0: float
    t1: float
    wheels: tuple[float, float]
    gyro: float
    forced: bool
    start: tuple[np.ndarray, np.ndarray]
    gyro_variance: float = 0.0
    measurements: list[Measurement] = field(default_factory=list)
    outcomes: list[tuple[bool, float, float]] = field(default_factory=list)
    slip: bool = False
    slip_score: float = 0.0
    steps: list[ekf.Step] = field(default_factory=list)


def _end(interval: Interval) -> float:
    return interval.t1


def _named_update(kind: int, what: str) -> Callable[..., None]:
    """The core's update method ``KINDS[kind]``: one reading of ``what``, with the gyro and
    command given beside it; the third argument is t, or dt for velocities."""

    def update(
        self: EstimatorCore,
        left: Any,
        right: Any,
        t: Any,
        *,
        gyro_angle: Any = None,
        gyro_rate: Any = None,
        commanded: Any = None,
    ) -> None:
        self._update(kind, (left, right, t), t, gyro_angle, gyro_rate, commanded)

    update.__name__ = update.__qualname__ = KINDS[kind]
    third = "dt" if kind == 3 else "t"
    update.__doc__ = (
        f"{KINDS[kind]}(left, right, {third}, *, gyro_angle=None, gyro_rate=None, "
        f"commanded=None): {what}."
    )
    return update


class EstimatorCore:
    """The state, history and updates of ``PoseEstimator``; use that class."""

    def __init__(self, wheels: Any, settings: CoreSettings) -> None:
        self._wheels = wheels
        self.config = settings
        self._command_sigma = settings.command_sigma
        self._gate = dict(zip((1, 2, 3), settings.gates, strict=True))
        # what an absolute update needs besides the state and the measurement
        self._measured = (
            settings.offset,
            self._gate,
            settings.estimate_offset,
            settings.inflate,
        )
        self._offset, self._history, self._ahead = (
            settings.offset,
            settings.history,
            settings.ahead,
        )
        self._mounting = np.array(settings.mounting)
        self._state = np.array(settings.state, dtype=float)
        self._P = np.array(settings.covariance, dtype=float).reshape(ekf.N, ekf.N)
        self._intervals: list[Interval] = []
        self._pending: list[Measurement] = []
        self._rate: float | None = None
        self._settled = [0, 0]  # accepted, rejected: measurements that left the history
        self._last = (False, 0.0, 0.0)  # slip, slip score, command score
        self._smoother = False  # keep each interval's smoother steps (estimate_trajectory)
        self._forced = False  # flag the next interval as slipping (estimate_trajectory)

    # -- what the Python class reads ------------------------------------------------------

    def _state_now(self) -> tuple[float, ...]:
        return tuple(self._state.tolist())

    def _covariance_now(self) -> tuple[float, ...]:
        return tuple(self._P.ravel().tolist())

    def _counts(self) -> tuple[int, int]:
        ok = sum(o for i in self._intervals for o, _, _ in i.outcomes)
        bad = sum(not o for i in self._intervals for o, _, _ in i.outcomes)
        return self._settled[0] + ok, self._settled[1] + bad

    def _history_start(self) -> float:
        if self._intervals:
            return self._intervals[0].t0
        return self._wheels._state()[4]

    def _slip(self) -> tuple[bool, float, float]:
        return self._last

    def _pose_at(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        k = bisect.bisect_left(self._intervals, t, key=_end)
        if k == len(self._intervals):
            x, P = self._state, self._P
        else:
            x, P = self._run(self._intervals[k], stop=t)
        return tuple(x.tolist()), tuple(P.ravel().tolist())

    # -- wheel readings -------------------------------------------------------------------

    update_ticks = _named_update(
        0, "absolute encoder counter readings at t s (the first sets the reference)"
    )
    update_positions = _named_update(1, "accumulated wheel angles (rad) at t s")
    update_increments = _named_update(2, "wheel-angle increments (rad) at t s")
    update_velocities = _named_update(3, "wheel velocities (rad/s) held dt s")

    def _update(self, kind, args, t, gyro_angle, gyro_rate, commanded) -> None:
        name = KINDS[kind]
        if t is None:
            what = "dt" if kind == 3 else "t"
            raise ValueError(
                f"{name}: PoseEstimator needs the time {what} (s) of every reading: late "
                "measurements are placed by time"
            )
        previous = self._wheels._state()[4]
        previous = None if math.isnan(previous) else previous
        if previous is None and kind == 2:
            raise ValueError(
                f"{name}: the estimator's clock has not started: give initial_time, or "
                "begin with a ticks or positions reading"
            )
        if previous is None and kind == 3:
            previous = 0.0  # velocities start the clock at 0 s, as Odometry's do
        # Everything about this reading is checked before anything changes: the gyro and
        # commands here, the wheels by their own update, which is all or nothing.
        rate = None if gyro_rate is None else self._gyro_rate(gyro_rate)
        if gyro_angle is not None:
            gyro_angle = finite("gyro_angle", gyro_angle)
        no_gyro = gyro_angle is None and rate is None
        if previous is not None and no_gyro and self.config.heading != "wheels":
            raise ValueError(
                f"{name}: heading {self.config.heading!r} needs gyro_angle or gyro_rate with "
                "every wheel reading"
            )
        wanted = None if commanded is None else WheelVelocities.coerce(commanded, "commanded")
        before = self._wheels._wheel_arcs()
        snapshot = self._wheels._snapshot()
        getattr(self._wheels, name)(*args)
        now = self._wheels._state()[4]
        if previous is None:  # a reference reading: the clock starts
            self._rate = rate
            return
        dt = now - previous
        after = self._wheels._wheel_arcs()
        r_l, r_r = self.config.drive[0], self.config.drive[1]
        dl, dr = (after[0] - before[0]) / r_l, (after[1] - before[1]) / r_r
        gyro, gyro_variance = self._gyro_angle(gyro_angle, rate, dt)
        command_score = 0.0
        if wanted is not None and dt > 0.0:
            miss = (dl / dt - wanted.left, dr / dt - wanted.right)
            sigma2 = self._command_sigma * self._command_sigma
            command_score = (miss[0] * miss[0] + miss[1] * miss[1]) / sigma2
        forced = command_score > ekf.COMMAND_THRESHOLD or self._forced
        start = (self._state, self._P)
        interval = Interval(previous, now, (dl, dr), gyro, forced, start, gyro_variance)
        due = [m for m in self._pending if m.t <= now]
        interval.measurements = sorted(due, key=lambda m: m.order)
        try:
            with np.errstate(over="ignore", invalid="ignore", under="ignore"):
                x, P = self._run(interval)
            finite_state = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(P)))
        except (ValueError, OverflowError, np.linalg.LinAlgError):  # math on an inf
            finite_state = False
        if not finite_state:
            self._wheels._restore(snapshot)
            raise ValueError(
                f"{name}: the update would overflow the state; refused, nothing changed"
            )
        self._pending = [m for m in self._pending if m.t > now]
        self._rate = rate if rate is not None else self._rate
        self._intervals.append(interval)
        self._state, self._P = x, P
        self._last = (interval.slip, interval.slip_score, command_score)
        self._trim()

    def _gyro_rate(self, rate: object) -> float:
        if isinstance(rate, int | float):
            return finite("gyro_rate", rate)
        values = _floats(rate, "gyro_rate", "gyro_rate")
        if values.shape == (3,):
            values = np.asarray(self._mounting @ values)
        if values.shape != () or not np.isfinite(values):
            raise ValueError(f"gyro_rate must be a finite yaw rate or 3 IMU rates, got {rate!r}")
        return float(values)

    def _gyro_angle(
        self, angle: float | None, rate: float | None, dt: float
    ) -> tuple[float, float]:
        """The angle the gyro turned over the interval (NaN: no gyro) and its variance beyond
        the random walk's: from two rates, how far they leave the angle between them open
        (``Gyro.interpolation_variances``); from an angle, 0."""
        if angle is not None:
            return angle, 0.0
        if rate is not None:
            held = rate if self._rate is None else self._rate
            return 0.5 * (held + rate) * dt, _interpolation_variance(dt, rate - held)
        return math.nan, 0.0

    # -- absolute measurements ------------------------------------------------------------

    def _add_fast(self, kind, t, value, covariance, lever_arm) -> bool | None:
        """The C core's shortcut for plain numbers; here: always the checked way."""
        return None

    def _add(self, m: Measurement) -> bool:
        where = f"{m.kind} measurement at t = {m.t!r} s"
        now = self._wheels._state()[4]
        if math.isnan(now):
            raise ValueError(f"{where}: no wheel reading yet, so no time to place it at")
        start = self._history_start()
        if m.t > now + self._ahead:
            raise ValueError(
                f"{where}: more than ahead = {self._ahead!r} s past the newest wheel reading "
                f"({now!r} s)"
            )
        if m.t > now:
            self._pending.append(m)
            return False
        if not self._intervals or m.t < start:
            if m.t == now and not self._intervals:  # at the start itself
                with np.errstate(all="ignore"):
                    x, P, ok, _, _ = ekf.absolute_update(self._state, self._P, m, *self._measured)
                if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
                    raise ValueError(f"{where}: it would overflow the state; refused")
                self._state, self._P = x, P
                self._settled[0 if ok else 1] += 1
                return ok
            raise ValueError(
                f"{where}: older than the history, which starts at {start!r} s "
                f"(history = {self._history!r} s)"
            )
        k = bisect.bisect_left(self._intervals, m.t, key=_end)
        target = self._intervals[k]
        kept = [
            (i.start, list(i.measurements), i.outcomes, i.steps, i.slip, i.slip_score)
            for i in self._intervals[k:]
        ]
        keys = [x.order for x in target.measurements]
        target.measurements.insert(bisect.bisect_right(keys, m.order), m)
        try:
            with np.errstate(all="ignore"):
                x, P = self._replay(k)
            finite_state = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(P)))
        except (ValueError, OverflowError, np.linalg.LinAlgError):
            finite_state = False
        if not finite_state:  # the history as it was
            for interval, old in zip(self._intervals[k:], kept, strict=True):
                (interval.start, interval.measurements, interval.outcomes, interval.steps) = old[:4]
                interval.slip, interval.slip_score = old[4:]
            raise ValueError(f"{where}: it would overflow the state; refused, nothing changed")
        self._state, self._P = x, P
        return target.outcomes[target.measurements.index(m)][0]

    # -- a whole log ----------------------------------------------------------------------

    def _run_log(self, log: LogArrays, out: PassArrays, smooth: bool) -> int:
        """``estimate_trajectory``'s pass over a whole ``log`` from the state now, leaving the
        estimator as it was, filling ``out`` (``backends.settings``' ``LogArrays`` and
        ``PassArrays`` say what each array is), smoothed with ``smooth``; with ``smooth``,
        unless ``out.records`` is None, the smoother's record of each step in time order
        (``filter.record_steps`` says how many). Measurements stamped at ``times[0]`` are
        applied at the start. Returns -1, or the interval whose state would overflow (-2: the
        start)."""
        times, left, right, gyro, gyro_variance, forced, m_t, m_kind, m_value, m_cov, m_lever = log
        states, covariances, slips, scores, accepted, distances, log_dets, records = out
        made = []
        for j in range(len(m_t)):
            kind = MEASUREMENT_KINDS[int(m_kind[j])]
            k = {"pose": 3, "position": 2, "heading": 1}[kind]
            value, cov = np.array(m_value[j, :k]), np.array(m_cov[j, : k * k]).reshape(k, k)
            lever = (float(m_lever[j, 0]), float(m_lever[j, 1]))
            made.append(Measurement(kind, float(m_t[j]), value, cov, lever))
        x, P = self._state, self._P
        j = 0
        with np.errstate(all="ignore"):
            while j < len(made) and made[j].t == times[0]:  # at the start itself
                x, P, accepted[j], distances[j], log_dets[j] = ekf.absolute_update(
                    x, P, made[j], *self._measured
                )
                j += 1
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
            return -2
        states[0], covariances[0], slips[0], scores[0] = x, P.ravel(), 0.0, 0.0
        intervals: list[Interval] = []
        saved = self._smoother
        self._smoother = smooth
        try:
            for k in range(1, len(times)):
                interval = Interval(
                    float(times[k - 1]),
                    float(times[k]),
                    (float(left[k - 1]), float(right[k - 1])),
                    float(gyro[k - 1]),
                    bool(forced[k - 1]),
                    (x, P),
                    float(gyro_variance[k - 1]),
                )
                first = j
                while j < len(made) and made[j].t <= times[k]:
                    j += 1
                interval.measurements = made[first:j]
                try:
                    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
                        x, P = self._run(interval)
                    finite_state = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(P)))
                except (ValueError, OverflowError, np.linalg.LinAlgError):
                    finite_state = False
                if not finite_state:
                    return k - 1
                states[k], covariances[k] = x, P.ravel()
                slips[k], scores[k] = interval.slip, interval.slip_score
                intervals.append(interval)
        finally:
            self._smoother = saved
        outcomes = [o for i in intervals for o in i.outcomes]
        head = len(made) - len(outcomes)
        for q, (ok, score, log_det) in enumerate(outcomes):
            accepted[head + q], distances[head + q], log_dets[head + q] = ok, score, log_det
        if smooth and records is not None:
            steps = [step for interval in intervals for step in interval.steps]
            if len(steps) != len(records):
                raise ValueError(f"_run_log: records must have {len(steps)} rows")
            for row, step in enumerate(steps):
                parts = (step.before, step.before_cov, step.after, step.after_cov, step.gain)
                records[row] = np.concatenate([np.ravel(part) for part in parts])
        if smooth:  # Rauch-Tung-Striebel, backwards
            for k in range(len(times) - 1, 0, -1):
                states[k], covariances[k] = x, P.ravel()
                for step in reversed(intervals[k - 1].steps):
                    x = step.before + step.gain @ (x - step.after)
                    P = step.before_cov + step.gain @ (P - step.after_cov) @ step.gain.T
                    P = 0.5 * (P + P.T)
            states[0], covariances[0] = x, P.ravel()
        return -1

    # -- the history ----------------------------------------------------------------------

    def _run(self, interval: Interval, stop: float | None = None):
        """Run ``interval`` from its start state (splitting it at each measurement's stamp)
        and record its outcomes (and its smoother steps, if kept); with ``stop``, only up to
        that time, recording nothing."""
        c = self.config
        x, P = interval.start
        (dl, dr), g, duration = interval.wheels, interval.gyro, interval.t1 - interval.t0
        gv = interval.gyro_variance
        if stop is None:
            if math.isnan(g):
                interval.slip, interval.slip_score = interval.forced, 0.0
            else:
                score = ekf.slip_score(c, x, P, dl, dr, g, gv, duration)
                interval.slip = bool(score > c.slip_threshold) or interval.forced
                interval.slip_score = float(score)
        end = interval.t1 if stop is None else stop
        cuts = sorted({m.t for m in interval.measurements if m.t <= end} | {end})
        outcomes: list[tuple[bool, float, float]] = []
        done, t = 0.0, interval.t0
        queue = list(interval.measurements)
        sink: list[ekf.Step] | None = [] if self._smoother and stop is None else None
        keep = sink is not None
        for cut in cuts:
            share = (cut - interval.t0) / duration if duration > 0.0 else 1.0
            part = share - done
            if cut > t:
                x, P, step = ekf.advance(
                    c, x, P, part * dl, part * dr, part * g, part * gv, cut - t, interval.slip, keep
                )
                if sink is not None and step is not None:
                    sink.append(step)
            done, t = share, cut
            while queue and queue[0].t <= cut:
                m = queue.pop(0)
                x, P, ok, score, log_det = ekf.absolute_update(x, P, m, *self._measured)
                outcomes.append((ok, score, log_det))
        if stop is None:
            interval.outcomes = outcomes
            interval.steps = sink or []
        return x, P

    def _replay(self, first: int) -> tuple[np.ndarray, np.ndarray]:
        """Run the intervals from ``first`` on, each from the end of the one before: the
        state and covariance now."""
        x, P = self._intervals[first].start
        for interval in self._intervals[first:]:
            interval.start = (x, P)
            x, P = self._run(interval)
        return x, P

    def _trim(self) -> None:
        newest = self._intervals[-1].t1
        while len(self._intervals) > 1 and self._intervals[1].t0 < newest - self._history:
            gone = self._intervals.pop(0)
            for ok, _, _ in gone.outcomes:
                self._settled[0 if ok else 1] += 1
