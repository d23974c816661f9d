"""What every synthetic sensor starts from: a trajectory, checked, and its motion per interval.

A trajectory is its sample ``times`` ``(T+1,)`` s, strictly increasing, and its ``poses``
``(T+1, 3)`` or, for a batch of robots, ``(N, T+1, 3)`` (a ``simulate`` result, or a
reference read from a file or bag). Its headings may be wrapped to any one turn, (-pi, pi] or
[0, 2 pi) alike (all within a span of 2 pi: each step then turns less than pi, and a jump
across the wrap is a small turn), or unwrapped (spanning more than a turn: each step's own
turn). Between two samples the body moves along the constant twist that joins them (the SE(2)
logarithm of the relative pose), as ``simulate``'s exact step does; so a trajectory that
``simulate`` made gives its own wheel motion back to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diffdrive import batch
from diffdrive.model import Robot, geometry_of
from diffdrive.sensor_noise import draw_geometry

__all__ = [
    "Motion",
    "checked_trajectory",
    "heading_span",
    "motion_of",
    "robot_count",
    "robot_geometry",
    "unwrapped",
]


@dataclass(frozen=True, eq=False)
class Motion:
    """A checked trajectory: ``times`` ``(T+1,)`` s, ``poses`` ``(B, T+1, 3)`` (``B`` is 1 for
    one trajectory shared by every robot), ``increments`` ``(B, T, 3)``: the body-frame twist
    of each interval times its duration, at the robot's equivalent-drive point."""

    times: np.ndarray
    poses: np.ndarray
    increments: np.ndarray

    @property
    def durations(self) -> np.ndarray:
        """Each step's length ``(T,)``, s."""
        return np.diff(self.times)

    @property
    def headings(self) -> np.ndarray:
        """The headings ``(B, T+1)`` rad made continuous by each interval's turn (a wrapped
        trajectory's unwrapped): what interpolation between samples reads."""
        turned = np.cumsum(self.increments[..., 2], axis=-1)
        first = self.poses[..., :1, 2]
        return np.concatenate([first, first + turned], axis=-1)

    def robots(self, robots: int | None) -> int:
        """How many robots: the batch's, or ``robots`` for one trajectory (default 1)."""
        return robot_count(self.poses.shape[0], robots)


def robot_count(batch_size: int, robots: int | None) -> int:
    """How many robots ride ``batch_size`` trajectories: one each, or ``robots`` on one
    trajectory (default 1); ``ValueError`` naming ``robots`` if neither."""
    if robots is None:
        return batch_size
    if isinstance(robots, bool) or not isinstance(robots, int | np.integer) or robots < 1:
        raise ValueError(f"robots must be a whole number from 1, got {robots!r}")
    if batch_size not in (1, robots):
        raise ValueError(f"robots={robots} for a batch of {batch_size} trajectories")
    return int(robots)


def motion_of(robot: Robot, times: object, poses: object) -> Motion:
    """``times`` and ``poses`` checked (``ValueError`` naming what is wrong), and the motion of
    the robot's equivalent-drive point between samples."""
    t, p = checked_trajectory(times, poses)
    moved = robot.to_reference(p)
    relative = batch.relative_to(moved[:, 1:], moved[:, :-1])
    increments = batch.log(relative)
    # The log wraps each turn to (-pi, pi]. Headings within one turn's span are read as
    # wrapped, as tools write them (a jump across the wrap is a small turn); spanning more,
    # they are unwrapped, and their own turn is kept (a fast spin may turn more than pi in a
    # sample).
    if unwrapped(p):
        increments[..., 2] = np.diff(p[..., 2], axis=-1)
    return Motion(t, p, np.asarray(increments))


def unwrapped(poses: np.ndarray) -> bool:
    """Whether a trajectory's headings are unwrapped: some robot's span more than a turn,
    which wrapped ones cannot (see the module)."""
    return heading_span(poses) > ONE_TURN


ONE_TURN = 2.0 * np.pi * (1.0 + 1e-12)  # a wrapped heading's span, and its rounding


def heading_span(poses: np.ndarray) -> float:
    """The largest span (max - min, rad) of one robot's headings in ``poses`` ``(..., T+1,
    3)``."""
    headings = poses[..., 2]
    return float((headings.max(axis=-1) - headings.min(axis=-1)).max())


def checked_trajectory(
    times: object, poses: object, finite: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """``times`` ``(T+1,)`` and ``poses`` ``(B, T+1, 3)`` (one trajectory: ``B`` 1) as float
    arrays, or ``ValueError`` naming what is wrong; ``finite=False`` leaves the poses'
    finiteness to a caller that reads them all anyway."""
    t = np.asarray(times, dtype=float)
    p = np.asarray(poses, dtype=float)
    if t.ndim != 1 or len(t) < 2:
        raise ValueError(f"times must be (T+1,) with T >= 1, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("times must be finite")
    steps = np.diff(t)
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0)) + 1
        raise ValueError(
            f"times must increase: times[{k}] = {float(t[k])!r} after {float(t[k - 1])!r}"
        )
    if p.ndim == 2:
        p = p[None]
    if p.ndim != 3 or p.shape[1:] != (len(t), 3):
        raise ValueError(
            f"poses must be ({len(t)}, 3) or (N, {len(t)}, 3) for {len(t)} times, got {p.shape}"
        )
    if finite and not np.all(np.isfinite(p)):
        raise ValueError(NOT_FINITE)
    return t, p


NOT_FINITE = "poses must be finite"


def robot_geometry(
    robot: Robot,
    robots: int,
    radius_bias: tuple[float, float],
    track_bias: float,
    geometry_sigma: tuple[float, float, float],
    rng: np.random.Generator,
) -> np.ndarray:
    """Each robot's true geometry ``(N, 3)`` ``[r_left, r_right, track]`` (m): the equivalent
    drive's, biased, and drawn around that with relative standard deviations
    ``geometry_sigma`` (as ``monte_carlo``'s)."""
    nominal = np.array(geometry_of(robot)[:3])
    biased = nominal * (1.0 + np.array([*radius_bias, track_bias]))
    return draw_geometry(biased, np.asarray(geometry_sigma, dtype=float), robots, rng)
