"""The result of a simulation: sample times, poses, and the wheel history that drove them.

Its arrays are of the library the history came in (NumPy, JAX, PyTorch, CuPy, ...), and so is
everything derived from them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diffdrive import batch
from diffdrive._arrays import device, floating, namespace
from diffdrive.integrate import Method
from diffdrive.model import DiffDrive

__all__ = ["Trajectory"]


@dataclass(frozen=True, eq=False, repr=False)
class Trajectory:
    """Poses at sample times, for one robot or a batch of them.

    ``times`` is ``(..., T+1)`` in s; ``poses`` is ``(..., T+1, 3)`` ``[x, y, theta]`` with
    ``theta`` unwrapped; ``wheel_velocities`` is ``(..., T, 2)`` in rad/s, each held over its
    step. The twists, wheel angles and distances are derived from those when asked for, in
    the arrays' library.
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
            f"[{float(self._xp.min(self.times[..., 0])):g}, "
            f"{float(self._xp.max(self.times[..., -1])):g}] s, "
            f"method={self.method!r}, final_pose={_short(self.final_pose)}, "
            f"dtype={self.poses.dtype}, robot={self.robot!r})"
        )

    @property
    def _xp(self):
        return namespace(self.poses)

    @property
    def steps(self) -> int:
        """The number of integration steps, T."""
        return self.poses.shape[-2] - 1

    @property
    def durations(self) -> np.ndarray:
        """The length of each step, s; ``(..., T)``."""
        return self._xp.diff(self.times, axis=-1)

    @property
    def twists(self) -> np.ndarray:
        """The body twist held over each step, ``(..., T, 3)`` ``[vx, vy, omega]``."""
        return batch.to_twist(self.robot, self.wheel_velocities)

    @property
    def wheel_positions(self) -> np.ndarray:
        """Wheel angles ``(..., T+1, 2)`` in rad, accumulated from 0 at the first sample."""
        xp = self._xp
        turned = xp.cumulative_sum(self.wheel_velocities * self.durations[..., None], axis=-2)
        return xp.concat([xp.zeros_like(turned[..., :1, :]), turned], axis=-2)

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
        xp, twists = self._xp, self.twists
        lengths = xp.hypot(twists[..., 0], twists[..., 1]) * self.durations
        return xp.concat(
            [xp.zeros_like(lengths[..., :1]), xp.cumulative_sum(lengths, axis=-1)], axis=-1
        )

    def sample(self, at: object) -> np.ndarray:
        """Poses ``(..., M, 3)`` at the times ``at`` ``(M,)``, s, along each step's arc.

        Inside a step the robot follows the constant-twist arc from the pose at the step's
        start; a sample at a sample time is the stored pose. Within a step this is exact for
        the ``exact`` method. Needs one-dimensional ``times``.
        """
        xp, times = self._xp, self.times
        if times.ndim != 1:
            raise ValueError(f"sample needs one-dimensional times, got {tuple(times.shape)}")
        t = floating(xp, at, "at")
        if t.ndim != 1:
            raise ValueError(f"at must be one-dimensional, got shape {tuple(t.shape)}")
        t = xp.astype(t, times.dtype)
        outside = (t < times[0]) | (t > times[-1]) | ~xp.isfinite(t)
        if bool(xp.any(outside)):
            first = int(xp.argmax(xp.astype(outside, xp.int8)))
            raise ValueError(
                f"at must lie within [{float(times[0])}, {float(times[-1])}] s, "
                f"got {float(t[first])}"
            )
        if self.steps == 0:  # one pose, at one time: every sample is that pose
            return xp.take(self.poses, xp.zeros(t.shape, dtype=xp.int64, device=device(t)), axis=-2)
        # A sample at times[-1] finds step T, the last pose, with no time left to move.
        step = xp.searchsorted(times, t, side="right") - 1
        wheels = xp.take(self.wheel_velocities, xp.clip(step, max=self.steps - 1), axis=-2)
        twists = batch.to_twist(self.robot, wheels)
        since = t - xp.take(times, step)
        return batch.compose(xp.take(self.poses, step, axis=-2), batch.exp(twists, since))

    def to_array(self) -> np.ndarray:
        """``[t, x, y, theta]`` rows, ``(..., T+1, 4)``."""
        xp = self._xp
        times = xp.broadcast_to(self.times, self.poses.shape[:-1])
        return xp.concat([xp.astype(times[..., None], self.poses.dtype), self.poses], axis=-1)


def _short(pose: np.ndarray) -> str:
    """One final pose as a short list, or the shape of many."""
    if pose.ndim == 1:
        return "[" + ", ".join(f"{float(pose[k]):.6g}" for k in range(pose.shape[0])) + "]"
    return f"<{tuple(pose.shape)} array>"
