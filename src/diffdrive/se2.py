"""SE(2), the group of planar rigid motions, on scalar ``Pose`` and ``Twist`` values.

The exponential uses the half-angle form: moving along a constant twist ``(vx, vy, omega)``
for ``dt`` s turns the body by ``phi = omega*dt`` and displaces it by the chord
``dt * sinc(phi/2) * R(phi/2) @ (vx, vy)``. This is seed 001's ``T_bb'`` written so that the
only division, ``sin(u)/u``, has a Taylor form near zero; ``1 - cos`` never appears, so no
cancellation. It is the exact method's step of ``diffdrive._step``; the same formulas, over
arrays, are in ``diffdrive.batch``.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from diffdrive import _step
from diffdrive._validate import finite, floats
from diffdrive.angles import wrap_angle
from diffdrive.types import Pose, Twist

__all__ = [
    "compose",
    "exp",
    "from_matrix",
    "inverse",
    "log",
    "pose_derivative",
    "relative_to",
    "rotation_matrix",
    "sinc",
    "to_matrix",
    "wrap_angle",
]

compose = Pose.compose
"""``compose(a, b)``: the pose ``b`` (given in ``a``'s frame) in the world, ``a b`` in SE(2)
(``Pose.compose``)."""
inverse = Pose.inverse
"""``inverse(a)``: the world's origin seen from ``a`` (``Pose.inverse``)."""
relative_to = Pose.relative_to
"""``relative_to(a, b)``: the pose ``a`` seen from ``b``, ``b^-1 a`` (``Pose.relative_to``)."""


def sinc(u: float) -> float:
    """``sin(u)/u`` (unnormalised), 1 at u = 0, smooth through 0 (``diffdrive._step``'s rule);
    u must be finite."""
    return _step.sinc(finite("u", u))


def exp(twist: Twist, dt: float = 1.0) -> Pose:
    """The pose delta after moving with the constant body ``twist`` for ``dt`` s.

    Exact for constant wheel velocities (the constant-curvature arc). The delta is in the
    body frame at the start; compose it onto the start pose: ``pose.compose(exp(twist, dt))``.
    """
    twist = Twist.coerce(twist, "twist")
    dt = finite("dt", dt)
    return Pose(
        *_step.twist_move(twist.vx, twist.vy, twist.omega, dt, *_step.method_flags("exact"))
    )


def log(pose: Pose) -> Twist:
    """The twist that moves from the identity to ``pose`` in unit time (principal branch).

    ``theta`` is first wrapped to (-pi, pi], so ``exp(log(p))`` equals ``p`` up to whole turns
    of the heading, and ``log(exp(t))`` equals ``t`` for ``|t.omega| < pi``.
    """
    pose = Pose.coerce(pose, "pose")
    theta = wrap_angle(pose.theta)
    half = 0.5 * theta
    c, s = math.cos(half), math.sin(half)
    scale = 1.0 / sinc(half)  # sinc(half) >= 2/pi on the principal branch
    return Twist(
        scale * (c * pose.x + s * pose.y),
        scale * (-s * pose.x + c * pose.y),
        theta,
    )


def rotation_matrix(theta: float) -> np.ndarray:
    """The 2x2 rotation from body to world coordinates for heading ``theta`` (seed 003)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def to_matrix(pose: Pose) -> np.ndarray:
    """The 3x3 homogeneous matrix ``[[R, p], [0, 0, 1]]`` of ``pose``."""
    pose = Pose.coerce(pose, "pose")
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    return np.array([[c, -s, pose.x], [s, c, pose.y], [0.0, 0.0, 1.0]])


def from_matrix(matrix: object, atol: float = math.sqrt(sys.float_info.epsilon)) -> Pose:
    """The pose of a 3x3 homogeneous matrix; ``theta`` in (-pi, pi].

    Raises ``ValueError`` if the matrix is not a rigid motion to within ``atol``.
    """
    m = floats("matrix", matrix)
    if m.shape != (3, 3):
        raise ValueError(f"matrix must be a homogeneous transform of shape (3, 3), got {m.shape}")
    rotation = m[:2, :2]
    if not (
        np.allclose(rotation.T @ rotation, np.eye(2), rtol=0.0, atol=atol)
        and np.linalg.det(rotation) > 0.0
        and np.allclose(m[2], [0.0, 0.0, 1.0], rtol=0.0, atol=atol)
    ):
        raise ValueError(f"from_matrix expects a rigid motion [[R, p], [0, 0, 1]], got\n{m}")
    return Pose(float(m[0, 2]), float(m[1, 2]), math.atan2(m[1, 0], m[0, 0]))


def pose_derivative(pose: Pose, twist: Twist) -> tuple[float, float, float]:
    """``(x_dot, y_dot, theta_dot)`` in the world frame: the unicycle ODE (seeds 000, 002)."""
    pose, twist = Pose.coerce(pose, "pose"), Twist.coerce(twist, "twist")
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    return (c * twist.vx - s * twist.vy, s * twist.vx + c * twist.vy, twist.omega)
