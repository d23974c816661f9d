"""Differential-drive kinematics over arrays.

Wheels are ``(..., 2)`` arrays ``[left, right]`` in rad/s (velocities) or rad (positions);
twists are ``(..., 3)`` arrays ``[vx, vy, omega]``. The same formulas as ``DiffDrive``'s
methods; leading axes broadcast and the floating dtype is kept.
"""

from __future__ import annotations

import math
from typing import Any

from diffdrive._arrays import components, finite_positive_dt, leading_shape, namespace
from diffdrive.batch.se2 import TWIST
from diffdrive.model import DiffDrive
from diffdrive.skid_steer import SkidSteer

__all__ = [
    "advance_wheel_positions",
    "instantaneous_center",
    "to_twist",
    "to_wheel_velocities",
    "turning_radius",
    "wheel_velocities_from_positions",
]

WHEELS = "left, right"


def _wheels(xp: Any, value: object, name: str = "wheels") -> Any:
    return components(xp, value, name, WHEELS)


def to_twist(robot: DiffDrive | SkidSteer, wheels: object) -> Any:
    """Body twists ``(..., 3)`` from wheel velocities ``(..., 2)`` (forward kinematics).

    A ``SkidSteer`` goes through its equivalent drive, its twist moved to the body origin.
    """
    xp = namespace(wheels)
    w = _wheels(xp, wheels)
    drive: DiffDrive = robot.equivalent if isinstance(robot, SkidSteer) else robot
    shift = robot.reference_offset if isinstance(robot, SkidSteer) else 0.0
    left = drive.left_wheel_radius * w[..., 0]
    right = drive.right_wheel_radius * w[..., 1]
    omega = (right - left) / drive.track_width
    forward = 0.5 * (right + left) + shift * omega if shift else 0.5 * (right + left)
    return xp.stack([forward, drive.axle_offset * omega, omega], axis=-1)


def to_wheel_velocities(robot: DiffDrive | SkidSteer, twists: object) -> Any:
    """Wheel velocities ``(..., 2)`` that drive ``twists`` ``(..., 3)``; ``vy`` is not used."""
    xp = namespace(twists)
    v = components(xp, twists, "twists", TWIST)
    if isinstance(robot, SkidSteer):  # its equivalent drive, at its reference point
        shift, robot = robot.reference_offset, robot.equivalent
        v = xp.stack([v[..., 0] - shift * v[..., 2], v[..., 1], v[..., 2]], axis=-1)
    half_turn = 0.5 * robot.track_width * v[..., 2]
    return xp.stack(
        [
            (v[..., 0] - half_turn) / robot.left_wheel_radius,
            (v[..., 0] + half_turn) / robot.right_wheel_radius,
        ],
        axis=-1,
    )


def turning_radius(robot: DiffDrive | SkidSteer, wheels: object) -> Any:
    """Signed radius ``(...)`` of the axle midpoint's path, m: ``v/omega``.

    ``+-inf`` driving straight, 0 spinning in place, NaN standing still.
    """
    xp = namespace(wheels)
    twist = to_twist(robot, wheels)
    v, omega = twist[..., 0], twist[..., 2]
    turning = omega != 0
    radius = v / xp.where(turning, omega, xp.ones_like(omega))
    straight = xp.where(v != 0, xp.copysign(xp.full_like(v, math.inf), v), xp.nan)
    return xp.where(turning, radius, straight)


def instantaneous_center(robot: DiffDrive | SkidSteer, wheels: object) -> Any:
    """Instantaneous centres of curvature ``(..., 2)`` in the body frame, m: on the axle line
    (``x = -axle_offset``), or for a ``SkidSteer`` at ``x = icr_x``."""
    xp = namespace(wheels)
    radius = turning_radius(robot, wheels)
    x = robot.icr_x if isinstance(robot, SkidSteer) else -robot.axle_offset
    return xp.stack([xp.full_like(radius, x), radius], axis=-1)


def advance_wheel_positions(positions: object, velocities: object, dt: object) -> Any:
    """Wheel angles ``(..., 2)`` after turning at ``velocities`` for ``dt`` s (seed 001)."""
    xp = namespace(positions, velocities, dt)
    p, w = _wheels(xp, positions, "positions"), _wheels(xp, velocities, "velocities")
    step = finite_positive_dt(xp, dt, like=p)
    leading_shape(positions=tuple(p.shape[:-1]), velocities=tuple(w.shape[:-1]))
    return p + w * step[..., None]


def wheel_velocities_from_positions(before: object, after: object, dt: object) -> Any:
    """Mean wheel velocities ``(..., 2)`` between two wheel-angle readings ``dt`` s apart."""
    xp = namespace(before, after, dt)
    p0, p1 = _wheels(xp, before, "before"), _wheels(xp, after, "after")
    step = finite_positive_dt(xp, dt, like=p0)
    leading_shape(before=tuple(p0.shape[:-1]), after=tuple(p1.shape[:-1]))
    return (p1 - p0) / step[..., None]
