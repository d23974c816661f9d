"""Closed-loop simulation: trackers driving robots along a plan, through a real drive.

Every period ``dt`` each robot's tracker turns the pose its wheel odometry believes into a
twist, the twist becomes wheel commands (inverse kinematics), a ``Limiter`` (batched over
the robots) may limit them, they take effect ``delay`` s later (a pure delay, per robot),
and the wheels answer them as the ``drive`` does (a ``dynamics.DriveModel``: an identified
response's lag, gain and acceleration limit, or a voltage-driven wheel; by default a
first-order ``lag``), stepped period by period (``DriveModel.step``). The robot moves with the
wheels' mean velocity over the period by the library's integration step; the odometry
integrates the same wheel travel plus random-walk noise of variance ``k |travel|`` per wheel
(``wheel_noise``, as ``Odometry``'s), so the tracker sees what a robot would.

``delay_margin`` runs the same loop for a range of delays at once and reports the largest the
tracker stays on the path with: the margin *by simulation* along this plan.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive import batch
from diffdrive._validate import (
    check_samples,
    finite,
    floats,
    positive,
    rng_of,
    settings_of,
    whole,
)
from diffdrive.control.limiter import Limiter
from diffdrive.control.planning import Plan
from diffdrive.control.tracking import Tracker
from diffdrive.dynamics.drive import DriveModel
from diffdrive.evaluation import PathErrors, path_errors
from diffdrive.integrate import Method, check_method
from diffdrive.sensor_noise import NONE as NO_NOISE
from diffdrive.sensor_noise import WheelNoise, WheelNoiseLike, draw_travel

__all__ = ["FollowResult", "FollowSettings", "delay_margin", "follow"]


@dataclass(frozen=True, eq=False)
class FollowResult:
    """``times`` ``(T+1,)`` s; ``poses`` (true) and ``estimates`` (odometry) ``(N, T+1, 3)``;
    ``commands`` (sent) and ``wheel_velocities`` (the wheels' mean over each period)
    ``(N, T, 2)`` rad/s; ``delays`` ``(N,)`` s."""

    plan: Plan
    times: np.ndarray
    poses: np.ndarray
    estimates: np.ndarray
    commands: np.ndarray
    wheel_velocities: np.ndarray
    delays: np.ndarray

    def errors(self) -> PathErrors:
        """Cross-track, along-track and heading errors of the true poses against the plan."""
        reference = self.plan.sample(self.times)["pose"]
        return path_errors(self.plan.times, self.plan.poses, self.times, self.poses, reference)


def _per_robot(name: str, value: object, robots: int) -> np.ndarray:
    """``value`` as one number per robot ``(robots,)``: one, or ``robots`` of them."""
    given = floats(name, value)
    if given.shape not in ((), (1,), (robots,)):
        raise ValueError(
            f"{name} must be one number or one per robot ({robots}), got {given.size} values"
        )
    array = np.broadcast_to(given, (robots,)).copy()
    if not np.all(np.isfinite(array)) or np.any(array < 0.0):
        raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
    return array


def _start_poses(start: object, plan: Plan, robots: int) -> np.ndarray:
    """The robots' start poses ``(robots, 3)``: the plan's first, or ``start`` ``(3,)`` or
    ``(robots, 3)``."""
    if start is None:
        return np.broadcast_to(plan.poses[0], (robots, 3))
    poses = floats("start", start)
    if poses.shape not in ((3,), (robots, 3)):
        raise ValueError(
            f"start must be one pose (x, y, theta) or one per robot ({robots}, 3), got shape "
            f"{poses.shape}"
        )
    if not np.all(np.isfinite(poses)):
        raise ValueError(f"start must be finite poses, got {start!r}")
    return np.broadcast_to(poses, (robots, 3))


@dataclass(frozen=True, eq=False)
class FollowSettings:
    """How ``follow`` simulates: how many ``robots``, their ``start`` poses ``(3,)`` or
    ``(robots, 3)`` (None: the plan's first), ``settle`` s simulated after the plan ends, the
    odometry's ``wheel_noise`` (a ``WheelNoise``, m; none by default), the ``seed`` of its
    draws and the integration ``method``. Each is checked when made."""

    robots: int = 1
    start: object = None
    settle: float = 1.0
    wheel_noise: WheelNoiseLike = NO_NOISE
    seed: int | None = None
    method: Method = "exact"

    def __post_init__(self) -> None:
        object.__setattr__(self, "robots", whole("FollowSettings.robots", self.robots, 1))
        settle = finite("FollowSettings.settle", self.settle)
        if settle < 0.0:
            raise ValueError(f"FollowSettings.settle must be >= 0 s, got {self.settle!r}")
        object.__setattr__(self, "settle", settle)
        noise = WheelNoise.coerce(self.wheel_noise, "FollowSettings.wheel_noise")
        object.__setattr__(self, "wheel_noise", noise)
        rng_of(self.seed)  # a seed, or the refusal that names what is wrong
        check_method(self.method)


def follow(
    plan: Plan,
    tracker: Tracker,
    *,
    dt: float = 0.02,
    delay: object = 0.0,
    lag: float = 0.0,
    drive: DriveModel | None = None,
    limiter: Limiter | None = None,
    settings: FollowSettings | None = None,
) -> FollowResult:
    """Simulate robots following ``plan`` with ``tracker`` (see the module).

    ``delay``: s, one or one per robot, each a whole number of periods; ``lag``: the wheels'
    time constant (s; 0 for none); ``drive``: the wheels' response instead (its delay, unless
    ``delay`` is given, a whole number of periods; not with ``lag``); ``limiter``: a wheel
    ``Limiter`` (rad/s), its limits applied to every robot (``Limiter.batched``), from rest;
    ``settings``: how many robots, from where, for how long after the plan, with what
    odometry noise (``FollowSettings``; default one noise-free robot from the plan's start,
    1 s after it).
    """
    settings = settings_of(settings, FollowSettings)
    robots, start, settle = settings.robots, settings.start, settings.settle
    seed, method = settings.seed, settings.method
    if not isinstance(plan, Plan):
        raise TypeError(f"plan must be a Plan, got {type(plan).__name__}")
    dt = positive("dt", dt)
    lag = float(_per_robot("lag", lag, 1)[0])
    if drive is not None:
        if not isinstance(drive, DriveModel):
            raise TypeError(f"drive must be a DriveModel, got {type(drive).__name__}")
        if lag:
            raise ValueError("give the wheels' response as drive= or as lag=, not both")
        if not np.any(floats("delay", delay)):
            delay = drive.delay
    model = DriveModel(time_constant=lag) if drive is None else drive
    delays = _per_robot("delay", delay, robots)
    noise = settings.wheel_noise
    assert isinstance(noise, WheelNoise)  # coerced when the settings were made
    robot = plan.robot
    lags = np.rint(delays / dt).astype(int)
    off = np.flatnonzero(np.abs(delays / dt - lags) > 1e-9)
    if len(off):
        # Rounded, it would simulate another delay than the one asked for.
        raise ValueError(
            f"delay must be a whole number of periods dt ({dt} s): got {float(delays[off[0]])} s"
        )
    check_samples(
        robots * (plan.duration + settle) / dt,
        f"{robots} robots over {plan.duration + settle:.4g} s every {dt} s",
        "fewer robots, or a larger dt",
    )
    steps = max(math.ceil((plan.duration + settle) / dt), 1)
    times = plan.times[0] + dt * np.arange(steps + 1)
    poses = np.empty((robots, steps + 1, 3))
    poses[:, 0] = _start_poses(start, plan, robots)
    estimates = poses.copy()
    commands = np.zeros((robots, steps, 2))
    applied = np.zeros((robots, steps, 2))
    limited = limiter.batched(robots) if limiter is not None else None
    reset = getattr(tracker, "reset", None)
    if callable(reset):
        reset()  # a stateful tracker (``Predictive``) starts with nothing in flight
    rng = rng_of(seed)
    per_metre = robot.to_wheel_velocities((1.0, 0.0, 0.0)).to_array()  # wheel rad per m
    wheels = np.zeros((robots, 2))  # the wheels' velocities now (rad/s)
    rows = np.arange(robots)
    for k in range(steps):
        twist = np.asarray(tracker.command(plan, float(times[k]), estimates[:, k]), dtype=float)
        body = np.column_stack([twist[:, 0], np.zeros(robots), twist[:, 1]])
        sent = batch.to_wheel_velocities(robot, body)
        if limited is not None:
            sent = limited.step(sent, dt)
        commands[:, k] = sent
        source = k - lags
        target = np.where((source >= 0)[:, None], commands[rows, np.maximum(source, 0)], 0.0)
        wheels, mean = model.step(wheels, target, dt)
        applied[:, k] = mean
        moved = batch.to_twist(robot, mean)
        poses[:, k + 1] = batch.integrate.step(poses[:, k], moved, dt, method)
        travel = mean * dt
        if noise:
            metres = travel / np.abs(per_metre)
            travel = travel + draw_travel(metres, noise.k, rng) * np.abs(per_metre)
        believed = batch.to_twist(robot, travel / dt)
        estimates[:, k + 1] = batch.integrate.step(estimates[:, k], believed, dt, method)
    return FollowResult(plan, times, poses, estimates, commands, applied, lags * dt)


def delay_margin(
    plan: Plan,
    tracker: Tracker,
    *,
    dt: float = 0.02,
    lag: float = 0.0,
    known: float = 0.0,
    max_delay: float = 0.5,
    bound: float = 0.25,
    drive: DriveModel | None = None,
) -> float:
    """The largest pure actuation delay (s, a multiple of ``dt`` up to ``max_delay``) beyond
    the ``known`` one (what a ``Predictive`` tracker assumes) with which ``tracker`` keeps every
    robot within ``bound`` m of the path and within 90 degrees of its heading, along this
    ``plan`` with this ``lag``: by simulation, every delay at once; a delay counts only if
    every smaller one passes too. -1 if the tracker fails even at the known delay. ``drive``:
    the wheels' response instead of ``lag`` (its own delay left out: the delays tried are
    these)."""
    delays = known + dt * np.arange(round(max_delay / dt) + 1)
    result = follow(
        plan,
        tracker,
        dt=dt,
        delay=delays,
        lag=lag,
        drive=drive,
        settings=FollowSettings(robots=len(delays)),
    )
    errors = result.errors()
    with np.errstate(invalid="ignore"):
        fine = np.all(np.abs(errors.cross_track) <= bound, axis=1) & np.all(
            np.abs(errors.heading) <= math.pi / 2, axis=1
        )
    if not fine[0]:
        return -1.0
    failing = np.flatnonzero(~fine)
    return float((delays[failing[0] - 1] if len(failing) else delays[-1]) - known)
