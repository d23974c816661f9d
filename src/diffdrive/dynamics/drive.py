"""Dynamic simulation: commands through a drive model to wheel velocities to poses.

``DriveModel`` says how each wheel's velocity (rad/s) answers its command:

- velocity-commanded (no ``feedforward``): the command acts after ``delay`` s, the wheel
  approaches ``gain`` times it as a first-order lag of ``time_constant`` s (0: at once), its
  acceleration at most ``max_acceleration`` rad/s^2 (``identify_velocity_response``'s model,
  integrated by its own exact step between samples and command changes);
- voltage-driven (a ``Feedforward``): the command is a voltage acting after ``delay`` s, and
  ``kA dw/dt = V - kS sgn(w) - kV w``, exact within each piece of constant sign; a wheel at
  rest stays at rest while ``|V| <= kS``, and one whose velocity would cross zero within a
  step stops there (static friction holds it, or the next step starts it the other way).

``simulate_commands`` drives robots with command histories through the model and integrates
the wheel velocities (each step's the mean of its ends) by ``diffdrive.simulate``, with its
backends and methods. Commands ``(..., M, 2)`` give a batch of robots.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive._validate import check_samples, finite, positive
from diffdrive.dynamics.lag import first_order
from diffdrive.dynamics.response import VelocityResponse, held_commands, simulate_response
from diffdrive.dynamics.voltage import Feedforward, VoltageResponse
from diffdrive.integrate import Method
from diffdrive.model import Robot
from diffdrive.simulation import simulate
from diffdrive.trajectory import Trajectory

__all__ = ["DriveModel", "simulate_commands"]


@dataclass(frozen=True)
class DriveModel:
    """How the wheels answer commands (see the module)."""

    delay: float = 0.0
    time_constant: float = 0.0
    gain: float = 1.0
    max_acceleration: float = math.inf
    feedforward: Feedforward | None = None

    def __post_init__(self) -> None:
        for name in ("delay", "time_constant"):
            value = finite(name, getattr(self, name))
            if value < 0.0:
                raise ValueError(f"{name} must be >= 0 s, got {value}")
        if finite("gain", self.gain) <= 0.0:
            raise ValueError(
                f"gain must be > 0 (the wheel's velocity per commanded), got {self.gain}"
            )
        limit = self.max_acceleration
        if isinstance(limit, str | bytes | bool) or not isinstance(limit, int | float | np.number):
            raise TypeError(f"max_acceleration must be a number > 0 (inf: none), got {limit!r}")
        if not limit > 0.0:
            raise ValueError(f"max_acceleration must be > 0 (inf: none), got {limit}")
        object.__setattr__(self, "max_acceleration", float(limit))
        ff = self.feedforward
        if ff is not None and not (ff.ks >= 0.0 and ff.kv > 0.0 and ff.ka > 0.0):
            raise ValueError(f"the feedforward needs kS >= 0, kV > 0 and kA > 0, got {ff}")

    @classmethod
    def from_response(cls, response: VelocityResponse | VoltageResponse) -> DriveModel:
        """The model an identification found."""
        if isinstance(response, VoltageResponse):
            return cls(delay=response.delay, feedforward=response.feedforward)
        return cls(response.delay, response.time_constant, response.gain, response.acceleration)

    def step(
        self, wheels: np.ndarray, commands: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """One period of ``dt`` s with ``commands`` held (rad/s; a voltage-driven model's
        commands are still wheel velocities, its feedforward's steady voltage for them is
        applied): the wheels' velocities at the end (any shape, rad/s) and their mean over
        the period, from ``wheels`` at its start. The delay is the caller's (whole periods);
        a closed loop (``control.follow``) steps through this. The mean is the lag's exact
        one for a held target; where the acceleration limit or static friction cuts the
        period short, the mean of its ends."""
        wheels, commands = np.asarray(wheels, dtype=float), np.asarray(commands, dtype=float)
        ff = self.feedforward
        if ff is None:
            end, mean = first_order(wheels, self.gain * commands, dt, self.time_constant)
            limit = self.max_acceleration * dt
            if limit == np.inf:
                return end, mean
            moved = np.clip(end - wheels, -limit, limit)
            cut = moved != end - wheels
            end = wheels + moved
            return end, np.where(cut, 0.5 * (wheels + end), mean)
        return self._voltage_step(wheels, ff.voltage(commands), dt, ff)

    def _voltage_step(self, w: np.ndarray, voltage: np.ndarray, dt: float, ff: Feedforward):
        """``step`` of the voltage-driven model, ``voltage`` held (see the module)."""
        direction = np.where(w != 0.0, np.sign(w), np.sign(voltage))
        stuck = (w == 0.0) & (np.abs(voltage) <= ff.ks)
        target = (voltage - ff.ks * direction) / ff.kv
        moved, mean = first_order(w, target, dt, ff.ka / ff.kv)
        # Crossing zero within the step: static friction stops the wheel there.
        crossed = (w != 0.0) & (np.sign(moved) != direction)
        end = np.where(stuck | crossed, 0.0, moved)
        return end, np.where(stuck | crossed, 0.5 * (w + end), mean)

    def wheel_velocities(
        self, times: object, command_times: object, commands: object, initial: object = None
    ) -> np.ndarray:
        """The wheels' velocities ``(..., N, 2)`` at ``times`` ``(N,)`` (s, increasing) of
        robots driven by ``commands`` ``(..., M, 2)`` held from ``command_times`` ``(M,)``
        (zero before the first), from ``initial`` ``(..., 2)`` (default rest) at
        ``times[0]``."""
        t = np.asarray(times, dtype=float)
        stamps = np.asarray(command_times, dtype=float)
        values = np.asarray(commands, dtype=float)
        if t.ndim != 1 or len(t) < 2 or not np.all(np.diff(t) > 0):
            raise ValueError("times must be 2 or more increasing stamps (s)")
        if stamps.ndim != 1 or len(stamps) < 1 or np.any(np.diff(stamps) <= 0):
            raise ValueError("command_times must be increasing stamps (s)")
        if values.shape[-2:] != (len(stamps), 2):
            raise ValueError(
                f"commands must be (..., {len(stamps)}, 2) for {len(stamps)} stamps, got "
                f"{values.shape}"
            )
        if not (
            np.all(np.isfinite(t)) and np.all(np.isfinite(stamps)) and np.all(np.isfinite(values))
        ):
            raise ValueError("times, command_times and commands must be finite")
        batch = values.shape[:-2]
        start = _initial(initial, batch, "initial")
        # Every wheel of every robot is a channel: (M, channels).
        channels = np.moveaxis(values.reshape(-1, len(stamps), 2), 1, 0).reshape(len(stamps), -1)
        first = start.reshape(-1)
        if self.feedforward is None:
            out = simulate_response(
                t,
                stamps,
                channels,
                self.delay,
                first,
                self.gain,
                self.time_constant,
                self.max_acceleration,
            )
        else:
            out = self._voltage_driven(t, stamps, channels, first)
        return np.moveaxis(out.reshape(len(t), -1, 2), 0, 1).reshape((*batch, len(t), 2))

    def _voltage_driven(self, t, stamps, volts, first) -> np.ndarray:
        ff = self.feedforward
        assert ff is not None
        out = np.empty((len(t), volts.shape[1]))
        out[0] = w = first.copy()
        applied = held_commands(stamps + self.delay, volts, t[:-1])
        for k, (step, voltage) in enumerate(zip(np.diff(t), applied, strict=True)):
            w = self._voltage_step(w, voltage, step, ff)[0]
            out[k + 1] = w
        return out


def _initial(given: object, batch: tuple[int, ...], name: str) -> np.ndarray:
    """The wheels' start ``(*batch, 2)`` rad/s (rest when None), or ``ValueError`` naming
    ``name``: finite, and one pair or one per robot."""
    if given is None:
        return np.zeros((*batch, 2))
    try:
        start = np.asarray(given, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be wheel velocities (left, right), got {given!r}") from None
    if start.shape[-1:] != (2,):
        raise ValueError(f"{name} must be (left, right) wheel velocities, got shape {start.shape}")
    try:
        start = np.broadcast_to(start, (*batch, 2))
    except ValueError:
        raise ValueError(
            f"{name} must be one (left, right) or one per robot {(*batch, 2)}, got {start.shape}"
        ) from None
    if not np.all(np.isfinite(start)):
        raise ValueError(f"{name} must be finite, got {start.tolist()}")
    return start


def simulate_commands(
    robot: Robot,
    model: DriveModel,
    command_times: object,
    commands: object,
    *,
    dt: float,
    duration: float | None = None,
    initial_pose: object = None,
    initial_wheels: object = None,
    method: Method = "exact",
) -> Trajectory:
    """Robots driven by wheel ``commands`` ``(..., M, 2)`` (rad/s, or V through a voltage
    model) held from ``command_times`` ``(M,)`` through ``model``, sampled every ``dt`` s for
    ``duration`` s (default: to the last command plus the delay and five time constants)
    from the first command's stamp; a ``Trajectory`` whose wheel velocities are each step's
    mean."""
    dt = positive("dt", dt)
    stamps = np.asarray(command_times, dtype=float)
    if stamps.ndim != 1 or len(stamps) < 1:
        raise ValueError("command_times must be one or more stamps (s)")
    if duration is None:
        settle = (
            model.time_constant
            if model.feedforward is None
            else (model.feedforward.ka / model.feedforward.kv)
        )
        duration = float(stamps[-1] - stamps[0]) + model.delay + 5.0 * settle + dt
    count = positive("duration", duration) / dt
    check_samples(count, f"{duration:g} s in steps of {dt:g} s", "is the step in seconds?")
    steps = max(math.ceil(count), 1)
    times = stamps[0] + dt * np.arange(steps + 1)
    batch = np.asarray(commands, dtype=float).shape[:-2]
    start = _initial(initial_wheels, batch, "initial_wheels")
    wheels = model.wheel_velocities(times, stamps, commands, start)
    means = 0.5 * (wheels[..., 1:, :] + wheels[..., :-1, :])
    trajectory = simulate(robot, means, dt=dt, initial_pose=initial_pose, method=method)
    return Trajectory(robot, times, trajectory.poses, means, method)  # type: ignore[arg-type]
