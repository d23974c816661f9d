"""SE(2) over arrays: poses and twists with components on the last axis, shape ``(..., 3)``.

The same operations, under the same names, as ``diffdrive.se2``; leading axes broadcast and
the floating dtype of the inputs is kept. Poses are ``[x, y, theta]``, twists
``[vx, vy, omega]``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from diffdrive._arrays import components, floating, leading_shape, namespace
from diffdrive._step import TAYLOR_LIMIT, Method, method_flags
from diffdrive.angles import TAU

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
    "transform_points",
    "wrap_angle",
]

POSE = "x, y, theta"
TWIST = "vx, vy, omega"
POINT = "x, y"


def _poses(xp: Any, value: object, name: str = "poses") -> Any:
    return components(xp, value, name, POSE)


def wrap_angle(angles: object) -> Any:
    """Angles in rad mapped to (-pi, pi], elementwise, as the scalar ``wrap_angle`` does.

    In NumPy the remainder is exact (``fmod``, then one exact shift by 2 pi), so large angles
    keep every bit; float16 and float32 are wrapped in float64 and rounded to the largest value
    of their dtype within the bounds (float32's nearest value to pi lies above pi).
    """
    xp = namespace(angles)
    a = floating(xp, angles, "angles")
    if xp is not np:  # other array libraries: their remainder, then the same shift
        wrapped = xp.remainder(a, TAU)
        return xp.where(wrapped > math.pi, wrapped - TAU, wrapped)
    wide = np.fmod(a.astype(np.float64, copy=False), TAU)
    wide = np.where(wide > math.pi, wide - TAU, np.where(wide <= -math.pi, wide + TAU, wide))
    if a.dtype == np.float64:
        return wide
    high = np.asarray(math.pi, dtype=a.dtype)
    if float(high) > math.pi:
        high = np.nextafter(high, a.dtype.type(0))
    return np.clip(wide.astype(a.dtype), -high, high)


def sinc(u: object) -> Any:
    """``sin(u)/u`` elementwise, by ``diffdrive._step``'s rule: its Taylor form below 1/16."""
    xp = namespace(u)
    x = floating(xp, u, "u")
    small = xp.abs(x) < TAYLOR_LIMIT
    safe = xp.where(small, xp.ones_like(x), x)
    u2 = x * x
    taylor = 1.0 - u2 * (1 / 6) * (1.0 - u2 * (1 / 20) * (1.0 - u2 * (1 / 42) * (1.0 - u2 / 72)))
    return xp.where(small, taylor, xp.sin(safe) / safe)


def exp(twists: object, dt: object = 1.0) -> Any:
    """Pose deltas ``(..., 3)`` after moving with constant body twists ``(..., 3)`` for ``dt``.

    ``dt`` (s) is a number or an array that broadcasts against the twists' leading axes.
    """
    return moves(twists, dt, "exact")


def moves(twists: object, dt: object, method: Method) -> Any:
    """Body-frame pose changes ``(..., 3)`` of ``twists`` held for ``dt`` s by ``method``'s
    step (``diffdrive._step``'s flags): ``batch.delta``, and ``exp`` for the exact one."""
    weight, chord = method_flags(method)
    xp = namespace(twists, dt)
    v = components(xp, twists, "twists", TWIST)
    step = floating(xp, dt, "dt", like=v)
    leading_shape(twists=tuple(v.shape[:-1]), dt=tuple(step.shape))
    turn = v[..., 2] * step
    # The velocity turned and scaled first, then times the step: linear in the travel, and
    # an overflowing step gives inf, not inf * 0.
    vx, vy = v[..., 0], v[..., 1]
    if weight:
        c, s = xp.cos(weight * turn), xp.sin(weight * turn)
        vx, vy = c * vx - s * vy, s * vx + c * vy
    scale = step * sinc(0.5 * turn) if chord else step
    return xp.stack([scale * vx, scale * vy, turn], axis=-1)


def log(poses: object) -> Any:
    """Twists ``(..., 3)`` that reach ``poses`` from the identity in unit time.

    Principal branch: ``theta`` is wrapped to (-pi, pi] first, as in ``diffdrive.se2.log``.
    """
    xp = namespace(poses)
    p = _poses(xp, poses)
    theta = wrap_angle(p[..., 2])
    half = 0.5 * theta
    scale = 1.0 / sinc(half)
    c, s = xp.cos(half), xp.sin(half)
    x, y = p[..., 0], p[..., 1]
    return xp.stack([scale * (c * x + s * y), scale * (-s * x + c * y), theta], axis=-1)


def compose(a: object, b: object) -> Any:
    """``a * b`` for pose arrays: each ``b`` expressed in the frame of its ``a``."""
    xp = namespace(a, b)
    p, q = _poses(xp, a, "a"), _poses(xp, b, "b")
    leading_shape(a=tuple(p.shape[:-1]), b=tuple(q.shape[:-1]))
    c, s = xp.cos(p[..., 2]), xp.sin(p[..., 2])
    return xp.stack(
        [
            p[..., 0] + c * q[..., 0] - s * q[..., 1],
            p[..., 1] + s * q[..., 0] + c * q[..., 1],
            p[..., 2] + q[..., 2],
        ],
        axis=-1,
    )


def inverse(poses: object) -> Any:
    """The inverse of each pose."""
    xp = namespace(poses)
    p = _poses(xp, poses)
    c, s = xp.cos(p[..., 2]), xp.sin(p[..., 2])
    x, y = p[..., 0], p[..., 1]
    return xp.stack([-c * x - s * y, s * x - c * y, -p[..., 2]], axis=-1)


def relative_to(poses: object, references: object) -> Any:
    """``poses`` seen from ``references``: ``inverse(references) * poses``."""
    xp = namespace(poses, references)
    p, r = _poses(xp, poses), _poses(xp, references, "references")
    leading_shape(poses=tuple(p.shape[:-1]), references=tuple(r.shape[:-1]))
    c, s = xp.cos(r[..., 2]), xp.sin(r[..., 2])
    dx, dy = p[..., 0] - r[..., 0], p[..., 1] - r[..., 1]
    return xp.stack([c * dx + s * dy, -s * dx + c * dy, p[..., 2] - r[..., 2]], axis=-1)


def relative_jacobians(poses: object, references: object) -> tuple[Any, Any]:
    """The derivatives ``(..., 3, 3)`` of ``relative_to(poses, references)`` with respect to
    a small change of each reference and of each pose, both in the world frame's ``(x, y,
    theta)``: how a sensor's noise at both ends enters the motion between its readings."""
    xp = namespace(poses, references)
    p, r = _poses(xp, poses), _poses(xp, references, "references")
    leading_shape(poses=tuple(p.shape[:-1]), references=tuple(r.shape[:-1]))
    c, s = xp.cos(r[..., 2]), xp.sin(r[..., 2])
    dx, dy = p[..., 0] - r[..., 0], p[..., 1] - r[..., 1]
    zero, one = xp.zeros_like(c), xp.ones_like(c)
    at_pose = xp.stack(
        [
            xp.stack([c, s, zero], axis=-1),
            xp.stack([-s, c, zero], axis=-1),
            xp.stack([zero, zero, one], axis=-1),
        ],
        axis=-2,
    )
    at_reference = xp.stack(
        [
            xp.stack([-c, -s, -s * dx + c * dy], axis=-1),
            xp.stack([s, -c, -c * dx - s * dy], axis=-1),
            xp.stack([zero, zero, -one], axis=-1),
        ],
        axis=-2,
    )
    return at_reference, at_pose


def transform_points(poses: object, points: object) -> Any:
    """Body-frame points ``(..., 2)`` in m expressed in the world frame of ``poses``."""
    xp = namespace(poses, points)
    p, q = _poses(xp, poses), components(xp, points, "points", POINT)
    leading_shape(poses=tuple(p.shape[:-1]), points=tuple(q.shape[:-1]))
    c, s = xp.cos(p[..., 2]), xp.sin(p[..., 2])
    return xp.stack(
        [p[..., 0] + c * q[..., 0] - s * q[..., 1], p[..., 1] + s * q[..., 0] + c * q[..., 1]],
        axis=-1,
    )


def pose_derivative(poses: object, twists: object) -> Any:
    """World-frame ``(x_dot, y_dot, theta_dot)``, shape ``(..., 3)``: the unicycle ODE."""
    xp = namespace(poses, twists)
    p, v = _poses(xp, poses), components(xp, twists, "twists", TWIST)
    leading_shape(poses=tuple(p.shape[:-1]), twists=tuple(v.shape[:-1]))
    c, s = xp.cos(p[..., 2]), xp.sin(p[..., 2])
    vx, vy = v[..., 0], v[..., 1]
    omega = v[..., 2] + xp.zeros_like(c)  # broadcast omega to the common leading shape
    return xp.stack([c * vx - s * vy, s * vx + c * vy, omega], axis=-1)


def rotation_matrix(theta: object) -> Any:
    """Body-to-world rotations, shape ``(..., 2, 2)``, for headings ``(...)`` in rad."""
    xp = namespace(theta)
    t = floating(xp, theta, "theta")
    c, s = xp.cos(t), xp.sin(t)
    return xp.stack([xp.stack([c, -s], axis=-1), xp.stack([s, c], axis=-1)], axis=-2)


def to_matrix(poses: object) -> Any:
    """Homogeneous matrices ``(..., 3, 3)`` of ``poses``."""
    xp = namespace(poses)
    p = _poses(xp, poses)
    c, s = xp.cos(p[..., 2]), xp.sin(p[..., 2])
    zero, one = xp.zeros_like(c), xp.ones_like(c)
    rows = [[c, -s, p[..., 0]], [s, c, p[..., 1]], [zero, zero, one]]
    return xp.stack([xp.stack(row, axis=-1) for row in rows], axis=-2)


def from_matrix(matrices: object, atol: float | None = None) -> Any:
    """Poses ``(..., 3)`` of homogeneous matrices ``(..., 3, 3)``; ``theta`` in (-pi, pi].

    Raises ``ValueError`` if any matrix is not a rigid motion to within ``atol`` (default:
    the square root of the dtype's epsilon).
    """
    xp = namespace(matrices)
    m = floating(xp, matrices, "matrices")
    if m.ndim < 2 or tuple(m.shape[-2:]) != (3, 3):
        raise ValueError(f"matrices must have shape (..., 3, 3), got {tuple(m.shape)}")
    if atol is None:
        atol = math.sqrt(float(xp.finfo(m.dtype).eps))
    r = m[..., :2, :2]
    gram = xp.matmul(xp.matrix_transpose(r), r)
    det = r[..., 0, 0] * r[..., 1, 1] - r[..., 0, 1] * r[..., 1, 0]
    bottom = m[..., 2, :] - xp.asarray([0.0, 0.0, 1.0], dtype=m.dtype)
    eye = xp.eye(2, dtype=m.dtype)
    rigid = (
        xp.all(xp.abs(gram - eye) <= atol, axis=(-2, -1))
        & (det > 0)
        & xp.all(xp.abs(bottom) <= atol, axis=-1)
    )
    if not bool(xp.all(rigid)):
        raise ValueError("matrices must all be rigid motions [[R, p], [0, 0, 1]]")
    theta = xp.atan2(m[..., 1, 0], m[..., 0, 0])
    return xp.stack([m[..., 0, 2], m[..., 1, 2], theta], axis=-1)
