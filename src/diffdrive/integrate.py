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

from diffdrive._step import METHODS, Method, check_method, method_flags, twist_move
from diffdrive._validate import finite
from diffdrive.types import Pose, Twist

__all__ = ["METHODS", "Method", "check_method", "delta", "step"]


def delta(twist: Twist, dt: float, method: Method = "exact") -> Pose:
    """The body-frame pose change over one step of ``dt`` s with ``twist`` held constant."""
    weight, chord = method_flags(method)
    twist = Twist.coerce(twist, "twist")
    return Pose(*twist_move(twist.vx, twist.vy, twist.omega, finite("dt", dt), weight, chord))


def step(pose: Pose, twist: Twist, dt: float, method: Method = "exact") -> Pose:
    """The pose after one step of ``dt`` s with the body ``twist`` held constant.

    With ``method="euler"`` this is seed 000's update
    ``x(t+h) = x(t) + h v cos(theta(t))``, ``y(t+h) = y(t) + h v sin(theta(t))``,
    ``theta(t+h) = theta(t) + h omega``.
    """
    return Pose.coerce(pose, "pose").compose(delta(twist, dt, method))
