"""Stateful limits on commands: velocity, acceleration and jerk, with a command timeout.

A ``Limiter`` follows targets for a few channels at once: ``(v, omega)`` with
``Limiter.for_twist`` or the two wheels with ``Limiter.for_wheels``. Every channel has its own
``Limits``. Each call to ``step(target, dt)`` applies, in this order:

1. the timeout: with no new target for ``timeout`` s, the target becomes zero;
2. the velocity limits on the target (forward and reverse), all channels scaled by one
   factor, so the target's curvature is kept;
3. for each channel, the change it can make in ``dt`` toward its target under its
   acceleration limits (speeding up and slowing down, forward and reverse; a step through
   zero slows down, then speeds up the other way) and, with ``max_jerk``, under the jerk limit
   and the approach that lets the acceleration reach zero at the target;
4. one fraction for all channels: each moves the same fraction of the way to its target, the
   smallest fraction any channel allows. With jerk limits on every channel the fraction itself
   follows one jerk-limited profile, in limits that are the tightest channel's, whenever the
   acceleration points along the way to the target (from rest, say); otherwise, say when the
   target changes in mid-manoeuvre, each channel follows its own profile until the next
   target. From rest, or whenever the curvature is not changing, the output keeps the
   target's curvature, so desaturation after the limiter keeps it too.

The outputs never exceed the velocity and acceleration limits: a jerk-limited profile that
would run past a velocity limit stops at it, and one that would carry a channel past rest away
from its target (its acceleration left from a target that changed) stops at rest. The jerk
limit holds except where a hard limit overrides it: at rest, at a zero crossing into a
direction with a lower acceleration limit than the acceleration at the crossing, and on
reaching a velocity limit. A refused call (a non-finite
target, ``dt <= 0``, or a step whose output or acceleration would overflow to infinity, such
as from -1e308 to 1e308) raises ``ValueError`` and changes nothing; outputs are always finite.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from diffdrive._validate import floats

__all__ = ["Limiter", "Limits"]


def _number(name: str, value: object) -> float:
    """``value`` as a float, or an error naming ``name`` (no text, no integers beyond floats)."""
    if isinstance(value, str | bytes | bool):
        raise TypeError(f"{name} must be a number, got {value!r}")
    try:
        return float(value)  # type: ignore[arg-type]
    except OverflowError:
        raise ValueError(f"{name} must be finite, got an integer too large for a float") from None
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number, got {value!r}") from None


def _optional_limit(name: str, value: float | None, allow_zero: bool = False) -> float:
    if value is None:
        return math.inf
    number = _number(name, value)
    if math.isnan(number) or number < 0.0 or (number == 0.0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be {bound} (or None for no limit), got {value!r}")
    return number


@dataclass(frozen=True)
class Limits:
    """Limits of one channel, in its units (m/s, rad/s) and their rates; None: no limit.

    ``max_acceleration`` bounds speeding up and ``max_deceleration`` slowing down, both while
    moving forward (positive); the ``reverse`` ones while moving backward, defaulting to the
    forward ones. ``max_reverse_velocity`` defaults to ``max_velocity``; 0 forbids reversing.
    """

    max_velocity: float | None = None
    max_reverse_velocity: float | None = None
    max_acceleration: float | None = None
    max_deceleration: float | None = None
    max_reverse_acceleration: float | None = None
    max_reverse_deceleration: float | None = None
    max_jerk: float | None = None

    def __post_init__(self) -> None:
        for field in fields(self):
            _optional_limit(field.name, getattr(self, field.name), "velocity" in field.name)

    def bounds(self) -> np.ndarray:
        """``[v_fwd, v_rev, acc_fwd, dec_fwd, acc_rev, dec_rev, jerk]``, inf for no limit."""
        v = _optional_limit("max_velocity", self.max_velocity)
        acc = _optional_limit("max_acceleration", self.max_acceleration)
        dec = _optional_limit("max_deceleration", self.max_deceleration)
        dec = acc if self.max_deceleration is None else dec

        def or_default(value: float | None, default: float) -> float:
            return default if value is None else float(value)

        return np.array(
            [
                v,
                or_default(self.max_reverse_velocity, v),
                acc,
                dec,
                or_default(self.max_reverse_acceleration, acc),
                or_default(self.max_reverse_deceleration, dec),
                _optional_limit("max_jerk", self.max_jerk),
            ]
        )


@dataclass(frozen=True, eq=False)
class _Planned:
    """A limiter's next state: output, acceleration, target held and time since it came."""

    value: np.ndarray
    acceleration: np.ndarray
    target: np.ndarray
    since: float


class Limiter:
    """Targets in, limited commands out, for the channels of ``limits`` (one ``Limits`` each).

    ``timeout`` (s, default none) stops the robot when targets stop coming: ``step(None, dt)``
    means no new target this cycle. The state (``value``, ``acceleration``) starts at rest.
    ``batched(n)`` gives a limiter for ``n`` robots at once: its state, targets and outputs
    are ``(n, channels)``, each row limited as its own limiter would limit it.
    """

    def __init__(self, limits: tuple[Limits, ...], timeout: float | None = None) -> None:
        if not limits or not all(isinstance(item, Limits) for item in limits):
            raise TypeError("limits must be a non-empty tuple of Limits, one per channel")
        self.limits = tuple(limits)
        self.timeout = _optional_limit("timeout", timeout)
        self._bounds = np.stack([item.bounds() for item in limits], axis=-1)  # (7, channels)
        self.value = np.zeros(len(limits))
        self.acceleration = np.zeros(len(limits))
        self._target = np.zeros(len(limits))
        self._since_target = 0.0

    def batched(self, robots: int) -> Limiter:
        """A limiter with these limits and timeout for ``robots`` robots, at rest."""
        if isinstance(robots, bool) or not isinstance(robots, int) or robots < 1:
            raise ValueError(f"robots must be a whole number >= 1, got {robots!r}")
        many = Limiter(self.limits, None if math.isinf(self.timeout) else self.timeout)
        many.value = np.zeros((robots, len(self.limits)))
        many.reset()
        return many

    @classmethod
    def for_twist(cls, v: Limits, omega: Limits, timeout: float | None = None) -> Limiter:
        """A limiter for ``(v, omega)``: m/s and rad/s."""
        return cls((v, omega), timeout)

    @classmethod
    def for_wheels(cls, wheel: Limits, timeout: float | None = None) -> Limiter:
        """A limiter for ``(left, right)`` wheel velocities, rad/s, the same limits on each."""
        return cls((wheel, wheel), timeout)

    def step(self, target: object, dt: float) -> np.ndarray:
        """The limited command after ``dt`` s toward ``target`` (None: no new target)."""
        planned = self._plan(target, dt)
        self._commit(planned)
        return planned.value.copy()

    def _plan(self, target: object, dt: float) -> _Planned:
        """The next state toward ``target`` after ``dt`` s, checked, with nothing changed."""
        dt = _number("dt", dt)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be finite and > 0, got {dt!r}")
        if target is not None:
            target = self._vector("target", target)
        since = 0.0 if target is not None else self._since_target + dt
        held = self._target if target is None else target
        goal = np.zeros_like(held) if since >= self.timeout else self._within_velocity(held)
        with np.errstate(over="ignore", invalid="ignore"):
            new = self._reachable(goal, dt)
            if not np.isfinite(self._bounds[6]).any():
                gap = goal - self.value
                with np.errstate(divide="ignore"):
                    fractions = np.where(gap != 0.0, (new - self.value) / gap, 1.0)
                fraction = np.clip(fractions.min(axis=-1, keepdims=True), 0.0, 1.0)
                new = np.where(gap != 0.0, self.value + fraction * gap, goal)
            # A jerk profile may run past the goal; never past a velocity limit.
            new = np.clip(new, -self._bounds[1], self._bounds[0])
            acceleration = (new - self.value) / dt
        if not (np.all(np.isfinite(new)) and np.all(np.isfinite(acceleration))):
            raise ValueError(
                f"a step from {self.value.tolist()} toward {held.tolist()} in {dt!r} s would "
                "overflow to infinity; refused, nothing changed"
            )
        return _Planned(new, acceleration, held, since)

    def _commit(self, planned: _Planned) -> None:
        """Take the planned state (every check has passed)."""
        self.value, self.acceleration = planned.value, planned.acceleration
        self._target, self._since_target = planned.target, planned.since

    def reset(self, value: object = None) -> None:
        """Set the state to ``value`` (default rest) with zero acceleration and no target."""
        value = np.zeros_like(self.value) if value is None else self._vector("value", value)
        self.value, self._target = value.copy(), value.copy()
        self.acceleration = np.zeros_like(self.value)
        self._since_target = 0.0

    def _vector(self, name: str, value: object) -> np.ndarray:
        """``value`` as one finite float per channel, or an error naming ``name``."""
        array = floats(name, value)
        if array.shape != self.value.shape:
            raise ValueError(f"{name} must have shape {self.value.shape}, got {array.shape}")
        if not np.all(np.isfinite(array)):
            raise ValueError(f"{name} must be finite, got {array.tolist()}")
        return array

    def _within_velocity(self, target: np.ndarray) -> np.ndarray:
        """The target scaled by one factor so that every channel is within its velocity."""
        v_fwd, v_rev = self._bounds[0], self._bounds[1]
        limit = np.where(target >= 0.0, v_fwd, v_rev)
        with np.errstate(divide="ignore", over="ignore"):
            scale = np.where(np.abs(target) > limit, limit / np.abs(target), 1.0)
        return target * scale.min(axis=-1, keepdims=True)

    def _reachable(self, goal: np.ndarray, dt: float) -> np.ndarray:
        """Per channel, the value it can reach toward ``goal`` in ``dt`` under its limits."""
        v, a = self.value, self.acceleration
        if goal.ndim == 1 or not np.isfinite(self._bounds[6]).any():  # elementwise: at once
            return self._reachable_one(goal, v, a, dt)
        return np.array([self._reachable_one(goal[n], v[n], a[n], dt) for n in range(len(goal))])

    def _reachable_one(
        self, goal: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float
    ) -> np.ndarray:
        """``_reachable`` from the state ``v``, ``a``: one robot's, or (without jerk limits,
        where every step is elementwise) a batch's."""
        acc_fwd, dec_fwd, acc_rev, dec_rev, jerk = self._bounds[2:]
        gap = goal - v
        up = gap > 0.0
        # Accelerating upward: slowing down a reverse motion, or speeding up a forward one.
        forward = np.where(v != 0.0, v > 0.0, up)
        rising = np.where(forward, acc_fwd, dec_rev)
        falling = np.where(forward, dec_fwd, acc_rev)
        bound = np.where(up, rising, falling)
        # A step through zero: slow down to rest, then speed up the other way.
        other = np.where(up, acc_fwd, acc_rev)
        to_rest = np.abs(v) / bound
        crosses = ((v > 0.0) & ~up) | ((v < 0.0) & up)
        crosses &= to_rest < dt
        reach = np.where(crosses, np.abs(v) + other * (dt - to_rest), bound * dt)
        value = v + np.sign(gap) * np.minimum(reach, np.abs(gap))
        has_jerk = np.isfinite(jerk)
        if not has_jerk.any():
            return value
        rate = _rate_along(a, gap) if has_jerk.all() else None
        if rate is not None:
            # Every channel moves the same fraction of its gap, by one jerk-limited profile
            # of that fraction: the limits in fractions of the gap are the tightest channel's.
            moving = np.abs(gap) > 1e-9 * np.abs(gap).max()  # the others move too, a hair
            size = np.abs(gap[moving])
            toward = np.where(gap > 0.0, rising, falling)[moving] / size
            away = np.where(gap > 0.0, falling, rising)[moving] / size
            fraction = (
                _jerk_limited(
                    1.0,
                    rate,
                    toward.min(),
                    away.min(),
                    toward.min(),
                    (jerk[moving] / size).min(),
                    dt,
                )
                * dt
            )
            if abs(1.0 - fraction) <= 1e-12:
                return goal
            return _through_rest(v, v + fraction * gap, goal, acc_fwd, acc_rev, dt)
        jerk = np.where(has_jerk, jerk, 1.0)  # channels without a jerk limit: unused
        a_new = _jerk_limited(gap, a, bound, falling, rising, jerk, dt)
        # The acceleration decides the step, even past the goal: stopping short of it would
        # make the acceleration jump. The profile lands on the goal when it can.
        lands = np.abs(gap - a_new * dt) <= 1e-12 * np.maximum(1.0, np.abs(goal))
        stepped = _through_rest(v, v + a_new * dt, goal, acc_fwd, acc_rev, dt)
        return np.where(has_jerk, np.where(lands, goal, stepped), value)


def _through_rest(v, new, goal, acc_fwd, acc_rev, dt):
    """A jerk-limited step ``v`` -> ``new`` held to the hard limits at rest: it stops there
    rather than go on past it away from the ``goal`` (an acceleration left over from a target
    that changed would carry it the wrong way), and past rest toward the goal it speeds up
    the other way within that direction's acceleration limit, over the part of the step
    after rest (the acceleration of the step held)."""
    into_reverse, into_forward = (new < 0.0) & (v >= 0.0), (new > 0.0) & (v <= 0.0)
    # Past a goal of rest itself the profile may run on a little, as past any goal.
    away = (into_reverse & (goal > 0.0)) | (into_forward & (goal < 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        to_rest = np.where(v != 0.0, np.abs(v) * dt / np.abs(new - v), 0.0)
    speed = np.where(into_reverse, acc_rev, acc_fwd) * np.maximum(dt - to_rest, 0.0)
    crossing = into_reverse | into_forward
    limited = np.where(crossing, np.sign(new) * np.minimum(np.abs(new), speed), new)
    return np.where(away, 0.0, limited)


def _rate_along(a: np.ndarray, gap: np.ndarray) -> float | None:
    """The acceleration ``a`` as a rate of fractions of ``gap`` per s^2, if it points along the
    gap (or is zero), so that moving by fractions of the gap keeps the jerk limits; else
    None."""
    length = float(gap @ gap)
    if length < 1e-200:  # no gap, or one too small to divide by
        return None
    rate = float(a @ gap) / length
    if np.linalg.norm(a - rate * gap) > 1e-9 * np.linalg.norm(a):
        return None
    return rate


def _jerk_limited(gap, a, bound, falling, rising, jerk, dt):
    """The next acceleration toward ``gap``: at most ``bound`` toward it, within ``falling``
    and ``rising``, changed by at most ``jerk * dt``, and no more than the acceleration from
    which ramping down by ``jerk * dt`` a step still ends at rest on the goal:
    ``a dt + a (a - j dt) / (2 j) <= |gap|``."""
    j_dt = jerk * dt
    approach = 0.5 * (np.sqrt(j_dt**2 + 8.0 * jerk * np.abs(gap)) - j_dt)
    wanted = np.sign(gap) * np.minimum(np.minimum(bound, approach), np.abs(gap) / dt)
    return np.clip(np.clip(wanted, a - j_dt, a + j_dt), -falling, rising)
