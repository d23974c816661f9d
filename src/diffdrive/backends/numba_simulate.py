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

The work comes in tasks: a robot, or a chunk of one robot's steps when there are fewer robots
than threads. Chunks are integrated in three passes: the turn of each chunk (cheap: no
trigonometry), then each chunk from its start heading and a zero position, then each chunk's
positions shifted by the sum of the chunks before it (``diffdrive.backends.simulate_kernel``
runs the passes over threads). The shift rounds the positions a second time, so float32
output keeps one chunk per robot and with it the half-ulp bound of the NumPy path.

``kernel_ir`` gives the entry point as LLVM IR, a C function over raw arrays that
``simulate_kernel`` turns into machine code cached on disk; ``run_tasks`` is the same entry
as a numba function, for platforms where that cache is not used. Importing this module
imports numba; nothing imports it until the kernel must be compiled.
"""

from __future__ import annotations

import math
import types
from typing import Any

import numba
import numpy as np
from numba import types as nb

from diffdrive import _step

__all__ = ["STEP", "kernel_ir", "run_tasks"]

# Steps between fresh cos and sin of the heading; in between they turn with each step, and
# the rounding that gathers (a few ulp per step) stays below 1e-13.
_ANCHOR = 64
# The kernel raises nothing and allocates nothing: no exception or reference-count path of
# numba's runtime is ever taken (simulate_kernel makes them traps in the cached code).
_kernel = numba.njit(cache=True, error_model="numpy", nogil=True)


@numba.njit(cache=True, inline="always")
def _wheel_angles(history, times, n, k, angles):
    """The angles (rad) the left and right wheels turn in step k of robot n.

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
    return left, right


def _compile_step() -> dict[str, Any]:
    """``diffdrive._step``'s functions compiled as written: each one's copy sees the compiled
    versions of those it calls (the callees come first), so nothing is written twice."""
    compiled: dict[str, Any] = {}
    for name in ("sinc_cos_small", "sinc", "sinc_cos", "wheel_move", "body_move"):
        function = getattr(_step, name)
        scope = {**vars(_step), **compiled}
        copy = types.FunctionType(function.__code__, scope, name, function.__defaults__)
        compiled[name] = numba.njit(cache=True, inline="always")(copy)
    return compiled


STEP = _compile_step()
_sinc_cos = STEP["sinc_cos"]
_wheel_move = STEP["wheel_move"]


@numba.njit(cache=True, inline="always")
def _move(history, times, geometry, n, k, angles):
    """``_step.wheel_move`` of step k of robot n: ``(forward, sideways, turn)``, m, m, rad."""
    left, right = _wheel_angles(history, times, n, k, angles)
    return _wheel_move(geometry[0], geometry[1], geometry[2], geometry[3], left, right)


@numba.njit(cache=True, inline="always")
def _compensated_add(total, compensation, term):
    """``total + term`` with Kahan's compensation: the new total and compensation."""
    corrected = term - compensation
    new_total = total + corrected
    return new_total, (new_total - total) - corrected


@_kernel
def _chunk_turn(history, times, angles, geometry, n, first, stop):
    """The heading change (rad) over steps ``first:stop`` of robot n."""
    total, compensation = 0.0, 0.0
    for k in range(first, stop):
        turn = _move(history, times, geometry, n, k, angles)[2]
        total, compensation = _compensated_add(total, compensation, turn)
    return total


@_kernel
def _integrate_chunk(
    history, times, angles, geometry, midpoint, chord, n, first, stop, x, y, heading, out
):
    """Integrate steps ``first:stop`` of robot n from the pose ``(x, y, heading)`` into ``out``.

    Writes ``out[n, first+1 : stop+1]`` and returns the final x and y. The steps go in blocks
    of ``_ANCHOR``: each block starts from a fresh cos and sin of the heading and turns them
    step by step, and sums its moves from zero; the blocks' sums add up with compensation.
    """
    x_error, y_error, heading_error = 0.0, 0.0, 0.0
    for block in range(first, stop, _ANCHOR):
        cos, sin = math.cos(heading), math.sin(heading)
        block_x, block_y, block_turn = 0.0, 0.0, 0.0
        for k in range(block, min(stop, block + _ANCHOR)):
            forward, sideways, turn = _move(history, times, geometry, n, k, angles)
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


@_kernel
def run_tasks(stage, inputs, first, stop):
    """One pass over tasks ``first:stop`` (robot ``task // chunks``, chunk ``task % chunks``).

    Stage 0 writes each chunk's turn into ``turns``; stage 1 integrates each chunk from its
    start heading (the robot's, plus the turns of the chunks before it) into ``out`` and its
    final x and y into ``ends``; the first chunk of a robot starts at its start pose, the
    others at x = y = 0; stage 2 shifts the positions of every chunk but a robot's first by
    the ends of the chunks before it. ``inputs`` is the tuple ``(history, times, angles,
    start, geometry, midpoint, chord, chunks, turns, out, ends)``.
    """
    history, times, angles, start, geometry, midpoint, chord, chunks, turns, out, ends = inputs
    steps = out.shape[1] - 1
    size = (steps + chunks - 1) // chunks
    for task in range(first, stop):
        n, c = task // chunks, task % chunks
        k0, k1 = c * size, min(steps, (c + 1) * size)
        if stage == 0:
            turns[task] = _chunk_turn(history, times, angles, geometry, n, k0, k1)
            continue
        if stage == 2:
            if c > 0:  # a robot's first chunk starts where the robot does
                shift_x, shift_y = 0.0, 0.0
                for j in range(n * chunks, task):
                    shift_x += ends[j, 0]
                    shift_y += ends[j, 1]
                for k in range(k0 + 1, k1 + 1):
                    out[n, k, 0] += shift_x
                    out[n, k, 1] += shift_y
            continue
        heading = start[n, 2]
        for j in range(n * chunks, task):
            heading += turns[j]
        x, y = 0.0, 0.0
        if c == 0:
            x, y = start[n, 0], start[n, 1]
            out[n, 0, 0], out[n, 0, 1], out[n, 0, 2] = x, y, heading
        ends[task, 0], ends[task, 1] = _integrate_chunk(
            history, times, angles, geometry, midpoint, chord, n, k0, k1, x, y, heading, out
        )


def kernel_ir(values: str, times: str, poses: str) -> tuple[str, str]:
    """``run_tasks`` for histories of dtype ``values``, times of ``times`` and poses of
    ``poses`` (``"float32"`` or ``"float64"``) as a C function over raw arrays: its LLVM IR
    and its symbol.

    The C signature, every count an int64 and every flag an int64 0 or 1: ``(stage, history,
    history_rows, history_length, times, times_rows, times_length, angles, start, geometry,
    midpoint, chord, chunks, turns, poses, robots, samples, ends, first, stop)``; ``history``
    is ``(history_rows, history_length, 2)``, ``times`` ``(times_rows, times_length)``,
    ``start`` ``(robots, 3)`` and ``geometry`` ``(4,)`` float64, ``turns`` ``(robots * chunks,)``
    and ``ends`` ``(robots * chunks, 2)`` float64, ``poses`` ``(robots, samples, 3)``.
    """
    i8, f8 = nb.int64, nb.CPointer(nb.float64)
    value, time, pose = (nb.CPointer(numba.from_dtype(np.dtype(d))) for d in (values, times, poses))
    signature = nb.void(
        i8, value, i8, i8, time, i8, i8, i8, f8, f8, i8, i8, i8, f8, pose, i8, i8, f8, i8, i8
    )

    def entry(
        stage,
        history,
        history_rows,
        history_length,
        times,
        times_rows,
        times_length,
        angles,
        start,
        geometry,
        midpoint,
        chord,
        chunks,
        turns,
        poses,
        robots,
        samples,
        ends,
        first,
        stop,
    ):
        tasks = robots * chunks
        inputs = (
            numba.carray(history, (history_rows, history_length, 2)),
            numba.carray(times, (times_rows, times_length)),
            angles != 0,
            numba.carray(start, (robots, 3)),
            numba.carray(geometry, (4,)),
            midpoint != 0,
            chord != 0,
            chunks,
            numba.carray(turns, (tasks,)),
            numba.carray(poses, (robots, samples, 3)),
            numba.carray(ends, (tasks, 2)),
        )
        run_tasks(stage, inputs, first, stop)

    compiled = numba.cfunc(signature, error_model="numpy")(entry)
    return compiled.inspect_llvm(), compiled.native_name
