"""The pure-Python twin of the C core (``_odometry.c``), for where the extension is absent.

``diffdrive.estimation.odometry`` uses the C ``OdometryCore`` when it was built, and this one
otherwise (an installation without a C compiler, Pyodide); ``DIFFDRIVE_PURE_PYTHON=1`` picks
this one anyway. It follows the C file function by function, in the same order of operations,
with the same checks and messages: ``tests/test_odometry_python.py`` and the conformance table
of ``tests/test_backends.py`` hold the two equal. An update costs microseconds here instead of a
fraction of one.
"""

from __future__ import annotations

import math
from typing import Any

from diffdrive._step import METHODS, method_flags, move_jacobians, wheel_move
from diffdrive._validate import finite
from diffdrive.backends.settings import OdometrySettings

__all__ = ["OdometryCore"]

WINDOW_SAMPLES = 1024  # the velocity window keeps samples window / 1024 s apart at least
_INT64 = (-(1 << 63), (1 << 63) - 1)
Covariance = tuple[float, float, float, float, float, float, float, float, float]


def _add(total: float, compensation: float, term: float) -> tuple[float, float]:
    """Neumaier's compensated ``total + term``: the new total and compensation."""
    t = total + term
    if abs(total) >= abs(term):
        compensation += (total - t) + term
    else:
        compensation += (term - t) + total
    return t, compensation


def _propagate(cov: list[float], jp: list[float], jw: list[float], q: tuple[float, float]):
    """``J cov J^T + W diag(q) W^T``, J 3x3 and W 3x2, row-major lists."""
    jc = [
        jp[3 * i] * cov[j] + jp[3 * i + 1] * cov[3 + j] + jp[3 * i + 2] * cov[6 + j]
        for i in range(3)
        for j in range(3)
    ]
    return [
        jc[3 * i] * jp[3 * j]
        + jc[3 * i + 1] * jp[3 * j + 1]
        + jc[3 * i + 2] * jp[3 * j + 2]
        + jw[2 * i] * q[0] * jw[2 * j]
        + jw[2 * i + 1] * q[1] * jw[2 * j + 1]
        for i in range(3)
        for j in range(3)
    ]


def _number(name: str, field: str, value: object) -> float:
    """A finite float, or the C core's TypeError or ValueError."""
    try:
        if isinstance(value, bool):
            raise TypeError
        return finite(f"{name}: {field}", value)
    except TypeError:  # the C core's wording, text and booleans included
        raise TypeError(f"{name}: {field} must be a number, got {value!r}") from None


def _tick_reading(value: object, field: str, bits: int) -> int:
    """A counter reading: an int or a whole float within the counter's range."""
    name = "update_ticks"
    if isinstance(value, bool) or not hasattr(value, "__index__"):
        if isinstance(value, bool) or not hasattr(value, "__float__"):
            raise TypeError(f"{name}: {field} must be an integer counter reading, got {value!r}")
        number = float(value)
        if not (math.isfinite(number) and number == math.floor(number)):
            raise ValueError(f"{name}: {field} must be a whole counter reading, got {value!r}")
        reading = int(number)
    else:
        reading = value.__index__()
    if bits == 64 and (1 << 63) <= reading < (1 << 64):
        reading -= 1 << 64  # kept as its two's-complement bit pattern, as in C
    low = -(1 << (bits - 1)) if 0 < bits < 64 else _INT64[0]
    high = (1 << bits) - 1 if 0 < bits < 64 else _INT64[1]
    if not low <= reading <= high:
        if bits:
            span = f"from -2^{bits - 1} to 2^{bits} - 1, signed or unsigned"
            raise ValueError(
                f"{name}: {field} = {value!r} does not fit a {bits}-bit counter ({span})"
            )
        raise ValueError(
            f"{name}: {field} = {value!r} does not fit a 64-bit integer; give "
            "counter_bits for a counter that rolls over"
        )
    return reading


class OdometryCore:
    """The state and update of diffdrive.Odometry; use that class."""

    def __init__(self, settings: OdometrySettings) -> None:
        self._r_left, self._r_right, self._track, self._axle = settings.drive
        self._weight, self._chord = method_flags(METHODS[settings.method_code])
        counts = settings.ticks_per_revolution
        self._rad_per_tick = 2.0 * math.pi / counts if counts else 0.0
        self._max_wheel_speed = settings.max_wheel_speed
        self._counter_bits = settings.counter_bits
        self._k_left, self._k_right = settings.k
        self._window = settings.velocity_window
        self._pose = [0.0, 0.0, 0.0, 0.0]  # x, y, theta, distance: sums ...
        self._comp = [0.0, 0.0, 0.0, 0.0]  # ... and their compensations
        self._cov = [0.0] * 9
        self._time = math.nan
        self._ticks: tuple[int, int] | None = None
        self._positions: tuple[float, float] | None = None
        self._arcs = (0.0, 0.0)
        self._samples: list[tuple[float, float, float]] = []  # (t, arc left, arc right)

    # -- the maths of one step --------------------------------------------------------------

    def _step(self, theta: float, dl: float, dr: float):
        forward, sideways, turn = wheel_move(
            self._r_left, self._r_right, self._track, self._axle, dl, dr
        )
        dx, dy, by_forward, by_turn = move_jacobians(
            forward, self._axle, turn, self._weight, self._chord, theta
        )
        jac_pose = [1.0, 0.0, -dy, 0.0, 1.0, dx, 0.0, 0.0, 1.0]
        jac_wheels = [0.0] * 6
        dturn = (-1.0 / self._track, 1.0 / self._track)
        for w, radius in enumerate((self._r_left, self._r_right)):
            jac_wheels[w] = radius * (0.5 * by_forward[0] + dturn[w] * by_turn[0])
            jac_wheels[2 + w] = radius * (0.5 * by_forward[1] + dturn[w] * by_turn[1])
            jac_wheels[4 + w] = radius * dturn[w]
        return dx, dy, turn, jac_pose, jac_wheels, math.hypot(forward, sideways)

    # -- checks, the next state, and the commit ------------------------------------------------

    def _check(self, name: str, dl: float, dr: float, has_t: bool, t: float, dt: float) -> None:
        if not (math.isfinite(dl) and math.isfinite(dr)):
            raise ValueError(
                f"{name}: the wheel increments must be finite, got left {dl!r}, right {dr!r}"
            )
        if has_t and not math.isfinite(t):
            raise ValueError(
                f"{name}: the clock would pass the largest finite time: {t!r} s "
                f"after {self._time!r} s"
            )
        if has_t and dt < 0.0:
            raise ValueError(f"{name}: time went backwards: t = {t!r} s after {self._time!r} s")
        if has_t and dt == 0.0 and (dl != 0.0 or dr != 0.0):
            raise ValueError(
                f"{name}: time stands still at t = {t!r} s while the wheels moved: no velocity"
            )
        if dt > 0.0 and not math.isfinite(max(abs(dl), abs(dr)) / dt):
            worst = dl if abs(dl) > abs(dr) else dr
            raise ValueError(
                f"{name}: a wheel turned {worst!r} rad in {dt!r} s, a speed past the largest "
                "float: a glitch, or a time stamp in the wrong unit"
            )
        if dt > 0.0 and max(abs(dl), abs(dr)) > self._max_wheel_speed * dt:
            worst = dl if abs(dl) > abs(dr) else dr
            raise ValueError(
                f"{name}: a wheel turned {worst!r} rad in {dt!r} s, {abs(worst) / dt!r} rad/s, "
                f"over max_wheel_speed {self._max_wheel_speed!r} rad/s: a glitch, or a counter "
                "roll-over with the wrong counter_bits"
            )

    def _next(self, name: str, dl: float, dr: float):
        theta = self._pose[2] + self._comp[2]
        dx, dy, turn, jac_pose, jac_wheels, travel = self._step(theta, dl, dr)
        q = (
            self._k_left * abs(self._r_left * dl) / (self._r_left * self._r_left),
            self._k_right * abs(self._r_right * dr) / (self._r_right * self._r_right),
        )
        cov = _propagate(self._cov, jac_pose, jac_wheels, q)
        left, right = self._r_left * dl, self._r_right * dr
        moved = [
            _add(s, c, term)
            for s, c, term in zip(self._pose, self._comp, (dx, dy, turn, travel), strict=True)
        ]
        arcs = (self._arcs[0] + left, self._arcs[1] + right)
        finite = all(math.isfinite(s + c) for s, c in moved) and all(map(math.isfinite, arcs))
        what = "pose, distance or wheel travel"
        if finite and not all(map(math.isfinite, cov)):
            finite, what = False, "covariance"
        if not finite:
            raise ValueError(
                f"{name}: increments of {dl!r} and {dr!r} rad would make the "
                f"{what} overflow (not finite); refused, nothing changed"
            )
        return moved, cov, arcs

    def _push_sample(self, t: float) -> None:
        samples = self._samples
        sample = (t, *self._arcs)
        if samples and samples[-1][0] == t:  # the same instant: nothing moved
            samples[-1] = sample
            return
        if len(samples) >= 2 and t - samples[-2][0] < self._window / WINDOW_SAMPLES:
            samples[-1] = sample  # too close to the one before the newest: replace it
        else:
            samples.append(sample)
        # Keep one sample at or before the start of the window, so that it spans the window.
        drop = 0
        while len(samples) - drop >= 2 and samples[drop + 1][0] <= t - self._window:
            drop += 1
        del samples[:drop]

    def _commit(self, moved, cov, arcs, has_t: bool, t: float) -> None:
        self._pose = [s for s, _ in moved]
        self._comp = [c for _, c in moved]
        self._cov, self._arcs = cov, arcs
        if has_t:
            self._time = t
            self._push_sample(t)
        else:
            self._time = math.nan  # the clock is lost until the next time stamp
            self._samples.clear()

    def _update(self, name: str, dl: float, dr: float, has_t: bool, t: float) -> None:
        dt = t - self._time if has_t else math.nan
        self._check(name, dl, dr, has_t, t, dt)
        moved, cov, arcs = self._next(name, dl, dr)
        self._commit(moved, cov, arcs, has_t, t)

    def _time_of(self, name: str, t: object) -> tuple[bool, float]:
        return (False, math.nan) if t is None else (True, _number(name, "t", t))

    def _start_reference(self, name: str, has_t: bool, t: float) -> None:
        """A first reading only sets the reference: its time starts the clock and window."""
        if has_t:
            self._check(name, 0.0, 0.0, True, t, t - self._time)
            self._time = t
            self._push_sample(t)

    # -- the update methods ------------------------------------------------------------------

    def update_increments(self, left: float, right: float, t: float | None = None) -> None:
        """update_increments(left, right, t=None): wheel-angle increments since the last
        update, rad."""
        name = "update_increments"
        dl, dr = _number(name, "left", left), _number(name, "right", right)
        self._update(name, dl, dr, *self._time_of(name, t))

    def update_positions(self, left: float, right: float, t: float | None = None) -> None:
        """update_positions(left, right, t=None): accumulated wheel angles, rad."""
        name = "update_positions"
        a, b = _number(name, "left", left), _number(name, "right", right)
        has_t, time = self._time_of(name, t)
        if self._positions is None:
            self._start_reference(name, has_t, time)
        else:
            before = self._positions
            self._update(name, a - before[0], b - before[1], has_t, time)
        self._positions = (a, b)

    def _tick_change(self, before: int, after: int, field: str) -> int:
        bits = self._counter_bits
        if bits == 0:
            change = after - before
            if not _INT64[0] <= change <= _INT64[1]:
                raise ValueError(f"update_ticks: {field} changed by more than 2^63 counts")
            return change
        change = (after - before) % (1 << 64)
        if bits < 64:
            modulus = 1 << bits
            change &= modulus - 1
            return change - modulus if change >= modulus // 2 else change
        return change - (1 << 64) if change >= 1 << 63 else change

    def update_ticks(self, left: Any, right: Any, t: float | None = None) -> None:
        """update_ticks(left, right, t=None): absolute encoder counter readings."""
        name = "update_ticks"
        if self._rad_per_tick == 0.0:
            raise ValueError(
                "update_ticks needs ticks_per_revolution, which this Odometry was made without"
            )
        a = _tick_reading(left, "left", self._counter_bits)
        b = _tick_reading(right, "right", self._counter_bits)
        has_t, time = self._time_of(name, t)
        if self._ticks is None:
            self._start_reference(name, has_t, time)
        else:
            change_left = self._tick_change(self._ticks[0], a, "left")
            change_right = self._tick_change(self._ticks[1], b, "right")
            dl, dr = change_left * self._rad_per_tick, change_right * self._rad_per_tick
            self._update(name, dl, dr, has_t, time)
        self._ticks = (a, b)

    def update_velocities(self, left: float, right: float, dt: float | None = None) -> None:
        """update_velocities(left, right, dt): wheel velocities, rad/s, held over dt s."""
        name = "update_velocities"
        if dt is None:
            raise TypeError("update_velocities needs dt, s")
        a, b = _number(name, "left", left), _number(name, "right", right)
        step = _number(name, "dt", dt)
        if step <= 0.0:
            raise ValueError(f"{name}: dt must be > 0, got {dt!r}")
        # Without a clock, one starts at 0 s with these velocities.
        start = 0.0 if math.isnan(self._time) else self._time
        dl, dr = a * step, b * step
        self._check(name, dl, dr, True, start + step, step)
        moved, cov, arcs = self._next(name, dl, dr)
        if math.isnan(self._time):
            self._time = 0.0
            self._push_sample(0.0)
        self._commit(moved, cov, arcs, True, start + step)

    # -- what the Python class reads and sets -------------------------------------------------

    def _state(self) -> tuple[float, float, float, float, float]:
        x, y, theta, distance = (s + c for s, c in zip(self._pose, self._comp, strict=True))
        return x, y, theta, distance, self._time

    def _covariance(self) -> Covariance:
        c = self._cov
        return (c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8])

    def _wheel_arcs(self) -> tuple[float, float]:
        return self._arcs

    def _snapshot(self) -> Any:
        state = dict(vars(self))
        for name in ("_pose", "_comp", "_cov", "_samples"):
            state[name] = list(state[name])
        return state

    def _restore(self, snapshot: Any) -> None:
        vars(self).update(snapshot)
        for name in ("_pose", "_comp", "_cov", "_samples"):
            setattr(self, name, list(snapshot[name]))

    def _window_velocities(self) -> tuple[float, float, float] | None:
        if len(self._samples) < 2:
            return None
        (t0, l0, r0), (t1, l1, r1) = self._samples[0], self._samples[-1]
        span = t1 - t0
        return (l1 - l0) / span / self._r_left, (r1 - r0) / span / self._r_right, span

    def _set_pose(self, x: float, y: float, theta: float, covariance: Covariance) -> None:
        self._pose, self._comp, self._cov = [x, y, theta, 0.0], [0.0] * 4, [*covariance]

    def _jacobians(
        self, left: float, right: float
    ) -> tuple[Covariance, tuple[float, float, float, float, float, float]]:
        _, _, _, p, w, _ = self._step(self._pose[2] + self._comp[2], left, right)
        return (p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8]), (
            w[0],
            w[1],
            w[2],
            w[3],
            w[4],
            w[5],
        )

    def _run(
        self,
        kind: int,
        lefts: list[Any],
        rights: list[Any],
        thirds: list[Any],
        poses: Any,
        covariances: Any,
    ) -> tuple[int, str] | None:
        """Updates of ``kind`` (0 ticks, 1 positions, 2 increments, 3 velocities) row by row,
        each pose into ``poses`` (n, 3) and covariance into ``covariances`` (n, 3, 3) unless
        None; ``(k, message)`` for the first refused, after which the state is row k-1's."""
        if not 0 <= kind <= 3:
            raise ValueError("_run: kind must be 0 to 3")
        update = (
            self.update_ticks,
            self.update_positions,
            self.update_increments,
            self.update_velocities,
        )[kind]
        for k, (left, right, third) in enumerate(zip(lefts, rights, thirds, strict=True)):
            try:
                update(left, right, third)
            except (TypeError, ValueError) as refused:
                return k, str(refused)
            poses[k] = self._state()[:3]
            if covariances is not None:
                covariances[k] = [self._cov[0:3], self._cov[3:6], self._cov[6:9]]
        return None
