"""Model predictive path integral control (MPPI; Williams et al., "Information theoretic MPC
for model-based reinforcement learning", ICRA 2017): a ``Tracker`` that plans by sampling.

Each cycle, for each robot: ``samples`` sequences of ``horizon`` twists ``(v, omega)`` are
drawn around the mean sequence (Gaussian, of standard deviations ``sigma``), driven from the
robot's pose through the commands already in flight (a ``delay`` of whole periods) and the
acceleration limits (``rollouts``, the compiled batch kernel where numba is), and scored by
``MPPICosts``. The mean moves by the information-theoretic weighted average of the
perturbations (``weighted_update``: weights ``exp(-(S - min S) / temperature)``), is smoothed
by a moving average of ``smoothing`` steps (the average of noisy samples is noisy, and a
wheel would follow its jitter), and its first twist is sent; shifted one period, it warm
starts the next cycle.

``MPPICosts`` are named terms, each with its weight (>= 0): the distance to the plan's pose at
each step's time (``position``, per m^2) and its heading error (``heading``, per rad^2), the
twist's size (``effort``) and change (``rate``), and each wheel's velocity beyond
``max_wheel_velocity`` (``wheel_limit``). The wheels' limit is
the controller's own; by default the plan's, which leaves no room to catch up: plan below the
wheels' limit and give the limit here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from diffdrive import batch
from diffdrive._validate import check_samples, nonnegative, positive, rng_of, whole
from diffdrive.control.planning import Plan
from diffdrive.control.rollouts import rollouts

__all__ = ["MPPI", "MPPICosts", "weighted_update"]


@dataclass(frozen=True)
class MPPICosts:
    """Each cost term's weight (see the module); every one finite and >= 0."""

    position: float = 50.0
    heading: float = 5.0
    effort: float = 0.01
    rate: float = 0.1
    wheel_limit: float = 100.0

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


class MPPI:
    """A sampling tracker (see the module). ``dt`` (s) is its period and step; ``delay`` (s,
    whole periods) the commands in flight it accounts for; ``max_acceleration`` ``(v,
    omega)`` in m/s^2 and rad/s^2 (None: none); ``max_wheel_velocity`` (rad/s; None: the
    plan's); ``seed`` for the sampling."""

    def __init__(
        self,
        *,
        samples: int = 512,
        horizon: int = 20,
        dt: float = 0.05,
        sigma: tuple[float, float] = (0.15, 0.4),
        temperature: float = 0.05,
        smoothing: int = 5,
        costs: MPPICosts | None = None,
        delay: float = 0.0,
        max_acceleration: tuple[float, float] | None = None,
        max_wheel_velocity: float | None = None,
        seed: int | None = None,
    ) -> None:
        self.samples, self.horizon = whole("samples", samples, 1), whole("horizon", horizon, 1)
        check_samples(self.samples * self.horizon, "MPPI's samples x horizon", "fewer samples")
        self.dt, self.temperature = positive("dt", dt), positive("temperature", temperature)
        self.smoothing = whole("smoothing", smoothing, 1)
        self.sigma = np.array([positive("sigma", s) for s in sigma])
        if self.sigma.shape != (2,):
            raise ValueError(f"sigma must be (v, omega) standard deviations, got {sigma!r}")
        self.costs = MPPICosts() if costs is None else costs
        if not isinstance(self.costs, MPPICosts):
            raise TypeError(f"costs must be MPPICosts, got {type(self.costs).__name__}")
        steps = delay / self.dt
        if not (math.isfinite(steps) and steps >= 0 and abs(steps - round(steps)) < 1e-9):
            raise ValueError(f"delay must be a whole number of dt ({dt} s) >= 0, got {delay!r}")
        self.delay_steps = round(steps)
        self.max_acceleration = max_acceleration
        self.max_wheel_velocity = None
        if max_wheel_velocity is not None:
            self.max_wheel_velocity = positive("max_wheel_velocity", max_wheel_velocity)
        self._rng = rng_of(seed)
        self.reset()

    def reset(self) -> None:
        """Forget the mean sequences and the commands in flight; the next call sets how many
        robots there are."""
        self._mean = np.zeros((0, self.horizon, 2))
        self._sent = np.zeros((0, self.delay_steps, 2))
        self._applied = np.zeros((0, 2))

    def command(self, plan: Plan, t: float, poses: np.ndarray) -> np.ndarray:
        """Each robot's twist ``(N, 2)`` to send now, from its pose ``(N, 3)``."""
        poses = np.asarray(poses, dtype=float)
        if poses.ndim != 2 or poses.shape[1] != 3:
            raise ValueError(f"poses must be (N, 3) [x, y, theta], got shape {poses.shape}")
        if len(self._mean) and len(self._mean) != len(poses):
            raise ValueError(f"expected {len(self._mean)} poses as before, got {len(poses)}")
        if not len(self._mean):
            self._mean = np.zeros((len(poses), self.horizon, 2))
            self._sent = np.zeros((len(poses), self.delay_steps, 2))
            self._applied = np.zeros((len(poses), 2))
        reference = plan.sample(t + self.dt * np.arange(1, self.horizon + 1))["pose"]
        sent = np.empty((len(poses), 2))
        for n, pose in enumerate(poses):
            noise = self._rng.standard_normal((self.samples, self.horizon, 2)) * self.sigma
            path, applied = rollouts(
                pose,
                self._mean[n] + noise,
                self.dt,
                in_flight=self._sent[n],
                current=self._applied[n],
                max_acceleration=self.max_acceleration,
            )
            step, _ = weighted_update(
                self.score(plan, path, applied, reference), noise, self.temperature
            )
            mean = _moving_average(self._mean[n] + step, self.smoothing)
            sent[n] = mean[0]
            self._applied[n] = self._next_applied(self._applied[n], self._sent[n], sent[n])
            self._mean[n] = np.concatenate([mean[1:], mean[-1:]])  # the next cycle's start
        if self.delay_steps:
            self._sent = np.concatenate([self._sent[:, 1:], sent[:, None]], axis=1)
        return sent

    def score(
        self, plan: Plan, poses: np.ndarray, twists: np.ndarray, reference: np.ndarray
    ) -> np.ndarray:
        """Each candidate's cost ``(K,)`` from its poses ``(K, T+1, 3)`` and applied twists
        ``(K, T, 2)``, against the plan's poses ``(T, 3)`` at the steps' times."""
        w = self.costs
        after = poses[:, 1:]
        gap = after[..., :2] - reference[None, :, :2]
        heading = batch.wrap_angle(after[..., 2] - reference[None, :, 2])
        cost = w.position * np.sum(gap * gap, axis=(1, 2)) + w.heading * np.sum(heading**2, 1)
        cost += w.effort * np.sum(twists * twists, axis=(1, 2))
        cost += w.rate * np.sum(np.diff(twists, axis=1) ** 2, axis=(1, 2))
        limit = self.max_wheel_velocity or plan.limits.max_wheel_velocity
        if limit is not None and w.wheel_limit:
            body = np.stack([twists[..., 0], np.zeros(twists.shape[:2]), twists[..., 1]], -1)
            excess = np.maximum(np.abs(batch.to_wheel_velocities(plan.robot, body)) - limit, 0.0)
            cost += w.wheel_limit * np.sum(excess * excess, axis=(1, 2))
        return cost

    def _next_applied(self, current, in_flight, sent) -> np.ndarray:
        """The twist the robot moves with over the next period: the oldest command in flight
        (or the one sent, without a delay), reached from ``current`` within the limits."""
        target = in_flight[0] if len(in_flight) else sent
        if self.max_acceleration is None:
            return target.copy()
        step = np.asarray(self.max_acceleration, dtype=float) * self.dt
        return current + np.clip(target - current, -step, step)


def _moving_average(sequence: np.ndarray, window: int) -> np.ndarray:
    """``sequence`` ``(T, 2)`` averaged over ``window`` steps, its ends held (1: as it is)."""
    if window <= 1:
        return sequence
    before, after = window // 2, window - 1 - window // 2
    padded = np.concatenate([np.repeat(sequence[:1], before, 0), sequence])
    padded = np.concatenate([padded, np.repeat(sequence[-1:], after, 0)])
    kernel = np.ones(window) / window
    return np.stack([np.convolve(padded[:, j], kernel, "valid") for j in range(2)], axis=-1)
