"""One integration step of the pose: the three methods, on scalar values.

Each method turns a body twist held for ``dt`` into a body-frame pose delta; the step is
``pose.compose(delta)``. Written as deltas, the three differ only in the direction of the
displacement, which is what lets batch integration be a prefix sum (``diffdrive.batch``):

- ``euler``: along the heading at the start of the step (seeds 000, 002);
- ``rk2``: along the heading at mid-step (second order; common in ROS);
- ``exact``: along the mid-step heading with the chord length ``sinc(omega*dt/2)`` times the
  arc, the SE(2) exponential (seed 001's ``T_bb'``): exact for constant wheel velocities.
"""

from __future__ import annotations

import math
from typing import Literal

from diffdrive import se2
from diffdrive._validate import finite
from diffdrive.types import Pose, Twist

Method = Literal["euler", "rk2", "exact"]
METHODS: tuple[Method, ...] = ("euler", "rk2", "exact")

__all__ = ["METHODS", "Method", "check_method", "delta", "step"]


def check_method(method: str) -> Method:
    """``method`` itself if it names an integration method; ``ValueError`` listing them if not."""
    for known in METHODS:
        if method == known:
            return known
    raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")


def delta(twist: Twist, dt: float, method: Method = "exact") -> Pose:
    """The body-frame pose change over one step of ``dt`` s with ``twist`` held constant."""
    check_method(method)
    twist = Twist.coerce(twist, "twist")
    if method == "exact":
        return se2.exp(twist, dt)
    dt = finite("dt", dt)
    turn = twist.omega * dt
    dx, dy = twist.vx * dt, twist.vy * dt
    if method == "euler":
        return Pose(dx, dy, turn)
    c, s = math.cos(0.5 * turn), math.sin(0.5 * turn)
    return Pose(c * dx - s * dy, s * dx + c * dy, turn)


def step(pose: Pose, twist: Twist, dt: float, method: Method = "exact") -> Pose:
    """The pose after one step of ``dt`` s with the body ``twist`` held constant.

    With ``method="euler"`` this is seed 000's update
    ``x(t+h) = x(t) + h v cos(theta(t))``, ``y(t+h) = y(t) + h v sin(theta(t))``,
    ``theta(t+h) = theta(t) + h omega``.
    """
    return Pose.coerce(pose, "pose").compose(delta(twist, dt, method))
