"""Whole driving histories over arrays, in the caller's array library, written functionally.

``accumulate`` turns body-twist increments ``(..., T, 3)`` into poses ``(..., T+1, 3)``;
``rollout`` drives wheel velocities ``(..., T, 2)`` held for ``dt``. Both compute in the library
of their inputs (NumPy, JAX, PyTorch, CuPy, array-api-strict) on its device, in its dtype, with
no in-place assignment, so JAX can jit them and differentiate a loss of the poses with respect
to the geometry (what gradient-based calibration needs).

The step is ``batch.delta``'s: each method a body-frame delta (euler along the start heading,
rk2 along the mid-step heading, exact that times the chord factor ``sinc(dtheta/2)``); the
headings are a prefix sum of the turns, and the positions a prefix sum of the deltas rotated by
them. ``diffdrive.simulate`` does the same in float64 blocks (or with the numba kernel) for
NumPy histories of any length.

``geometry`` is a ``DiffDrive`` (or ``SkidSteer``), or an array ``(..., 3)`` or ``(..., 4)``
``[left_wheel_radius, right_wheel_radius, track_width, axle_offset]`` of the histories'
library: differentiable, and one row per robot where the leading axes say so.
"""

from __future__ import annotations

from typing import Any

from diffdrive._arrays import components, device, floating, namespace
from diffdrive.batch.integrate import delta
from diffdrive.batch.kinematics import WHEELS, to_twist, wheel_map
from diffdrive.batch.se2 import POSE, TWIST
from diffdrive.integrate import Method, check_method
from diffdrive.model import Robot

__all__ = ["GEOMETRY", "accumulate", "rollout", "travel", "twists"]

GEOMETRY = "left_wheel_radius, right_wheel_radius, track_width, axle_offset"


def twists(geometry: Robot | object, wheels: object) -> Any:
    """Body twists ``(..., T, 3)`` from wheel velocities ``(..., T, 2)`` and a geometry (see
    the module); an array geometry's leading axes broadcast against the wheels' (not ``T``)."""
    if isinstance(geometry, Robot):
        return to_twist(geometry, wheels)
    xp = namespace(wheels, geometry)
    w = components(xp, wheels, "wheels", WHEELS)
    g = floating(xp, geometry, "geometry")
    if g.ndim == 0 or g.shape[-1] not in (3, 4):
        raise ValueError(
            f"geometry must have shape (..., 3) or (..., 4) [{GEOMETRY}], got {tuple(g.shape)}"
        )
    return wheel_map(g[..., None, :], w)  # a geometry per history, the same at every step


def travel(moves: Any, heading: Any) -> Any:
    """The prefix sum, written once: the world-frame travel ``(..., T, 3)`` from the start
    after each of the body-frame moves ``(..., T, 3)`` (``delta``'s), starting at ``heading``
    ``(...)`` rad. Each move turns by the turns before it; the positions are the sums."""
    xp = namespace(moves, heading)
    turn = xp.cumulative_sum(moves[..., 2], axis=-1)
    start = heading[..., None] + (turn - moves[..., 2])  # the heading at each step's start
    c, s = xp.cos(start), xp.sin(start)
    dx, dy = moves[..., 0], moves[..., 1]
    x = xp.cumulative_sum(c * dx - s * dy, axis=-1)
    y = xp.cumulative_sum(s * dx + c * dy, axis=-1)
    # x and y take the heading's leading axes (one per robot); turn may not have them yet.
    return xp.stack([x, y, xp.broadcast_to(turn, x.shape)], axis=-1)


def accumulate(increments: object, initial_pose: object = None, method: Method = "exact") -> Any:
    """Poses ``(..., T+1, 3)`` from body-twist increments ``(..., T, 3)`` (twist times step
    duration), from ``initial_pose`` ``(..., 3)`` (default: the origin)."""
    check_method(method)
    xp = namespace(increments, initial_pose)
    inc = components(xp, increments, "increments", TWIST)
    if inc.ndim < 2:
        raise ValueError(f"increments must have shape (..., T, 3), got {tuple(inc.shape)}")
    if initial_pose is None:
        start = xp.zeros(3, dtype=inc.dtype, device=device(inc))
    else:
        start = xp.astype(components(xp, initial_pose, "initial_pose", POSE), inc.dtype)
    after = start[..., None, :] + travel(delta(inc, 1.0, method), start[..., 2])
    first = xp.broadcast_to(start[..., None, :], (*after.shape[:-2], 1, 3))
    return xp.concat([first, after], axis=-2)


def rollout(
    geometry: Robot | object,
    wheel_velocities: object,
    dt: object,
    initial_pose: object = None,
    method: Method = "exact",
) -> Any:
    """Poses ``(..., T+1, 3)`` of robots driving ``wheel_velocities`` ``(..., T, 2)`` (rad/s),
    each held for ``dt`` s (a number, or an array ``(..., T)`` of step durations)."""
    xp = namespace(wheel_velocities, geometry, dt, initial_pose)
    w = components(xp, wheel_velocities, "wheel_velocities", WHEELS)
    if isinstance(dt, int | float) and not (dt > 0 and dt < float("inf")):
        raise ValueError(f"dt must be finite and > 0, got {dt!r}")
    durations = floating(xp, dt, "dt", like=w)
    return accumulate(twists(geometry, w) * durations[..., None], initial_pose, method)
