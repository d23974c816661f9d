"""Model predictive path integral control (MPPI; Williams et al., "Information theoretic MPC
for model-based reinforcement learning", ICRA 2017): a ``Tracker`` that plans by sampling.

Each cycle, for each robot, ``samples`` sequences of twist commands ``(v, omega)``, one a
period over the ``horizon`` (s; ``MPPISampling``), are drawn around the mean sequence
(Gaussian, standard deviations ``sigma``) and rolled out through the drive: first the commands
already in flight (``delay``, whole periods), then the candidate's; each period the command
becomes wheel targets (inverse kinematics, times the drive's ``gain``), each wheel follows its
target as the drive's first-order lag (time constant tau: over ``dt`` it ends at ``u + (w - u)
exp(-dt/tau)`` and moves with the lag's mean over the period) within its acceleration limit,
the robot moves with the wheels' mean (forward kinematics) by the exact SE(2) step. That is
``dynamics.DriveModel.step``; a voltage-driven model is rolled out as its lag ``kA/kV`` with
static friction left out.

Every candidate's cost is the sum over its steps of named terms, each with its weight in
``MPPICosts`` (>= 0):

- ``cross_track`` and ``along_track`` per m^2: the distance to the plan's pose at the step's
  time, across and along its heading (by default the first weighs 20 times the second: a
  robot behind its plan where it bends catches up along the path, not across the bend; at
  equal weights it cut the first bend of a plan started 0.1 s late by up to 166 mm);
  ``heading``: ``2 (1 - cos e)`` of the heading error ``e`` (``e^2`` for small errors);
- ``effort``: ``v^2 + omega^2`` of the twist moved with; ``rate``: the square of its change;
- ``wheel_limit``, ``acceleration_limit`` and ``voltage_limit``: the square of each wheel's
  velocity (rad/s), acceleration (rad/s^2) and feedforward voltage (V, ``kS sgn w + kV w + kA
  a``, the sign that of the period's start where the wheel ends at rest) beyond its limit
  (the controller's ``WheelLimits``, else the plan's ``PathLimits``): what is left of them
  where a candidate is projected, below;
- with ``obstacles`` (``control.Obstacles``) and a circular ``footprint`` of that radius (m):
  ``collision`` each step the footprint touches an obstacle, ``clearance`` times the square of
  how far the footprint is inside the ``inflation`` band (m) around them, the band narrowed
  at each step to the plan's own gap where the plan comes closer than that without touching
  (else a goal 0.1 m from a wall, inside a 0.3 m band, was never reached: the robot stopped
  where the band's cost met the tracking's, 193 mm short);
- ``goal`` per m^2: the distance from the plan's last pose at the horizon's end;
  ``progress`` per m: how far the horizon's end falls behind the plan's pose there.

Limits that hold: every command a candidate rolls out, and the one sent, is first projected
into what the drive can do from where its wheels are: each wheel's lag end over the period
brought within its velocity limit, then within its acceleration limit and its voltage limit
(which win where the wheel is past its velocity limit already, as physics would), and the
command that gives those ends (``_mppi_arrays.feasible_commands``). The sent command is
projected from the wheels' state when it takes effect, after the commands in flight; so a
drive that answers as its model says never leaves the limits.

Among obstacles the controller follows ``control.guide``'s plan: the given plan with every
stretch that comes too close to an obstacle replaced by the cheapest way around, made once. A
sampler sees only its horizon, and an obstacle squarely on the plan is a local minimum in
front of it (on the benchmark's cluttered corridors the plan as given stalled 5 to 14 runs in
20). The plan's time the steps are scored against runs at most ``lead`` s (0.1 by default)
ahead of the robot's own place on it, so a robot held back is led along the path, not pulled
across a corner to where it should have been.

A robot that stands (moves less than a quarter of ``Arrival.tolerance``) for ``Arrival.stall``
s, farther than the tolerance from the plan's last pose and from where the plan is by then
(a plan that creeps away slowly asks for no more), has stalled: it is given a way
of its own from where it stands to that pose (``plan`` within the plan's limits, through both
headings where the spline allows, routed around the obstacles by ``guide``) and follows it;
each stall is kept in ``MPPI.stalls`` with whether a way was made and, if not, why.

The update is the information-theoretic weighted average of the perturbations (weights
``exp(-(S - min S) / temperature)``), the result smoothed by a moving average over
``smoothing`` s (the average of noisy samples is noisy, and a wheel would follow its
jitter); its first twist is sent, and shifted one period it warm starts the next cycle.

Backends: ``"numba"`` runs the whole cycle (sampling, rollouts, costs, update) as one
compiled pass over every core (``backends.numba_mppi``); ``"numpy"``, ``"jax"`` and
``"torch"`` run it in that library (``control._mppi_arrays``), on its device; ``"auto"``:
numba where it is installed.
"""

from __future__ import annotations

import importlib.util
import math
import time
from dataclasses import dataclass, fields

import numpy as np

from diffdrive import batch
from diffdrive._validate import (
    check_samples,
    finite,
    floats,
    nonnegative,
    positive,
    rng_of,
    settings_of,
    whole,
)
from diffdrive.backends.settings import MPPISettings
from diffdrive.control._mppi_arrays import ArrayCycle, drive_period, feasible_commands
from diffdrive.control.clearance import guide
from diffdrive.control.obstacles import Obstacles
from diffdrive.control.planning import PathLimits, Plan, plan, wheel_feedforwards
from diffdrive.dynamics.drive import DriveModel
from diffdrive.dynamics.voltage import Feedforward

__all__ = [
    "MPPI",
    "Arrival",
    "Avoidance",
    "MPPICosts",
    "MPPISampling",
    "Stall",
    "WheelLimits",
    "weighted_update",
]

BACKENDS = ("auto", "numba", "numpy", "jax", "torch")
LANES = 16  # the compiled cycle's block of candidates (numba_mppi.LANES)
RECOUNT = 0.1  # s between counts of the free cores (MPPI._free_threads)


@dataclass(frozen=True)
class MPPICosts:
    """Each cost term's weight (see the module); every one finite and >= 0."""

    cross_track: float = 400.0
    along_track: float = 20.0
    heading: float = 5.0
    effort: float = 0.01
    rate: float = 0.1
    wheel_limit: float = 100.0
    acceleration_limit: float = 0.01
    voltage_limit: float = 100.0
    collision: float = 1e4
    clearance: float = 500.0
    goal: float = 0.0
    progress: float = 0.0

    def __post_init__(self) -> None:
        for term in fields(self):
            nonnegative(f"cost weight {term.name}", getattr(self, term.name))


def weighted_update(
    costs: np.ndarray, perturbations: np.ndarray, temperature: float
) -> tuple[np.ndarray, np.ndarray]:
    """The information-theoretic update: ``perturbations`` ``(K, ...)`` averaged with weights
    ``exp(-(S - min S) / temperature)`` of their ``costs`` ``(K,)``; ``(update, weights)``."""
    weights = np.exp(-(costs - costs.min()) / temperature)
    weights /= weights.sum()
    return np.tensordot(weights, perturbations, axes=1), weights


@dataclass(frozen=True, eq=False)
class MPPISampling:
    """How MPPI samples: ``samples`` candidates a cycle, each ``horizon`` s long (None: long
    enough for the delay, the lag's settling and a stop from full speed, ``default_horizon``),
    the perturbations' standard deviations ``sigma`` ``(v m/s, omega rad/s)``, the update's
    ``temperature``, the mean sequence's moving average over ``smoothing`` s, and the ``seed``
    of the draws. Both times are seconds, converted to steps at the controller's period, so
    the same settings hold at 20, 50 and 100 ms; an int there is refused, as it counted steps
    before. Each is checked when made."""

    samples: int = 1024
    horizon: float | None = None
    sigma: tuple[float, float] = (0.15, 0.4)
    temperature: float = 0.05
    smoothing: float = 0.25
    seed: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "samples", whole("MPPISampling.samples", self.samples, 1))
        for name in ("horizon", "smoothing"):
            value = getattr(self, name)
            if isinstance(value, int | np.integer) and not isinstance(value, bool):
                raise TypeError(
                    f"MPPISampling.{name} is in seconds; {value!r} is an int, as its count of "
                    f"steps was before: give seconds as a float ({value} steps at 0.05 s: "
                    f"{value * 0.05:g})"
                )
            if value is not None:
                object.__setattr__(self, name, positive(f"MPPISampling.{name} (s)", value))
        sigma = floats("MPPISampling.sigma", self.sigma)
        if sigma.shape != (2,) or not np.all(np.isfinite(sigma) & (sigma > 0)):
            raise ValueError(
                f"MPPISampling.sigma must be (v, omega) standard deviations > 0, got {self.sigma!r}"
            )
        object.__setattr__(self, "sigma", (float(sigma[0]), float(sigma[1])))
        temperature = positive("MPPISampling.temperature", self.temperature)
        object.__setattr__(self, "temperature", temperature)
        rng_of(self.seed)  # a seed, or the refusal that names what is wrong


def default_horizon(drive: DriveModel, stop: float | None, obstacles: bool) -> float:
    """The horizon (s) when none is given: the delay, three of the lag's time constants
    (95 % settled), and ``stop``, the time to stop from full speed (s; None: half a second),
    at least a second; half as long again among obstacles (on the benchmark's cluttered
    corridors 1 s left 4 runs of 150 stalled or late, 1.5 s left 1)."""
    seen = max(1.0, drive.delay + 3.0 * _rolled_lag(drive) + (0.5 if stop is None else stop))
    return 1.5 * seen if obstacles else seen


@dataclass(frozen=True)
class WheelLimits:
    """The wheels' limits MPPI keeps, whatever the plan says: ``max_velocity`` (rad/s),
    ``max_acceleration`` (rad/s^2) and ``max_voltage`` (V) through ``feedforward`` (one
    ``Feedforward`` on wheel velocities in rad/s for both wheels, or ``(left, right)``; given
    with ``max_voltage`` or not at all). A limit left None is the plan's."""

    max_velocity: float | None = None
    max_acceleration: float | None = None
    max_voltage: float | None = None
    feedforward: Feedforward | tuple[Feedforward, Feedforward] | None = None

    def __post_init__(self) -> None:
        for name in ("max_velocity", "max_acceleration", "max_voltage"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, positive(f"WheelLimits.{name}", value))
        wheel_feedforwards(self.max_voltage, self.feedforward)

    def feedforwards(self) -> tuple[Feedforward | None, Feedforward | None]:
        """``(left, right)``."""
        return wheel_feedforwards(self.max_voltage, self.feedforward)


@dataclass(frozen=True, eq=False)
class Avoidance:
    """What MPPI steers clear of: the ``obstacles`` (an ``Obstacles`` clearance grid), the
    robot's ``footprint`` (m, its radius) and an ``inflation`` (m) the clearance cost keeps
    beyond it; ``around``: follow ``guide``'s plan around them (False: the plan as given, the
    obstacle costs alone steering)."""

    obstacles: Obstacles
    footprint: float = 0.0
    inflation: float = 0.3
    around: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.obstacles, Obstacles):
            raise TypeError(
                f"Avoidance.obstacles must be Obstacles, got {type(self.obstacles).__name__}"
            )
        footprint = nonnegative("Avoidance.footprint", self.footprint)
        object.__setattr__(self, "footprint", footprint)
        object.__setattr__(self, "inflation", nonnegative("Avoidance.inflation", self.inflation))
        if not isinstance(self.around, bool | np.bool_):
            raise TypeError(f"Avoidance.around must be True or False, got {self.around!r}")


@dataclass(frozen=True)
class Arrival:
    """When a robot has arrived, and when it has stalled short of that: within
    ``tolerance`` m of the plan's last pose it has arrived; a robot farther off, and farther
    than that from where the plan is now, that has moved less than a quarter of ``tolerance``
    for ``stall`` s has stalled."""

    tolerance: float = 0.05
    stall: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "tolerance", positive("Arrival.tolerance", self.tolerance))
        object.__setattr__(self, "stall", positive("Arrival.stall (s)", self.stall))


@dataclass(frozen=True)
class Stall:
    """A robot found stalled (``Arrival``): its index ``robot``, the time ``t`` (s), its
    ``distance`` (m) from the plan's last pose then, and ``detour``: whether a way from where
    it stood to that pose was made for it to follow (False: ``why`` not)."""

    robot: int
    t: float
    distance: float
    detour: bool
    why: str = ""


class MPPI:
    """A sampling tracker (see the module).

    ``dt`` (s): its period and step; ``costs``: the cost terms' weights (``MPPICosts``);
    ``drive``: the wheels' response it rolls out (a ``DriveModel``; None: the wheels take each
    command at once); ``delay`` (s, whole periods; None: the drive's): the commands in flight
    it accounts for; ``limits``: the wheels' limits it keeps, whatever the plan says
    (``WheelLimits``; a limit not given: the plan's), every command it rolls out or sends
    projected into them; ``lead`` (s): how far the plan's time may
    run ahead of the robot's place on it; ``backend``: see the module; ``sampling``: how it
    samples (``MPPISampling``); ``avoid``: the obstacles it steers clear of (``Avoidance``;
    None: none); ``arrival``: when a robot has arrived or stalled (``Arrival``).

    A robot that stalls short of the goal (a local minimum its horizon cannot see past, such
    as an obstacle on a plan followed as given) gets a way of its own from where it stands to
    the plan's last pose, routed around the obstacles by ``guide``, and follows it from then
    on; each stall found is kept in ``stalls`` (``Stall``).
    """

    def __init__(
        self,
        *,
        dt: float = 0.05,
        costs: MPPICosts | None = None,
        drive: DriveModel | None = None,
        delay: float | None = None,
        limits: WheelLimits | None = None,
        lead: float = 0.1,
        backend: str = "auto",
        sampling: MPPISampling | None = None,
        avoid: Avoidance | None = None,
        arrival: Arrival | None = None,
    ) -> None:
        sampling = settings_of(sampling, MPPISampling)
        self.arrival = settings_of(arrival, Arrival)
        if avoid is not None and not isinstance(avoid, Avoidance):
            raise TypeError(f"avoid must be an Avoidance, got {type(avoid).__name__}")
        self.sampling, self.avoid = sampling, avoid
        self.dt, self.temperature = positive("dt", dt), sampling.temperature
        self.sigma = np.array(sampling.sigma)
        self.costs = MPPICosts() if costs is None else costs
        if not isinstance(self.costs, MPPICosts):
            raise TypeError(f"costs must be MPPICosts, got {type(self.costs).__name__}")
        if drive is not None and not isinstance(drive, DriveModel):
            raise TypeError(f"drive must be a DriveModel, got {type(drive).__name__}")
        self.drive = DriveModel() if drive is None else drive
        delay = self.drive.delay if delay is None else nonnegative("delay", delay)
        steps = delay / self.dt
        if not (math.isfinite(steps) and steps >= 0 and abs(steps - round(steps)) < 1e-9):
            raise ValueError(f"delay must be a whole number of dt ({dt} s) >= 0, got {delay!r}")
        self.delay_steps = round(steps)
        self.limits = WheelLimits() if limits is None else limits
        if not isinstance(self.limits, WheelLimits):
            raise TypeError(f"limits must be WheelLimits, got {type(limits).__name__}")
        self.max_wheel_velocity = self.limits.max_velocity
        self.max_wheel_acceleration = self.limits.max_acceleration
        horizon = sampling.horizon
        if horizon is None:
            stop = None
            if self.max_wheel_velocity is not None and self.max_wheel_acceleration is not None:
                stop = self.max_wheel_velocity / self.max_wheel_acceleration
            horizon = default_horizon(self.drive, stop, avoid is not None)
        self.samples, self.horizon = sampling.samples, max(1, round(horizon / self.dt))
        check_samples(self.samples * self.horizon, "MPPI's samples x horizon", "fewer samples")
        self.smoothing = max(1, round(sampling.smoothing / self.dt))
        # Without obstacles nothing reads the footprint, inflation or guide.
        self.obstacles = None if avoid is None else avoid.obstacles
        self.footprint = 0.0 if avoid is None else avoid.footprint
        self.inflation = 0.0 if avoid is None else avoid.inflation
        self.around = avoid is not None and bool(avoid.around)
        self.lead = positive("lead", lead)
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
        if backend == "auto":
            backend = "numba" if importlib.util.find_spec("numba") else "numpy"
        if backend == "numba" and not importlib.util.find_spec("numba"):
            raise ValueError("backend numba: numba is not installed (pip install diffdrive[fast])")
        self.backend = backend
        self._seed = sampling.seed
        self._settings: tuple[Plan, MPPISettings] | None = None
        self._guide: tuple[Plan, Plan] | None = None
        self.reset()

    def reset(self) -> None:
        """Forget the mean sequences, the commands in flight and the wheels' state; the next
        call sets how many robots there are."""
        self._mean = np.zeros((0, self.horizon, 2))
        self._counted = (-math.inf, 1)  # when the free cores were last counted, and how many
        self._sent = np.zeros((0, self.delay_steps, 2))
        self._wheels = np.zeros((0, 2))
        self._progress = np.zeros(0)
        self._still = np.zeros((0, 3))  # where each robot was last seen to move, and when
        self._detours: dict[int, tuple[float, Plan, MPPISettings]] = {}
        self.stalls: list[Stall] = []
        self._rng = rng_of(self._seed)
        self._arrays = None
        if self.backend != "numba":
            self._arrays = ArrayCycle(self.backend, self._seed)

    def command(self, plan: Plan, t: float, poses: np.ndarray) -> np.ndarray:
        """Each robot's twist ``(N, 2)`` to send now, from its pose ``(N, 3)`` at ``t`` s. A
        refused cycle (a time or pose that is no number, costs past float64's range: a pose
        far off the plan, weights too large) changes nothing, the draws included."""
        t = finite("t", t)
        poses = np.asarray(poses, dtype=float)
        if poses.ndim != 2 or poses.shape[1] != 3 or not np.all(np.isfinite(poses)):
            raise ValueError(f"poses must be finite (N, 3) [x, y, theta], got {poses.shape}")
        if len(self._mean) and len(self._mean) != len(poses):
            raise ValueError(f"expected {len(self._mean)} poses as before, got {len(poses)}")
        if not len(self._mean):
            self._check_start(poses)
        plan = self._guided(plan)
        q = self._settings_for(plan)
        if not len(self._mean):
            self._mean = np.zeros((len(poses), self.horizon, 2))
            self._sent = np.zeros((len(poses), self.delay_steps, 2))
            self._wheels = np.zeros((len(poses), 2))
            self._progress = np.full(len(poses), plan.times[0])
            self._still = np.column_stack([poses[:, :2], np.full(len(poses), t)])
        saved = self._cycle_state()
        try:
            return self._cycle(plan, q, t, poses)
        except BaseException:
            self._restore_cycle_state(saved)
            raise

    def _cycle(self, given: Plan, given_q, t: float, poses: np.ndarray) -> np.ndarray:
        """``command``'s cycle over the robots, its state moved on."""
        sent = np.empty((len(poses), 2))
        ahead = self.dt * np.arange(self.delay_steps + 1, self.delay_steps + self.horizon + 1)
        for n, pose in enumerate(poses):
            start, plan, q = self._detours.get(n, (0.0, given, given_q))
            if self._stalled(plan, start, n, pose, t):
                start, plan, q = self._make_detour(given, n, pose, t) or (start, plan, q)
            window = self.lead + ahead[-1]
            with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused below
                self._progress[n] = _progress(plan, pose[:2], self._progress[n], window)
                now = min(t - start, self._progress[n] + self.lead)
                on_plan = plan.sample(now + ahead)["pose"]
                step = self._step(q, n, pose, self._reference(on_plan))
            if not np.all(np.isfinite(step)):
                far = float(np.hypot(*(pose[:2] - on_plan[0, :2])))
                weight = max(getattr(self.costs, term.name) for term in fields(self.costs))
                raise ValueError(
                    f"robot {n}: every candidate's cost overflows float64 (its pose is {far:.3g} "
                    f"m from the plan; the largest cost weight is {weight:.3g}): no command"
                )
            mean = self._feasible(q, n, _moving_average(self._mean[n] + step, self.smoothing))
            sent[n] = mean[0]
            taking_effect = self._sent[n, :1] if self.delay_steps else sent[n : n + 1]
            self._wheels[n] = self._wheels_after(q, n, taking_effect)
            self._mean[n] = np.concatenate([mean[1:], mean[-1:]])  # the next cycle's start
        if self.delay_steps:
            self._sent = np.concatenate([self._sent[:, 1:], sent[:, None]], axis=1)
        return sent

    def _stalled(self, plan: Plan, start: float, n: int, pose: np.ndarray, t: float) -> bool:
        """Whether robot ``n`` at ``pose`` has stalled by ``t`` (``Arrival``) on ``plan``, which
        it follows from ``start`` s; it notes where a robot that moves was last seen."""
        tolerance, still = self.arrival.tolerance, self._still[n]
        if np.hypot(*(pose[:2] - still[:2])) >= 0.25 * tolerance:
            self._still[n] = (pose[0], pose[1], t)
            return False
        if t - still[2] < self.arrival.stall:
            return False
        # Stood still, neither where the plan ends nor where it is now (a plan may creep).
        now = plan.sample(np.array([t - start]))["pose"][0]
        return min(np.hypot(*(pose[:2] - at[:2])) for at in (now, plan.poses[-1])) > tolerance

    def _make_detour(
        self, given: Plan, n: int, pose: np.ndarray, t: float
    ) -> tuple[float, Plan, MPPISettings] | None:
        """Robot ``n``, stalled at ``pose`` at ``t``, given a way of its own to the plan's last
        pose (around the obstacles): when it starts, the way and its cycle's numbers; or None
        where there is none (the reason kept with the stall in ``stalls``)."""
        goal = given.poses[-1]
        distance = float(np.hypot(*(pose[:2] - goal[:2])))
        self._still[n] = (pose[0], pose[1], t)  # the next stall is a second from now
        try:
            way = _way_to(pose, goal, given)
            if self.obstacles is not None:
                way = guide(way, self.obstacles, self.footprint, inflation=self.inflation)
        except ValueError as error:
            self.stalls.append(Stall(n, t, distance, False, str(error)))
            return None
        self.stalls.append(Stall(n, t, distance, True))
        self._detours[n] = (t, way, settings(self, way))
        self._progress[n] = way.times[0]
        return self._detours[n]

    def _wheels_after(self, q, n: int, commands: np.ndarray) -> np.ndarray:
        """Robot ``n``'s wheels (rad/s) after the twist ``commands`` ``(D, 2)``, a period
        each, by the drive the cycle rolls out."""
        if self.backend == "numba":
            from diffdrive.backends import numba_mppi

            return numba_mppi.in_flight(np.zeros(3), self._wheels[n], commands, q)[4:6]
        wheels = self._wheels[n]
        for command in commands:
            wheels = drive_period(q, wheels, command)
        return wheels

    def _feasible(self, q, n: int, mean: np.ndarray) -> np.ndarray:
        """Robot ``n``'s mean sequence ``(T, 2)`` projected into what the drive can do from
        where its wheels will be when the first takes effect, after the commands in flight."""
        at_effect = self._wheels_after(q, n, self._sent[n])
        if self.backend == "numba":
            from diffdrive.backends import numba_mppi

            return numba_mppi.feasible(mean, q, at_effect)
        return feasible_commands(q, at_effect, mean)

    def _cycle_state(self) -> tuple:
        """What a cycle changes: the robots' mean sequences, commands in flight, wheels,
        progress, stall watch, detours and stalls, and where the draws stand."""
        arrays = None if self._arrays is None else self._arrays.generator_state()
        return (
            self._mean.copy(),
            self._sent.copy(),
            self._wheels.copy(),
            self._progress.copy(),
            self._still.copy(),
            dict(self._detours),
            list(self.stalls),
            self._rng.bit_generator.state,
            arrays,
        )

    def _restore_cycle_state(self, saved: tuple) -> None:
        self._mean, self._sent, self._wheels, self._progress = saved[:4]
        self._still, self._detours, self.stalls, rng, arrays = saved[4:]
        self._rng.bit_generator.state = rng
        if self._arrays is not None:
            self._arrays.restore_generator(arrays)

    def sampled(self, plan: Plan, pose: object, count: int = 64, robot: int = 0) -> np.ndarray:
        """Where ``count`` candidates drawn around ``robot``'s mean sequence would take it from
        ``pose`` ``(3,)``: positions ``(count, T, 2)`` after the commands in flight, for a
        picture (as Nav2's ``visualize``). Drawn by NumPy, seeded by the robot's index (the
        same candidates each call), apart from the controller's own sampling, which it leaves
        as it was; after at least one ``command``."""
        if not len(self._mean):
            raise ValueError(
                "sampled shows the candidates of a running controller: call command first"
            )
        plan = self._guided(plan)
        q = self._settings_for(plan)
        arrays = ArrayCycle("numpy", robot)
        noise = arrays.draw((self.horizon, 2, whole("count", count, 1)), self.sigma)
        start = floats("pose", pose)
        steps: list = []
        reference = self._reference(np.tile([*start[:2], 0.0], (self.horizon, 1)))
        arrays.costs(
            q,
            self._mean[robot],
            noise,
            start,
            self._wheels[robot],
            self._sent[robot],
            reference,
            None,
            positions=steps,
        )
        return np.stack([np.stack(xy, axis=-1) for xy in steps], axis=1)

    def _reference(self, on_plan: np.ndarray) -> np.ndarray:
        """The steps' reference ``(T, 5)``: the plan's poses ``on_plan`` ``(T, 3)`` as x, y,
        cos, sin, and the clearance band there (m): the ``inflation``, narrowed to the plan's
        own gap where the plan itself comes closer to an obstacle without touching it, so that
        a plan (a goal) inside the band is not a place the robot is pushed away from."""
        heading = on_plan[:, 2]
        band = np.full(len(on_plan), self.inflation)
        if self.obstacles is not None:
            gap = self.obstacles.clearance_at(on_plan[:, :2]) - self.footprint
            band = np.where(gap >= 0.0, np.minimum(band, gap), band)
        return np.column_stack([on_plan[:, :2], np.cos(heading), np.sin(heading), band])

    def _step(self, q, n: int, pose: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """The update ``(T, 2)`` of robot ``n``'s mean sequence."""
        grid = None if self.obstacles is None else self.obstacles.clearance
        if self.backend == "numba":
            import numba

            from diffdrive.backends import numba_mppi

            padded = -(-self.samples // LANES) * LANES
            noise = np.empty((self.horizon, 2, padded), dtype=np.float32)
            costs = np.empty(padded)
            state = numba_mppi.in_flight(pose, self._wheels[n], self._sent[n], q)
            seed = np.uint64(self._rng.integers(0, 2**63))
            step = np.empty((self.horizon, 2))
            pool = numba.get_num_threads()
            numba.set_num_threads(self._free_threads())  # the cores no one else holds
            try:
                numba_mppi.cycle(
                    self._mean[n],
                    q,
                    state,
                    reference,
                    np.zeros((2, 2)) if grid is None else grid,
                    seed,
                    True,
                    noise,
                    costs,
                )
                numba_mppi.update(
                    costs[: self.samples], noise[:, :, : self.samples], self.temperature, step
                )
            finally:
                numba.set_num_threads(pool)
            return step
        arrays = self._arrays
        assert arrays is not None  # made by reset for every backend but numba
        noise = arrays.draw((self.horizon, 2, self.samples), self.sigma)
        costs = arrays.costs(
            q, self._mean[n], noise, pose, self._wheels[n], self._sent[n], reference, grid
        )
        return arrays.update(costs, noise, self.temperature)[0]

    def _free_threads(self) -> int:
        """The threads the compiled cycle may use (``numba_mppi.free_threads``), counted again
        at most every ``RECOUNT`` s. Just after a cycle the count takes 0.1 to 0.4 ms, which
        had made a 2,048 x 100 cycle on a busy machine 2 to 9 % slower than one forced onto
        one thread; a core taken or freed is still seen within two periods at 20 Hz."""
        from diffdrive.backends import numba_mppi

        now = time.monotonic()
        if now - self._counted[0] >= RECOUNT:
            self._counted = (now, numba_mppi.free_threads())
        return self._counted[1]

    def _check_start(self, poses: np.ndarray) -> None:
        """Refuse a start whose footprint touches an obstacle, naming the robot."""
        if self.obstacles is None:
            return
        gaps = self.obstacles.clearance_at(poses[:, :2]) - self.footprint
        inside = np.flatnonzero(gaps < 0.0)
        if len(inside):
            n = int(inside[0])
            raise ValueError(
                f"robot {n} starts inside an obstacle: at ({poses[n, 0]:.3f}, {poses[n, 1]:.3f})"
                f" its footprint of {self.footprint} m overlaps one by {-gaps[n]:.3f} m"
            )

    def _guided(self, plan: Plan) -> Plan:
        """The plan this controller follows: among obstacles, ``guide``'s (made once)."""
        if not isinstance(plan, Plan):
            raise TypeError(f"plan must be a Plan, got {type(plan).__name__}")
        if self.obstacles is None or not self.around:
            return plan
        if self._guide is None or self._guide[0] is not plan:
            made = guide(plan, self.obstacles, self.footprint, inflation=self.inflation)
            self._guide = (plan, made)
        return self._guide[1]

    def _settings_for(self, plan: Plan) -> MPPISettings:
        """The cycle's numbers for this plan's robot and limits (``_guided`` checked it)."""
        if self._settings is not None and self._settings[0] is plan:
            return self._settings[1]
        q = settings(self, plan)
        self._settings = (plan, q)
        return q


def settings(mppi: MPPI, plan: Plan):
    """``MPPISettings`` of ``mppi`` for ``plan`` (see the module)."""
    robot, limits, drive, dt = plan.robot, plan.limits, mppi.drive, mppi.dt
    to_wheels = batch.to_wheel_velocities(robot, np.array([[1.0, 0, 0], [0, 0, 1.0]]))
    to_body = batch.to_twist(robot, np.eye(2))  # (wheel, (forward, sideways, turn))
    tau = _rolled_lag(drive)
    if drive.feedforward is not None:  # rolled out as its lag, static friction left out
        gain, step = 1.0, math.inf
    else:
        gain, step = drive.gain, drive.max_acceleration * dt
    decay = math.exp(-dt / tau) if tau > 0 else 0.0
    voltage: WheelLimits | PathLimits = mppi.limits
    if voltage.max_voltage is None:
        voltage = limits
    feedforwards = voltage.feedforwards() if voltage.max_voltage is not None else (None, None)
    volts = [(ff.ks, ff.kv, ff.ka) if ff is not None else (0.0, 0.0, 0.0) for ff in feedforwards]
    w, obstacles = mppi.costs, mppi.obstacles
    return MPPISettings(
        dt=dt,
        a00=to_wheels[0, 0],
        a01=to_wheels[1, 0],
        a10=to_wheels[0, 1],
        a11=to_wheels[1, 1],
        b00=to_body[0, 0],
        b01=to_body[1, 0],
        b10=to_body[0, 1],
        b11=to_body[1, 1],
        b20=to_body[0, 2],
        b21=to_body[1, 2],
        gain=gain,
        decay=decay,
        lag_mean=tau / dt * (1.0 - decay),
        wheel_step=step,
        cross_track=w.cross_track,
        along_track=w.along_track,
        heading=w.heading,
        effort=w.effort,
        rate=w.rate,
        wheel_limit=w.wheel_limit,
        max_wheel_velocity=_first(mppi.max_wheel_velocity, limits.max_wheel_velocity),
        acceleration_limit=w.acceleration_limit,
        max_wheel_acceleration=_first(mppi.max_wheel_acceleration, limits.max_wheel_acceleration),
        voltage_limit=w.voltage_limit if voltage.max_voltage is not None else 0.0,
        max_voltage=_first(voltage.max_voltage),
        ks_left=volts[0][0],
        kv_left=volts[0][1],
        ka_left=volts[0][2],
        ks_right=volts[1][0],
        kv_right=volts[1][1],
        ka_right=volts[1][2],
        voltage_bound=1.0 if voltage.max_voltage is not None else 0.0,
        ka_dt_left=volts[0][2] / dt,
        ka_dt_right=volts[1][2] / dt,
        volts_left=_per_volt(volts[0], dt),
        volts_right=_per_volt(volts[1], dt),
        undecay=1.0 / (1.0 - decay),
        collision=w.collision,
        clearance=w.clearance,
        footprint=mppi.footprint,
        inflation=mppi.inflation,
        origin_x=obstacles.origin[0] if obstacles else 0.0,
        origin_y=obstacles.origin[1] if obstacles else 0.0,
        resolution=obstacles.resolution if obstacles else 1.0,
        has_map=1.0 if obstacles else 0.0,
        goal=w.goal,
        progress=w.progress,
        goal_x=plan.poses[-1, 0],
        goal_y=plan.poses[-1, 1],
        sigma_v=mppi.sigma[0],
        sigma_omega=mppi.sigma[1],
    )


def _way_to(pose: np.ndarray, goal: np.ndarray, given: Plan) -> Plan:
    """A plan from ``pose`` to ``goal`` (both ``(3,)``) within ``given``'s robot and limits:
    through both headings, else (a spline with a cusp: the goal behind or beside the robot)
    through both places, the robot turning to the way's heading first."""
    try:
        return plan([pose, goal], given.robot, given.limits)
    except ValueError:
        return plan([pose[:2], goal[:2]], given.robot, given.limits)


def _rolled_lag(drive: DriveModel) -> float:
    """The lag's time constant (s) the rollouts use: a voltage-driven model's kA / kV."""
    ff = drive.feedforward
    return drive.time_constant if ff is None else ff.ka / ff.kv


def _per_volt(gains: tuple[float, float, float], dt: float) -> float:
    """``1 / (kV + kA / dt)``: a wheel's velocity at a period's end per volt, from rest; 0
    without a feedforward (no voltage limit)."""
    _, kv, ka = gains
    return 1.0 / (kv + ka / dt) if kv > 0.0 else 0.0


def _first(*limits: float | None) -> float:
    """The first limit given, inf if none."""
    return float(next((limit for limit in limits if limit is not None), math.inf))


def _progress(plan: Plan, point: np.ndarray, since: float, window: float) -> float:
    """The plan's time (s) where it passes nearest ``point``, among its states from ``since``
    to ``since + window`` and the stretches between them (``point`` projected onto the two
    beside the nearest state, the time from the stretch's speed and acceleration): where the
    robot is along the plan. Continuous, and timed as the plan moves: by the nearest state
    alone, a robot on a slow plan's first stretch stayed at its start until half the stretch
    on (and, timed linearly, behind where it was), and the plan led from there asked for no
    more than where it stood, so it stood."""
    times, xy = plan.times, plan.poses[:, :2]
    first = max(int(np.searchsorted(times, since, side="right")) - 1, 0)
    last = max(min(int(np.searchsorted(times, since + window)) + 1, len(times)), first + 1)
    gaps = np.sum((xy[first:last] - point) ** 2, axis=1)
    nearest = first + int(np.argmin(gaps))
    best, at = float(gaps[nearest - first]), float(times[nearest])
    for a in (nearest - 1, nearest):
        if a < first or a + 1 >= last:
            continue
        stretch = xy[a + 1] - xy[a]
        length = float(stretch @ stretch)
        if length == 0.0:  # a turn in place
            continue
        share = min(max(float((point - xy[a]) @ stretch) / length, 0.0), 1.0)
        gap = float(np.sum((xy[a] + share * stretch - point) ** 2))
        if gap < best:
            best, at = gap, float(times[a]) + _time_along(plan, a, share * math.sqrt(length))
    return max(since, at)


def _time_along(plan: Plan, state: int, distance: float) -> float:
    """The time (s) the plan takes from ``state`` to ``distance`` m along the stretch after
    it, at the state's speed and the stretch's held acceleration (at most the stretch's)."""
    span = float(plan.times[state + 1] - plan.times[state])
    speed, acceleration = float(plan.speed[state]), float(plan.accelerations[state])
    # d = u t + a t^2 / 2, solved in the form that keeps its digits as a or u goes to 0.
    root = speed + math.sqrt(max(speed * speed + 2.0 * acceleration * distance, 0.0))
    return min(2.0 * distance / root, span) if root > 0.0 else span


def _moving_average(sequence: np.ndarray, window: int) -> np.ndarray:
    """``sequence`` ``(T, 2)`` averaged over ``window`` steps, its ends held (1: as it is)."""
    if window <= 1:
        return sequence
    before, after = window // 2, window - 1 - window // 2
    padded = np.concatenate([np.repeat(sequence[:1], before, 0), sequence])
    padded = np.concatenate([padded, np.repeat(sequence[-1:], after, 0)])
    kernel = np.ones(window) / window
    return np.stack([np.convolve(padded[:, j], kernel, "valid") for j in range(2)], axis=-1)
