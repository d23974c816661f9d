"""The compiled simulation kernel (numba): ``simulate(..., backend="numba")``.

The maths per step is that of the NumPy path (``batch.to_twist`` then ``batch.delta``, rotated
into the world by the heading at the start of the step), as one loop per robot. Each method
moves along the body displacement turned by ``theta + a*dtheta`` and scaled by ``f``: euler
``a = 0, f = 1``; rk2 ``a = 1/2, f = 1``; exact ``a = 1/2, f = sinc(dtheta/2)``, the chord of
the arc. Three choices make it fast and keep it accurate:

- the half-turn's sin and cos come from short Taylor forms when it is under 1/16 rad, the usual
  case (to an ulp), and from libm otherwise;
- the heading's cos and sin are computed afresh every ``_ANCHOR`` steps and, in between, turned
  by each step's rotation, which costs four multiplies instead of two libm calls;
- each block of ``_ANCHOR`` steps sums its moves from zero, and the blocks' sums are added with
  Kahan's compensation, so 10^7 steps lose about what 64 do.

Both cores are used. Robots are shared out among the threads. When there are fewer robots than
threads, each robot's steps are cut into chunks integrated at the same time in three passes:
the turn of each chunk (cheap: no trigonometry), then each chunk from its start heading and a
zero position, then each chunk's positions shifted by the sum of the chunks before it. The
shift rounds the positions a second time, so float32 output keeps one chunk per robot and with
it the half-ulp bound of the NumPy path.

Importing this module imports numba; ``diffdrive.simulation`` does so only when asked to.
"""

from __future__ import annotations

import math
import types
from typing import Any

import numba
import numpy as np

from diffdrive import _step
from diffdrive.integrate import Method
from diffdrive.model import DiffDrive

__all__ = ["METHOD_FLAGS", "chunk_count", "integrate_history"]

# Steps between fresh cos and sin of the heading; in between they turn with each step, and
# the rounding that gathers (a few ulp per step) stays below 1e-13.
_ANCHOR = 64
# Fewer steps than this per chunk and the three passes cost more than they save.
_MIN_CHUNK = 1 << 14


@numba.njit(cache=True, inline="always")
def _wheel_arcs(history, times, geometry, n, k, angles):
    """Distances (m) the left and right wheels roll in step k of robot n.

    From wheel-angle differences or from rate times duration; a history or times array with
    one row serves every robot.
    """
    h = n if history.shape[0] > 1 else 0
    if angles:
        left = history[h, k + 1, 0] - history[h, k, 0]
        right = history[h, k + 1, 1] - history[h, k, 1]
    else:
        t = n if times.shape[0] > 1 else 0
        duration = times[t, k + 1] - times[t, k]
        left, right = history[h, k, 0] * duration, history[h, k, 1] * duration
    return geometry[0] * left, geometry[1] * right


def _compile_step() -> dict[str, Any]:
    """``diffdrive._step``'s functions compiled as written: each one's copy sees the compiled
    versions of those it calls (the callees come first), so nothing is written twice."""
    compiled: dict[str, Any] = {}
    for name in ("sinc", "sinc_cos", "wheel_move", "body_move"):
        function = getattr(_step, name)
        scope = {**vars(_step), **compiled}
        copy = types.FunctionType(function.__code__, scope, name, function.__defaults__)
        compiled[name] = numba.njit(cache=True, inline="always")(copy)
    return compiled


STEP = _compile_step()
_sinc_cos = STEP["sinc_cos"]


@numba.njit(cache=True, inline="always")
def _compensated_add(total, compensation, term):
    """``total + term`` with Kahan's compensation: the new total and compensation."""
    corrected = term - compensation
    new_total = total + corrected
    return new_total, (new_total - total) - corrected


@numba.njit(cache=True)
def _chunk_turn(history, times, angles, geometry, n, first, stop):
    """The heading change (rad) over steps ``first:stop`` of robot n."""
    inverse_track = 1.0 / geometry[2]
    total, compensation = 0.0, 0.0
    for k in range(first, stop):
        left, right = _wheel_arcs(history, times, geometry, n, k, angles)
        total, compensation = _compensated_add(total, compensation, (right - left) * inverse_track)
    return total


@numba.njit(cache=True)
def _integrate_chunk(history, times, angles, geometry, midpoint, chord, n, first, stop, pose, out):
    """Integrate steps ``first:stop`` of robot n from ``pose`` (x, y, heading) into ``out``.

    Writes ``out[n, first+1 : stop+1]`` and returns the final x and y. The steps go in blocks
    of ``_ANCHOR``: each block starts from a fresh cos and sin of the heading and turns them
    step by step, and sums its moves from zero; the blocks' sums add up with compensation.
    """
    inverse_track = 1.0 / geometry[2]
    x, y, heading = pose[0], pose[1], pose[2]
    x_error, y_error, heading_error = 0.0, 0.0, 0.0
    for block in range(first, stop, _ANCHOR):
        cos, sin = math.cos(heading), math.sin(heading)
        block_x, block_y, block_turn = 0.0, 0.0, 0.0
        for k in range(block, min(stop, block + _ANCHOR)):
            left, right = _wheel_arcs(history, times, geometry, n, k, angles)
            turn = (right - left) * inverse_track
            forward, sideways = 0.5 * (left + right), geometry[3] * turn
            sinc_half, cos_half = _sinc_cos(0.5 * turn)
            sin_half = 0.5 * turn * sinc_half
            scale = sinc_half if chord else 1.0
            along_x, along_y = cos, sin
            if midpoint:
                along_x, along_y = cos * cos_half - sin * sin_half, sin * cos_half + cos * sin_half
            block_x += scale * (along_x * forward - along_y * sideways)
            block_y += scale * (along_y * forward + along_x * sideways)
            block_turn += turn
            out[n, k + 1, 0] = x + block_x
            out[n, k + 1, 1] = y + block_y
            out[n, k + 1, 2] = heading + block_turn
            cos_turn = (cos_half - sin_half) * (cos_half + sin_half)
            sin_turn = 2.0 * sin_half * cos_half
            cos, sin = cos * cos_turn - sin * sin_turn, sin * cos_turn + cos * sin_turn
        x, x_error = _compensated_add(x, x_error, block_x)
        y, y_error = _compensated_add(y, y_error, block_y)
        heading, heading_error = _compensated_add(heading, heading_error, block_turn)
    return x, y


@numba.njit(cache=True, parallel=True)
def _integrate(history, times, angles, start, geometry, midpoint, chord, chunks, out):
    """Write poses ``(N, T+1, 3)`` into ``out``; see the module docstring for the passes."""
    robots, steps = out.shape[0], out.shape[1] - 1
    size = (steps + chunks - 1) // chunks
    tasks = robots * chunks
    turns = np.zeros(tasks)
    if chunks > 1:
        for task in numba.prange(tasks):
            n, c = task // chunks, task % chunks
            first, stop = c * size, min(steps, (c + 1) * size)
            turns[task] = _chunk_turn(history, times, angles, geometry, n, first, stop)
    ends = np.zeros((tasks, 2))
    for task in numba.prange(tasks):
        n, c = task // chunks, task % chunks
        pose = np.zeros(3)
        pose[2] = start[n, 2]
        for j in range(n * chunks, task):
            pose[2] += turns[j]
        if c == 0:
            pose[0], pose[1] = start[n, 0], start[n, 1]
            out[n, 0, 0], out[n, 0, 1], out[n, 0, 2] = pose[0], pose[1], pose[2]
        first, stop = c * size, min(steps, (c + 1) * size)
        ends[task, 0], ends[task, 1] = _integrate_chunk(
            history, times, angles, geometry, midpoint, chord, n, first, stop, pose, out
        )
    if chunks > 1:
        for task in numba.prange(tasks):
            n, c = task // chunks, task % chunks
            if c > 0:
                shift_x, shift_y = 0.0, 0.0
                for j in range(n * chunks, task):
                    shift_x += ends[j, 0]
                    shift_y += ends[j, 1]
                for k in range(c * size + 1, min(steps, (c + 1) * size) + 1):
                    out[n, k, 0] += shift_x
                    out[n, k, 1] += shift_y


# Per method, from ``diffdrive._step``: turn the move to the mid-step heading (a weight of
# 1/2; euler's is 0)? scale it to the chord of the arc?
METHOD_FLAGS: dict[Method, tuple[bool, bool]] = {
    method: (weight == 0.5, chord) for method, (weight, chord) in _step.METHOD_FLAGS.items()
}


def chunk_count(robots: int, steps: int, dtype: np.dtype, threads: int) -> int:
    """How many chunks to cut each robot's steps into so that every thread has work."""
    if dtype != np.float64 or robots >= threads:
        return 1
    return max(1, min(-(-threads // robots), steps // _MIN_CHUNK))


def integrate_history(
    robot: DiffDrive,
    history: np.ndarray,
    times: np.ndarray,
    angles: bool,
    start: np.ndarray,
    method: Method,
    out: np.ndarray,
) -> None:
    """Integrate N robots' driving histories into ``out`` ``(N, T+1, 3)``.

    ``history`` is ``(N or 1, T+1, 2)`` wheel angles (rad) when ``angles``, else
    ``(N or 1, T, 2)`` wheel velocities (rad/s) held over each step; ``times`` is
    ``(N or 1, T+1)`` (s) and ``start`` ``(N, 3)``. A first axis of 1 is shared by all robots.
    """
    robots, steps = out.shape[0], out.shape[1] - 1
    chunks = chunk_count(robots, steps, out.dtype, numba.get_num_threads())
    geometry = np.array(
        [robot.left_wheel_radius, robot.right_wheel_radius, robot.track_width, robot.axle_offset]
    )
    midpoint, chord = METHOD_FLAGS[method]
    # C-contiguous arrays only, so that numba compiles one version per dtype, not per layout.
    _integrate(
        np.ascontiguousarray(history),
        np.ascontiguousarray(times),
        angles,
        np.ascontiguousarray(start, dtype=np.float64),
        geometry,
        midpoint,
        chord,
        chunks,
        out,
    )
