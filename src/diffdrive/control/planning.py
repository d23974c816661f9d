"""Time-parameterised paths: the fastest timing of a path within every wheel's limits.

``plan(waypoints, robot, limits)`` samples the path (``diffdrive.control.path``) and times it
by a forward-backward pass (``diffdrive.control._timing``) so that at every state the chassis
speed and acceleration, the angular velocity and acceleration, the centripetal acceleration,
and **each wheel's** velocity, acceleration (with its ``v^2 dkappa/ds`` part) and, given a
feedforward, voltage stay within ``PathLimits``. The robot starts and ends at rest, and halts
wherever the path says (a stop, a change of direction, a turn in place). With ``max_jerk``
the fastest profile is averaged over a window in time (``_time_run``) and the plan's states
are then instants a few milliseconds apart rather than the path's samples.

``Plan`` holds the states; ``Plan.sample(t)`` gives pose, twist, curvature, wheel velocities
and accelerations at any time (constant acceleration between states, as the pass assumed);
``limit_ratios`` measures any timed path (ours or another library's) against limits, with
wheel accelerations by finite differences between states, so both are judged alike.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Sequence
from dataclasses import dataclass, fields
from functools import lru_cache
from typing import Any, cast

import numpy as np

from diffdrive._validate import check_samples, floats, positive
from diffdrive.control import _timing
from diffdrive.control.path import Leg, from_waypoints
from diffdrive.dynamics.voltage import Feedforward
from diffdrive.model import Robot, check_robot
from diffdrive.trajectory import Trajectory

__all__ = ["PathLimits", "Plan", "limit_ratios", "plan"]


@dataclass(frozen=True)
class PathLimits:
    """Limits a plan keeps at every state; None: no limit.

    Chassis: ``max_velocity`` (m/s), ``max_acceleration`` (m/s^2), ``max_angular_velocity``
    (rad/s), ``max_angular_acceleration`` (rad/s^2), ``max_centripetal_acceleration``
    (m/s^2). Each wheel: ``max_wheel_velocity`` (rad/s), ``max_wheel_acceleration``
    (rad/s^2), and ``max_voltage`` (V) through ``feedforward`` (one ``Feedforward`` for both
    wheels or ``(left, right)``, on wheel velocities in rad/s). ``max_jerk``: the rate of the
    acceleration along the path (m/s^3; rad/s^3 through a turn in place), from rest to rest.
    """

    max_velocity: float | None = None
    max_acceleration: float | None = None
    max_angular_velocity: float | None = None
    max_angular_acceleration: float | None = None
    max_centripetal_acceleration: float | None = None
    max_wheel_velocity: float | None = None
    max_wheel_acceleration: float | None = None
    max_voltage: float | None = None
    max_jerk: float | None = None
    feedforward: Feedforward | tuple[Feedforward, Feedforward] | None = None

    def __post_init__(self) -> None:
        for name in (*_NUMBERS, "max_jerk"):
            value = getattr(self, name)
            if value is None:
                continue
            if isinstance(value, bool):
                raise TypeError(f"{name} must be a number > 0 or None, got {value!r}")
            # NumPy's scalars are numbers too; text is not (positive refuses it by name).
            object.__setattr__(self, name, positive(name, value))
        wheel_feedforwards(self.max_voltage, self.feedforward)
        if (
            self.max_velocity is None
            and self.max_wheel_velocity is None
            and self.max_voltage is None
        ):
            raise ValueError(
                "no limit bounds the speed: give max_velocity, max_wheel_velocity or max_voltage"
            )

    def feedforwards(self) -> tuple[Feedforward | None, Feedforward | None]:
        """``(left, right)``."""
        return wheel_feedforwards(self.max_voltage, self.feedforward)

    def array(self) -> np.ndarray:
        """The kernel's limits, inf for none."""
        values = [getattr(self, name) for name in _NUMBERS]
        return np.array([math.inf if value is None else float(value) for value in values])


def wheel_feedforwards(
    max_voltage: float | None, feedforward: object
) -> tuple[Feedforward | None, Feedforward | None]:
    """A voltage limit's ``feedforward`` (one ``Feedforward`` for both wheels, or ``(left,
    right)``) as ``(left, right)``, checked: given with ``max_voltage`` or not at all, each
    a ``Feedforward`` with kS >= 0, kV > 0 and kA > 0, and kS below the limit (else the wheel
    could never start)."""
    if (max_voltage is None) != (feedforward is None):
        raise ValueError("max_voltage and feedforward go together: give both or neither")
    pair = feedforward if isinstance(feedforward, tuple) else (feedforward, feedforward)
    if len(pair) != 2:
        raise ValueError(f"feedforward must be one Feedforward or (left, right), got {pair!r}")
    for side, ff in zip(("left", "right"), pair, strict=True):
        if ff is None:
            continue
        if not isinstance(ff, Feedforward):
            raise TypeError(f"the {side} feedforward must be a Feedforward, got {ff!r}")
        if not (ff.ks >= 0.0 and ff.kv > 0.0 and ff.ka > 0.0):
            raise ValueError(f"the {side} feedforward needs kS >= 0, kV > 0, kA > 0: {ff}")
        if max_voltage is not None and ff.ks >= max_voltage:
            raise ValueError(
                f"max_voltage {max_voltage} V does not exceed the {side} wheel's kS "
                f"{ff.ks} V: the wheel could never start"
            )
    return pair[0], pair[1]


# The numeric limits in the order of the kernel's indices (``_timing.VMAX`` ... ``VOLTAGE``).
_NUMBERS = tuple(
    field.name for field in fields(PathLimits) if field.name not in ("feedforward", "max_jerk")
)
assert len(_NUMBERS) == _timing.VOLTAGE + 1
_JERK_ROUNDS = 60


def _wheel_map(robot: Robot) -> np.ndarray:
    """``(2, 2)``: wheel velocities (rad/s) per unit ``v`` and per unit ``omega`` (kept per
    robot model, which is immutable and hashable: sampling a plan asks for it every call)."""
    return _wheel_map_of(cast(Hashable, robot))


@lru_cache(maxsize=64)
def _wheel_map_of(robot: Any) -> np.ndarray:
    forward = robot.to_wheel_velocities((1.0, 0.0, 0.0)).to_array()
    turning = robot.to_wheel_velocities((0.0, 0.0, 1.0)).to_array()
    wheels = np.column_stack([forward, turning])
    wheels.flags.writeable = False
    return wheels


@dataclass(frozen=True, eq=False)
class Plan:
    """A timed path: ``N`` states.

    ``times`` (s), ``poses`` ``(N, 3)`` (heading unwrapped), ``speed`` ``u`` (m/s along a drive,
    rad/s through a turn; >= 0), ``accelerations`` (the path acceleration held from each state to
    the next; the last state repeats the one before), ``lin``, ``ang``, ``dang`` (the state's map
    from ``u`` to the twist: ``v = lin u``, ``omega = ang u``, ``domega/dt = ang a + dang u^2``),
    ``kappa`` (rad/m, of the path; 0 in a turn) and ``dkappa`` (rad/m^2).
    """

    robot: Robot
    limits: PathLimits
    times: np.ndarray
    poses: np.ndarray
    speed: np.ndarray
    accelerations: np.ndarray
    lin: np.ndarray
    ang: np.ndarray
    dang: np.ndarray
    kappa: np.ndarray
    dkappa: np.ndarray

    def __repr__(self) -> str:
        return f"Plan({len(self.times)} states, {self.duration:.3f} s, {self.length:.3f} m)"

    @property
    def duration(self) -> float:
        """s."""
        return float(self.times[-1] - self.times[0])

    @property
    def length(self) -> float:
        """m driven (turns in place add nothing)."""
        return float(np.sum(np.hypot(*np.diff(self.poses[:, :2], axis=0).T)))

    @property
    def twists(self) -> np.ndarray:
        """``(N, 2)``: ``(v, omega)`` in m/s and rad/s."""
        return np.column_stack([self.lin * self.speed, self.ang * self.speed])

    @property
    def twist_rates(self) -> np.ndarray:
        """``(N, 2)``: ``(dv/dt, domega/dt)``, with each state's acceleration toward the next."""
        a, u = self.accelerations, self.speed
        return np.column_stack([self.lin * a, self.ang * a + self.dang * u * u])

    @property
    def wheel_velocities(self) -> np.ndarray:
        """``(N, 2)`` rad/s."""
        return self.twists @ _wheel_map(self.robot).T

    @property
    def wheel_accelerations(self) -> np.ndarray:
        """``(N, 2)`` rad/s^2, each state's (toward the next)."""
        return self.twist_rates @ _wheel_map(self.robot).T

    @property
    def voltages(self) -> np.ndarray | None:
        """``(N, 2)`` V through the limits' feedforward, or None without one."""
        left, right = self.limits.feedforwards()
        if left is None or right is None:
            return None
        w, dw = self.wheel_velocities, self.wheel_accelerations
        return np.column_stack([left.voltage(w[:, 0], dw[:, 0]), right.voltage(w[:, 1], dw[:, 1])])

    def sample(self, t: object) -> dict[str, np.ndarray]:
        """The plan at times ``t`` (s; any shape, clamped to the plan): ``pose`` (..., 3),
        ``twist`` (..., 2) ``(v, omega)``, ``twist_rate`` (..., 2), ``kappa`` (robot curvature
        ``omega / v``, rad/m; NaN in a turn in place), ``wheel_velocities`` and
        ``wheel_accelerations`` (..., 2) in rad/s and rad/s^2.

        The pose lies on the path, at the share of the distance between two states that the
        speed's constant acceleration has covered. The twist goes in a straight line in time
        from one state's to the next, its rate that line's slope: so every wheel's velocity,
        acceleration and voltage between two states is what a controller stepping from one
        to the other sees, within the limits the states keep (the path's speed times its
        curvature, interpolated each, could leave them in between). Before the plan and after
        it the robot is at rest at its ends: no twist, and no rate."""
        given = floats("t", t)
        if np.isnan(given).any():
            raise ValueError("t must be times (s), not NaN")
        t = np.asarray(np.clip(given, self.times[0], self.times[-1]))
        i = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2)
        tau = t - self.times[i]
        a, u0 = self.accelerations[i], self.speed[i]
        gap = self.times[i + 1] - self.times[i]
        with np.errstate(invalid="ignore", divide="ignore"):
            travelled = u0 * tau + 0.5 * a * tau * tau
            whole = 0.5 * (u0 + self.speed[i + 1]) * gap
            f = np.where(whole > 0.0, np.clip(travelled / whole, 0.0, 1.0), 0.0)

        def along(values: np.ndarray) -> np.ndarray:
            start = values[i]
            return start + (values[i + 1] - start) * (f if values.ndim == 1 else f[..., None])

        lin, ang = along(self.lin), along(self.ang)
        twists = self.twists
        slope = (twists[i + 1] - twists[i]) / gap[..., None]
        outside = ((given < self.times[0]) | (given > self.times[-1]))[..., None]
        twist = np.where(outside, 0.0, twists[i] + slope * (t - self.times[i])[..., None])
        rate = np.where(outside, 0.0, slope)
        wheels = _wheel_map(self.robot)
        with np.errstate(invalid="ignore", divide="ignore"):
            kappa = np.where(lin != 0.0, ang / np.where(lin != 0.0, lin, 1.0), np.nan)
        return {
            "pose": along(self.poses),
            "twist": twist,
            "twist_rate": rate,
            "kappa": kappa,
            "wheel_velocities": twist @ wheels.T,
            "wheel_accelerations": rate @ wheels.T,
        }

    def to_trajectory(self, dt: float) -> Trajectory:
        """The plan sampled every ``dt`` s as a ``Trajectory`` (poses at the samples, each
        interval's wheel velocities those at its middle), for the writers and plots."""
        if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be a finite number > 0, got {dt!r}")
        if dt > self.duration:
            # One interval's wheel velocities (those at its middle) cannot carry the motion.
            raise ValueError(
                f"dt {dt:g} s exceeds the plan's {self.duration:.4g} s: its samples would not "
                "describe the motion; give a dt well below the duration"
            )
        check_samples(
            self.duration / dt, f"a plan of {self.duration:.4g} s every {dt} s", "a larger dt"
        )
        count = max(math.ceil(self.duration / dt), 1)
        times = self.times[0] + np.arange(count + 1) * dt
        middle = self.sample(times[:-1] + 0.5 * dt)["wheel_velocities"]
        robot: Any = self.robot  # a Trajectory takes any robot model
        return Trajectory(robot, times, self.sample(times)["pose"], middle, "exact")


def _join(run: list[Leg]) -> dict[str, np.ndarray]:
    """One run's legs as one sampled curve (the shared states kept once)."""
    parts: dict[str, list[np.ndarray]] = {
        key: [] for key in ("s", "x", "y", "heading", "kappa", "dkappa", "lin", "ang")
    }
    offset, heading_end = 0.0, None
    for number, leg in enumerate(run):
        keep = slice(0 if number == 0 else 1, None)
        heading = leg.heading
        if heading_end is not None:
            heading = heading + 2.0 * math.pi * round((heading_end - heading[0]) / (2 * math.pi))
        turn = leg.kind == "turn"
        parts["s"].append(offset + leg.s[keep])
        for key, values in (("x", leg.x), ("y", leg.y), ("heading", heading)):
            parts[key].append(values[keep])
        parts["kappa"].append(leg.kappa[keep])
        parts["dkappa"].append(leg.dkappa[keep])
        size = len(leg.s[keep])
        parts["lin"].append(np.zeros(size) if turn else np.full(size, float(leg.direction)))
        parts["ang"].append(np.full(size, float(leg.direction)) if turn else leg.kappa[keep])
        offset += leg.length
        heading_end = float(heading[-1])
    return {key: np.concatenate(values) for key, values in parts.items()}


_PROBLEMS = {
    _timing.UNBOUNDED: "no limit bounds the speed there (a turn in place needs "
    "max_angular_velocity, max_wheel_velocity or max_voltage)",
    _timing.STUCK: "the limits leave no acceleration to move on from rest",
    _timing.UNSETTLED: "the passes did not settle within the limits",
}


def _coefficients(curve: dict[str, np.ndarray], robot: Robot, limits: PathLimits) -> tuple:
    """The kernel's arrays for a sampled curve: ``(ds, lin, ang, dang, wc, wd, lim, ff)``."""
    wheels = _wheel_map(robot)
    lin, ang, dang = curve["lin"], curve["ang"], curve["dkappa"]
    wc = np.column_stack([lin, ang]) @ wheels.T
    wd = dang[:, None] * wheels[:, 1][None, :]
    ff = np.array(
        [[f.ks, f.kv, f.ka] if f is not None else [0.0, 1.0, 1.0] for f in limits.feedforwards()]
    )
    return np.diff(curve["s"]), lin, ang, dang, wc, wd, limits.array(), ff


def _fastest(arrays: tuple, ceiling: np.ndarray, curve: dict[str, np.ndarray], where: str):
    """The fastest speeds from rest to rest under the limits and ``ceiling``."""
    u = np.zeros(len(ceiling))
    status, state = _timing.kernel()(*arrays, ceiling, u)
    if status != _timing.OK:
        x, y, kappa = curve["x"][state], curve["y"][state], abs(curve["kappa"][state])
        bend = f"; the path's radius there is {1.0 / kappa:.3g} m" if kappa > 0.0 else ""
        raise ValueError(
            f"the path cannot be driven within the limits: {_PROBLEMS[status]} "
            f"({where}, at ({x:.3f}, {y:.3f}){bend})"
        )
    return u


def _profile(ds: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each segment's acceleration ``(N-1,)`` and the states' times ``(N,)`` of speeds ``u``."""
    accelerations = (u[1:] ** 2 - u[:-1] ** 2) / (2.0 * ds)
    return accelerations, np.concatenate([[0.0], np.cumsum(2.0 * ds / (u[1:] + u[:-1]))])


def _jerks(times: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """``(N,)``: at each state, how fast the rate of each interval ``rates`` ``(N-1, ...)``
    changes to the next: over the time between their middles, from rest before the first
    interval and to rest after the last."""
    middles = 0.5 * (times[1:] + times[:-1])
    spans = np.diff(np.concatenate([[times[0]], middles, [times[-1]]]))
    rest = np.zeros((1, *rates.shape[1:]))
    change = np.abs(np.diff(np.concatenate([rest, rates, rest]), axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        jerks = change / spans.reshape(-1, *([1] * (rates.ndim - 1)))
    return np.nan_to_num(jerks, nan=0.0, posinf=0.0)


def _smoothed(curve, u, window: float):
    """The speed profile ``u`` along ``curve`` averaged over ``window`` s in time, from rest
    to rest: a moving average changes the acceleration by at most its swing over the window,
    so a window of swing/jerk keeps the jerk limit. Returns the curve resampled at the
    averaged profile's instants (every ``window / 20`` s, at most 5 ms) and the speeds there."""
    ds = np.diff(curve["s"])
    a, times = _profile(ds, u)
    step = min(window / 20.0, 0.005)  # fine enough for rows a controller steps through
    check_samples(
        (times[-1] + 2.0 * window) / step,
        f"the jerk-limited profile (a window of {window:.4g} s over {times[-1]:.4g} s)",
        "is the jerk limit in m/s^3?",
    )
    t = np.arange(0.0, times[-1] + step, step)
    i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(ds) - 1)
    tau = np.minimum(t - times[i], times[i + 1] - times[i])
    speed = np.maximum(u[i] + a[i] * tau, 0.0)
    box = round(window / step)
    padded = np.concatenate([np.zeros(box), speed, np.zeros(box)])
    total = np.concatenate([[0.0], np.cumsum(padded)])
    average = (total[box:] - total[:-box]) / box
    moving = np.flatnonzero(average > 0.0)
    average = average[moving[0] - 1 : moving[-1] + 2]
    s = np.concatenate([[0.0], np.cumsum(0.5 * (average[1:] + average[:-1]) * step)])
    s *= curve["s"][-1] / s[-1]  # the same length to rounding: the average keeps the integral
    resampled = {key: np.interp(s, curve["s"], values) for key, values in curve.items()}
    resampled["s"] = s
    return resampled, average


def _time_run(curve: dict[str, np.ndarray], robot: Robot, limits: PathLimits, where: str):
    """One run's curve (resampled in time with a jerk limit), its speeds, accelerations (held
    from each state to the next) and times.

    With ``max_jerk`` the fastest profile is averaged over a window in time of its
    acceleration's swing over the jerk limit (a trapezoid of acceleration wherever the
    fastest profile switches). The averaged profile is checked against every limit; where it
    breaks one the fastest profile is capped below it there and averaged again, and where the
    jerk is still too high (between samples) the window widens."""
    arrays = _coefficients(curve, robot, limits)
    ceiling = np.full(len(curve["s"]), np.inf)
    u = _fastest(arrays, ceiling, curve, where)
    if limits.max_jerk is None:
        a, times = _profile(arrays[0], u)
        return curve, u, np.append(a, a[-1]), times
    widen = 1.0
    for _ in range(_JERK_ROUNDS):
        a = _profile(arrays[0], u)[0]
        swing = max(float(a.max()), 0.0) - min(float(a.min()), 0.0)
        window = widen * swing / limits.max_jerk
        smooth, speed = _smoothed(curve, u, window)
        checked = _coefficients(smooth, robot, limits)
        top = np.full(len(speed), np.inf)
        outside = _timing.checker()(*checked, speed, top)
        a_new, times = _profile(checked[0], speed)
        if outside:
            # Cap the fastest profile below the averaged one where it broke a limit.
            # The average reaches over a window: lower the fastest profile across it.
            broken = np.flatnonzero(np.isfinite(top))
            reach = speed[broken] * window
            low = np.searchsorted(curve["s"], smooth["s"][broken] - reach)
            high = np.searchsorted(curve["s"], smooth["s"][broken] + reach, side="right")
            for start, stop in zip(low, high, strict=True):
                ceiling[start:stop] = np.minimum(ceiling[start:stop], 0.97 * u[start:stop])
            u = _fastest(arrays, ceiling, curve, where)
        elif np.any(_jerks(times, a_new) > limits.max_jerk * (1.0 + 1e-9)):
            widen *= 1.1
        else:
            return smooth, speed, np.append(a_new, a_new[-1]), times
    # Where the last round still broke a limit (or, past the limits, the jerk's worst state).
    worst = (
        int(np.flatnonzero(np.isfinite(top))[0])
        if outside
        else int(np.argmax(_jerks(times, a_new)))
    )
    x, y, kappa = smooth["x"][worst], smooth["y"][worst], abs(smooth["kappa"][worst])
    bend = f"; the path's radius there is {1.0 / kappa:.3g} m" if kappa > 0.0 else ""
    raise ValueError(
        f"the path cannot be driven within the limits: the jerk limit was not met after "
        f"{_JERK_ROUNDS} rounds ({where}, at ({x:.3f}, {y:.3f}){bend})"
    )


def _runs_of_legs(given: object) -> bool:
    """Whether ``given`` is ``path.from_segments``' runs of legs, not rows of waypoints."""
    return (
        isinstance(given, list)
        and bool(given)
        and isinstance(given[0], list)
        and bool(given[0])
        and isinstance(given[0][0], Leg)
    )


def plan(
    waypoints: object,
    robot: Robot,
    limits: PathLimits,
    *,
    reverse: bool | Sequence[bool] = False,
    stops: Sequence[int] = (),
    step: float = 0.02,
) -> Plan:
    """The fastest timing of the path through ``waypoints`` within ``limits``, from rest to rest.

    ``waypoints``: ``(K, 2)`` or ``(K, 3)`` ``(x, y[, theta])`` (m, rad; see
    ``diffdrive.control.path.from_waypoints`` for the spline, ``reverse`` and ``stops``), or
    the runs of legs ``path.from_segments`` returns. ``step``: sample spacing (m or rad).
    """
    check_robot(robot)
    if not isinstance(limits, PathLimits):
        raise TypeError(f"limits must be PathLimits, got {type(limits).__name__}")
    runs: list[list[Leg]]
    if _runs_of_legs(waypoints):
        runs = waypoints  # type: ignore[assignment]
    else:
        runs = from_waypoints(waypoints, reverse=reverse, stops=stops, step=step)
    keys = ("times", "poses", "speed", "accelerations", "lin", "ang", "dang", "kappa", "dkappa")
    parts: dict[str, list[np.ndarray]] = {key: [] for key in keys}
    start, heading_end = 0.0, None
    for number, run in enumerate(runs):
        curve = _join(run)
        if heading_end is not None:
            curve["heading"] += (
                2.0 * math.pi * round((heading_end - curve["heading"][0]) / (2.0 * math.pi))
            )
        curve, u, a, times = _time_run(curve, robot, limits, f"run {number} of the path")
        parts["times"].append(start + times)
        parts["poses"].append(np.column_stack([curve["x"], curve["y"], curve["heading"]]))
        parts["speed"].append(u)
        parts["accelerations"].append(a)
        for key in ("lin", "ang", "kappa", "dkappa"):
            parts[key].append(curve[key])
        parts["dang"].append(curve["dkappa"])
        start += float(times[-1])
        heading_end = float(curve["heading"][-1])
    joined = {key: np.concatenate(values) for key, values in parts.items()}
    return Plan(robot, limits, **joined)


def limit_ratios(
    times: object, twists: object, robot: Robot, limits: PathLimits
) -> dict[str, np.ndarray]:
    """How far each state of a timed path uses each limit: value over limit, ``(N,)`` each
    (1 is at the limit), for the limits given. ``twists`` ``(N, 2)`` ``(v, omega)``;
    accelerations are finite differences to the next state (the last repeats), so any
    library's states are judged alike. Keys: ``velocity``, ``acceleration``,
    ``angular_velocity``, ``angular_acceleration``, ``centripetal``, ``wheel_velocity``,
    ``wheel_acceleration``, ``voltage`` (the worse wheel), ``jerk`` (the change of the
    acceleration along the path, or of a turn in place, over the time between neighbouring
    intervals, from rest to rest)."""
    t = np.asarray(times, dtype=float)
    twist = np.asarray(twists, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        rates = np.diff(twist, axis=0) / np.diff(t)[:, None]
    rates = np.nan_to_num(np.vstack([rates, rates[-1:]]), nan=0.0, posinf=0.0, neginf=0.0)
    wheels_map = _wheel_map(robot)
    wheels, wheel_rates = twist @ wheels_map.T, rates @ wheels_map.T
    # Jerk: the change of the acceleration between neighbouring intervals over the time
    # between their middles; along the path, or of the turn rate where the robot turns in
    # place (at rest at both ends of an interval).
    jerks = _jerks(t, rates[:-1])
    in_place = np.concatenate([[True], (twist[1:, 0] == 0.0) & (twist[:-1, 0] == 0.0)])
    jerk = np.where(in_place, jerks[:, 1], jerks[:, 0])
    values = {
        "velocity": (np.abs(twist[:, 0]), limits.max_velocity),
        "acceleration": (np.abs(rates[:, 0]), limits.max_acceleration),
        "angular_velocity": (np.abs(twist[:, 1]), limits.max_angular_velocity),
        "angular_acceleration": (np.abs(rates[:, 1]), limits.max_angular_acceleration),
        "centripetal": (np.abs(twist[:, 0] * twist[:, 1]), limits.max_centripetal_acceleration),
        "wheel_velocity": (np.abs(wheels).max(axis=1), limits.max_wheel_velocity),
        "wheel_acceleration": (np.abs(wheel_rates).max(axis=1), limits.max_wheel_acceleration),
        "jerk": (jerk, limits.max_jerk),
    }
    left, right = limits.feedforwards()
    if left is not None and right is not None:
        volts = np.column_stack(
            [
                left.voltage(wheels[:, 0], wheel_rates[:, 0]),
                right.voltage(wheels[:, 1], wheel_rates[:, 1]),
            ]
        )
        values["voltage"] = (np.abs(volts).max(axis=1), limits.max_voltage)
    return {key: value / limit for key, (value, limit) in values.items() if limit is not None}
