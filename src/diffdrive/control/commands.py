"""Wheel commands a motor can follow: desaturation of wheel velocities.

``desaturate`` brings wheel velocities within ``max_wheel_velocity`` (rad/s). By default it
scales both wheels by the same factor, which keeps the curvature ``omega / v`` and so the path;
only the speed along it drops. ``keep="omega"`` keeps the turn rate and gives up forward speed,
``keep="v"`` the reverse; each falls back to the largest feasible value of the kept quantity
when even that one alone is out of reach. Wheels within the limit are returned unchanged.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np

from diffdrive._arrays import components
from diffdrive._step import wheel_move
from diffdrive._validate import positive
from diffdrive.batch.kinematics import WHEELS
from diffdrive.model import Robot, check_robot
from diffdrive.types import WheelVelocities

__all__ = ["KEEP", "Keep", "desaturate"]

Keep = Literal["curvature", "omega", "v"]
KEEP: tuple[Keep, ...] = ("curvature", "omega", "v")
"""What desaturation keeps of a command beyond a wheel's limit: its ``"curvature"`` (the path), its
``"omega"`` or its ``"v"``."""


def desaturate(
    wheels: WheelVelocities | object,
    max_wheel_velocity: float,
    keep: Keep = "curvature",
    robot: Robot | None = None,
) -> Any:
    """Wheel velocities within ``+-max_wheel_velocity`` rad/s, keeping ``keep``.

    ``wheels`` is a ``WheelVelocities`` (returns one) or an array ``(..., 2)`` ``[left, right]``
    (returns an array). ``keep="omega"`` and ``keep="v"`` need the ``robot``.
    """
    limit = positive("max_wheel_velocity", max_wheel_velocity)
    if keep not in KEEP:
        raise ValueError(f"keep must be one of {', '.join(KEEP)}, got {keep!r}")
    if keep != "curvature" and robot is None:
        raise ValueError(f"keep={keep!r} needs the robot, to convert between wheels and twist")
    if robot is not None:
        check_robot(robot)
    if isinstance(wheels, WheelVelocities):
        return WheelVelocities(*_desaturate(wheels.to_array(), limit, keep, robot).tolist())
    w = components(np, wheels, "wheels", WHEELS)
    bad = ~np.isfinite(w)
    if bad.any():
        raise ValueError(f"wheels must be finite, got {w[bad][0]} at index {np.argwhere(bad)[0]}")
    return _desaturate(w, limit, keep, robot)


def _within(limit: float, dtype: np.dtype) -> np.ndarray:
    """The largest value of ``dtype`` at most ``limit``: the limit rounded in the data's dtype
    may lie above it (0.01 in float16 is 0.0100021), and the limit is a promise."""
    cap = np.asarray(limit, dtype=dtype)
    return np.nextafter(cap, dtype.type(0)) if float(cap) > limit else cap


def _desaturate(w: np.ndarray, limit: float, keep: Keep, robot: Robot | None) -> np.ndarray:
    cap = _within(limit, w.dtype)
    if keep == "curvature":
        largest = np.max(np.abs(w), axis=-1, keepdims=True)
        over = largest > cap
        scale = np.where(over, limit / np.where(over, largest, 1.0), 1.0)
        # The clip only trims the rounding that could leave the larger wheel an ulp over.
        return np.clip(w * scale, -cap, cap)
    assert robot is not None
    drive = robot.equivalent  # v and omega are those of the drive's reference point
    r_left, r_right = drive.left_wheel_radius, drive.right_wheel_radius
    twist_v, _, omega = wheel_move(r_left, r_right, drive.track_width, 0.0, w[..., 0], w[..., 1])
    # Wheel rim speeds: left = v - b*omega, right = v + b*omega (b = half the track); each
    # must stay within its wheel's radius times the limit.
    b = 0.5 * drive.track_width
    reach_left, reach_right = limit * r_left, limit * r_right
    if keep == "omega":
        turn_reach = (reach_left + reach_right) / (2 * b)
        omega = np.clip(omega, -turn_reach, turn_reach)
        low = np.maximum(b * omega - reach_left, -b * omega - reach_right)
        high = np.minimum(b * omega + reach_left, -b * omega + reach_right)
        twist_v = np.clip(twist_v, low, high)
    else:
        reach = min(reach_left, reach_right)
        twist_v = np.clip(twist_v, -reach, reach)
        low = np.maximum((twist_v - reach_left) / b, (-reach_right - twist_v) / b)
        high = np.minimum((twist_v + reach_left) / b, (reach_right - twist_v) / b)
        omega = np.clip(omega, low, high)
    left = (twist_v - b * omega) / r_left
    right = (twist_v + b * omega) / r_right
    # Rounding may put a wheel an ulp over the limit; the limit is a promise.
    limited = np.clip(np.stack([left, right], axis=-1), -cap, cap).astype(w.dtype, copy=False)
    within = np.all(np.abs(w) <= cap, axis=-1, keepdims=True)
    return np.where(within, w, limited)
