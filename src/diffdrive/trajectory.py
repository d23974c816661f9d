"""The result of a simulation: sample times, poses, and the wheel history that drove them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diffdrive import batch
from diffdrive._arrays import floating
from diffdrive.integrate import Method
from diffdrive.model import DiffDrive

__all__ = ["Trajectory"]


@dataclass(frozen=True, eq=False, repr=False)
class Trajectory:
    """Poses at sample times, for one robot or a batch of them.

    ``times`` is ``(..., T+1)`` in s; ``poses`` is ``(..., T+1, 3)`` ``[x, y, theta]`` with
    ``theta`` unwrapped; ``wheel_velocities`` is ``(..., T, 2)`` in rad/s, each held over its
    step. The twists, wheel angles and distances are derived from those when asked for.
    """

    robot: DiffDrive
    times: np.ndarray
    poses: np.ndarray
    wheel_velocities: np.ndarray
    method: Method

    def __repr__(self) -> str:
        robots = self.poses.shape[:-2]
        batch_text = f"{'x'.join(map(str, robots))} robots, " if robots else ""
        return (
            f"Trajectory({batch_text}{self.steps} steps over "
            f"[{float(np.min(self.times[..., 0])):g}, {float(np.max(self.times[..., -1])):g}] s, "
            f"method={self.method!r}, final_pose={_short(self.final_pose)}, "
            f"dtype={self.poses.dtype}, robot={self.robot!r})"
        )

    @property
    def steps(self) -> int:
        """The number of integration steps, T."""
        return self.poses.shape[-2] - 1

    @property
    def durations(self) -> np.ndarray:
        """The length of each step, s; ``(..., T)``."""
        return np.diff(self.times, axis=-1)

    @property
    def twists(self) -> np.ndarray:
        """The body twist held over each step, ``(..., T, 3)`` ``[vx, vy, omega]``."""
        return batch.to_twist(self.robot, self.wheel_velocities)

    @property
    def wheel_positions(self) -> np.ndarray:
        """Wheel angles ``(..., T+1, 2)`` in rad, accumulated from 0 at the first sample."""
        turned = np.cumsum(self.wheel_velocities * self.durations[..., None], axis=-2)
        zero = np.zeros_like(turned[..., :1, :])
        return np.concatenate([zero, turned], axis=-2)

    @property
    def final_pose(self) -> np.ndarray:
        """The last pose, ``(..., 3)``."""
        return self.poses[..., -1, :]

    @property
    def wrapped_headings(self) -> np.ndarray:
        """Headings wrapped to (-pi, pi], ``(..., T+1)``."""
        return batch.wrap_angle(self.poses[..., 2])

    @property
    def distance(self) -> np.ndarray:
        """Distance travelled by the reference point since the start, m; ``(..., T+1)``.

        Within a step the twist is constant, so the reference point moves at the constant
        speed ``hypot(vx, vy)``.
        """
        twists = self.twists
        lengths = np.hypot(twists[..., 0], twists[..., 1]) * self.durations
        zero = np.zeros_like(lengths[..., :1])
        return np.concatenate([zero, np.cumsum(lengths, axis=-1)], axis=-1)

    def sample(self, at: object) -> np.ndarray:
        """Poses ``(..., M, 3)`` at the times ``at`` ``(M,)``, s, along each step's arc.

        Inside a step the robot follows the constant-twist arc from the pose at the step's
        start; a sample at a sample time is the stored pose. Within a step this is exact for
        the ``exact`` method. Needs one-dimensional ``times``.
        """
        if self.times.ndim != 1:
            raise ValueError(f"sample needs one-dimensional times, got {self.times.shape}")
        t = floating(np, at, "at", self.times)
        if t.ndim != 1:
            raise ValueError(f"at must be one-dimensional, got shape {t.shape}")
        outside = (t < self.times[0]) | (t > self.times[-1]) | ~np.isfinite(t)
        if outside.any():
            raise ValueError(
                f"at must lie within [{self.times[0]}, {self.times[-1]}] s, "
                f"got {t[np.argmax(outside)]}"
            )
        if self.steps == 0:  # one pose, at one time: every sample is that pose
            return self.poses[..., np.zeros(t.shape, dtype=int), :]
        # A sample at times[-1] finds step T, the last pose, with no time left to move.
        step = np.searchsorted(self.times, t, side="right") - 1
        wheels = self.wheel_velocities[..., np.minimum(step, self.steps - 1), :]
        twists = batch.to_twist(self.robot, wheels)
        return batch.compose(self.poses[..., step, :], batch.exp(twists, t - self.times[step]))

    def to_array(self) -> np.ndarray:
        """``[t, x, y, theta]`` rows, ``(..., T+1, 4)``."""
        times = np.broadcast_to(self.times, self.poses.shape[:-1])
        return np.concatenate([times[..., None].astype(self.poses.dtype), self.poses], axis=-1)


def _short(pose: np.ndarray) -> str:
    """One final pose as a short list, or the shape of many."""
    if pose.ndim == 1:
        return "[" + ", ".join(f"{float(v):.6g}" for v in pose) + "]"
    return f"<{pose.shape} array>"
