"""Differential-drive kinematics over arrays.

Wheels are ``(..., 2)`` arrays ``[left, right]`` in rad/s (velocities) or rad (positions);
twists are ``(..., 3)`` arrays ``[vx, vy, omega]``. The same formulas as ``DiffDrive``'s
methods; leading axes broadcast and the floating dtype is kept.
"""

from __future__ import annotations

import math
from typing import Any

from diffdrive._arrays import components, device, finite_positive_dt, leading_shape, namespace
from diffdrive._step import wheel_move
from diffdrive.batch.se2 import TWIST
from diffdrive.model import Robot, check_robot, geometry_of

__all__ = [
    "advance_wheel_positions",
    "instantaneous_center",
    "to_twist",
    "to_wheel_velocities",
    "turning_radius",
    "wheel_map",
    "wheel_velocities_from_positions",
]

WHEELS = "left, right"


def _wheels(xp: Any, value: object, name: str = "wheels") -> Any:
    return components(xp, value, name, WHEELS)


def wheel_map(geometry: Any, wheels: Any) -> Any:
    """``_step.wheel_move`` over arrays: body twists ``(..., 3)`` from wheel velocities
    ``(..., 2)`` (or angle increments to twist increments), for a ``geometry`` array ``(..., 3)``
    or ``(..., 4)`` ``[r_left, r_right, track, axle_offset]`` that broadcasts against
    ``wheels[..., 0]``: the twists of the drive's reference point."""
    xp = namespace(wheels)
    offset = geometry[..., 3] if geometry.shape[-1] == 4 else 0.0
    forward, sideways, turn = wheel_move(
        geometry[..., 0],
        geometry[..., 1],
        geometry[..., 2],
        offset,
        wheels[..., 0],
        wheels[..., 1],
    )
    return xp.stack([forward, xp.broadcast_to(sideways, turn.shape), turn], axis=-1)


def to_twist(robot: Robot, wheels: object) -> Any:
    """Body twists ``(..., 3)`` from wheel velocities ``(..., 2)`` (forward kinematics): the
    robot's equivalent drive, its twist moved to the body origin."""
    xp = namespace(wheels)
    w = _wheels(xp, wheels)
    geometry = xp.asarray(geometry_of(robot), dtype=w.dtype, device=device(w))
    return robot.twist_from_reference(wheel_map(geometry, w))


def to_wheel_velocities(robot: Robot, twists: object) -> Any:
    """Wheel velocities ``(..., 2)`` that drive ``twists`` ``(..., 3)``; ``vy`` is not used."""
    xp = namespace(twists)
    v = check_robot(robot).twist_to_reference(components(xp, twists, "twists", TWIST))
    drive, forward = robot.equivalent, v[..., 0]
    half_turn = 0.5 * drive.track_width * v[..., 2]
    return xp.stack(
        [
            (forward - half_turn) / drive.left_wheel_radius,
            (forward + half_turn) / drive.right_wheel_radius,
        ],
        axis=-1,
    )


def turning_radius(robot: Robot, wheels: object) -> Any:
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


def instantaneous_center(robot: Robot, wheels: object) -> Any:
    """Instantaneous centres of curvature ``(..., 2)`` in the body frame, m: on the equivalent
    drive's axle line (``x = -axle_offset``; a ``SkidSteer``'s ``icr_x``)."""
    xp = namespace(wheels)
    radius = turning_radius(robot, wheels)
    x = -check_robot(robot).equivalent.axle_offset
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
