"""Simulation: a driving history and an initial pose to a trajectory (seed 000's main job).

Two backends compute the same poses. The NumPy one is a blocked prefix sum, not a loop per
step. Each step's body-frame pose delta comes from ``batch.delta`` (euler, rk2 or exact). The
headings are the running sum of the heading increments. Each delta is rotated into the world
by the heading at the start of its step, and the positions are running sums of those. This is
the same arithmetic as composing the deltas one after another. The steps are taken in blocks
of about ``_BLOCK_ELEMENTS`` values, each block's wheel travel and twists made only when it is
integrated: the temporaries stay small, and the running sums restart from carries that are
held in float64, so float32 input loses no accuracy to a long sequential sum. The numba one
(``diffdrive.backends.numba_simulate``) is a loop per robot over every core, for large calls.
Histories of other array libraries stay in their library (``batch.rollout``).
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from diffdrive import batch
from diffdrive._arrays import components, device, floating, namespace
from diffdrive.batch.integration import travel as prefix_travel
from diffdrive.batch.kinematics import WHEELS
from diffdrive.batch.se2 import POSE
from diffdrive.integrate import Method, check_method
from diffdrive.model import Robot
from diffdrive.trajectory import Trajectory

if TYPE_CHECKING:
    from diffdrive.io.run import Run

__all__ = ["dead_reckon", "integrate_increments", "simulate", "simulate_run"]

# Small enough that a block's temporaries are reused from the heap, not fresh pages each time.
_BLOCK_ELEMENTS = 1 << 11
# What "auto" weighs, measured on the CI machine class (bench_simulate.py, and fresh
# processes): seconds per robot-step of the NumPy path and of the kernel; a call of the
# kernel (its threads start); loading it into a process (importing llvmlite, loading the
# cached machine code) or, with no cache on disk yet, compiling it with numba.
_NUMPY_STEP_SECONDS = 200e-9
_KERNEL_STEP_SECONDS = 15e-9
_KERNEL_CALL_SECONDS = 0.012  # below 2^16 robot-steps NumPy wins even with the kernel loaded
_KERNEL_LOAD_SECONDS = 0.15
_KERNEL_COMPILE_SECONDS = 5.0

WheelFunction = Callable[[np.ndarray], Any]
Backend = Literal["auto", "numpy", "numba"]
BACKENDS: tuple[str, ...] = ("auto", "numpy", "numba")


def _first_bad(mask: Any) -> tuple[int, ...]:
    """The index of the first true entry of a boolean array of any library (one is true)."""
    xp = namespace(mask)
    first = int(xp.argmax(xp.astype(xp.reshape(mask, (-1,)), xp.int8)))
    return tuple(int(i) for i in np.unravel_index(first, tuple(mask.shape)))


def _first_non_finite(array: Any) -> tuple[int, ...] | None:
    """The index of the first entry that is not finite, or None."""
    xp = namespace(array)
    if xp is np:
        # A finite sum means every entry is finite; only a non-finite one (or a sum that
        # overflows) needs the slower search.
        with np.errstate(over="ignore", invalid="ignore"):
            if np.isfinite(np.sum(array, dtype=np.float64)):
                return None
    bad = ~xp.isfinite(array)
    return _first_bad(bad) if bool(xp.any(bad)) else None


def _check_finite(name: str, array: Any) -> None:
    index = _first_non_finite(array)
    if index is not None:
        raise ValueError(f"{name} must be finite, got {float(array[index])} at index {index}")


def integrate_increments(
    increments: object,
    initial_pose: object = None,
    method: Method = "exact",
    dtype: np.dtype | None = None,
) -> np.ndarray:
    """Poses ``(..., T+1, 3)`` from body-twist increments ``(..., T, 3)`` ``[dx, dy, dtheta]``.

    An increment is a step's twist times its duration, ``twist * dt``, which is the integral of
    the body twist over the step. The first pose is ``initial_pose`` (default: the origin,
    broadcast against the leading axes). The poses have ``dtype`` (default: the increments').
    Increments of another array library (JAX, PyTorch, ...) give poses of that library on the
    same device, from ``batch.accumulate`` (in their dtype; ``dtype`` must then be None).
    """
    check_method(method)
    if namespace(increments, initial_pose) is not np:
        if dtype is not None:
            raise ValueError("dtype is for NumPy increments; convert other arrays yourself")
        return batch.accumulate(increments, initial_pose, method)
    inc = components(np, increments, "increments", "dx, dy, dtheta")
    if inc.ndim < 2:
        raise ValueError(f"increments must have shape (..., T, 3), got {inc.shape}")
    start = np.zeros(3) if initial_pose is None else initial_pose
    start = components(np, start, "initial_pose", POSE)
    leading = np.broadcast_shapes(inc.shape[:-2], start.shape[:-1])
    poses = np.empty((*leading, inc.shape[-2] + 1, 3), dtype=dtype or inc.dtype)
    _integrate_blocks(lambda k0, k1: inc[..., k0:k1, :], start, method, poses)
    return poses


def dead_reckon(
    robot: Robot, increments: object, start: object = None, method: Method = "exact"
) -> np.ndarray:
    """Dead-reckoned poses ``(..., T+1, 3)`` of ``robot`` from wheel-angle increments
    ``(..., T, 2)`` rad and a ``start`` pose (default: the origin)."""
    return integrate_increments(batch.to_twist(robot, increments), start, method)


def simulate_run(robot: Robot, run: Run, increments: np.ndarray, method: Method = "exact"):
    """The poses ``(T+1, 3)`` a ``run``'s wheels drive from its first ground-truth pose (else
    the origin): wheel velocities held from each row to the next through ``simulate`` (its
    kernel for long logs), readings (ticks, angles) by ``dead_reckon`` of their
    ``increments`` ``(T, 2)`` rad (``run.increments()``)."""
    if run.kind == "velocity":
        trajectory = simulate(
            robot, run.wheels[:-1], times=run.times, initial_pose=run.start_pose(), method=method
        )
        return trajectory.poses
    return dead_reckon(robot, increments, run.start_pose(), method)


def _integrate_blocks(block_increments, start: np.ndarray, method: Method, poses: np.ndarray):
    """Fill ``poses`` ``(..., T+1, 3)`` block by block from ``start`` ``(..., 3)``.

    ``block_increments(k0, k1)`` gives the body-twist increments of steps ``k0:k1``; making
    them a block at a time keeps the temporaries small, whatever T is.
    """
    leading, steps = poses.shape[:-2], poses.shape[-2] - 1
    carry = np.array(np.broadcast_to(start, (*leading, 3)), dtype=np.float64)
    poses[..., 0, :] = carry
    robots = max(1, math.prod(leading))
    block = max(1, _BLOCK_ELEMENTS // robots)
    for k0 in range(0, steps, block):
        k1 = min(steps, k0 + block)
        out = poses[..., k0 + 1 : k1 + 1, :]
        carry = _integrate_block(block_increments(k0, k1), carry, method, out)


def _integrate_block(inc: np.ndarray, carry: np.ndarray, method: Method, out: np.ndarray):
    """Write the poses after each step of one block into ``out``; return the float64 carry."""
    delta = batch.delta(inc, 1.0, method).astype(np.float64, copy=False)
    travel = prefix_travel(delta, carry[..., 2])
    out[...] = carry[..., None, :] + travel
    # The carry continues from the float64 sums, not from ``out``, which may be float32.
    return carry + travel[..., -1, :]


def _step_times(steps: int | None, dt: object, times: object, like: Any = None) -> Any:
    """The ``(..., T+1)`` sample times from either ``dt`` or ``times``, checked, in the
    library of ``like`` (the history) or of ``times``.

    ``steps`` is T, known whenever ``dt`` is given; with ``times`` alone it may be None.
    """
    xp = namespace(like, times)
    if (dt is None) == (times is None):
        raise ValueError("give exactly one of dt (a uniform step, s) or times (s)")
    if dt is not None:
        assert steps is not None, "a uniform dt comes with its number of steps"
        step = floating(np, dt, "dt")
        if step.ndim != 0 or not np.isfinite(step) or step <= 0:
            raise ValueError(f"dt must be a finite number > 0, got {dt!r}")
        # float64 whatever the data: float32 times 1000 s in would put 6 % errors in 1 ms steps.
        if not math.isfinite(steps * float(step)):
            raise ValueError(f"{steps} steps of dt = {dt!r} s run past the largest float")
        sample_times = np.arange(steps + 1, dtype=np.float64)
        sample_times *= float(step)
        if xp is np:
            return sample_times
        # Another library's times take the history's dtype (JAX may not hold float64); its
        # integration uses dt itself, so only the record of the times is rounded.
        return xp.asarray(sample_times, dtype=like.dtype, device=device(like))
    t = floating(xp, times, "times", like)
    if xp is np and t.dtype not in (np.float32, np.float64):  # float16: no arithmetic in numba
        t = t.astype(np.float64)
    if t.ndim == 0 or t.shape[-1] < 2:
        raise ValueError(f"times must have shape (..., T+1) with T >= 1, got {tuple(t.shape)}")
    _check_finite("times", t)
    not_increasing = xp.diff(t, axis=-1) <= 0
    if bool(xp.any(not_increasing)):
        index = _first_bad(not_increasing)
        after = (*index[:-1], index[-1] + 1)
        raise ValueError(
            f"times must increase strictly; times{after} = {float(t[after])} "
            f"follows {float(t[index])}"
        )
    if steps is not None and t.shape[-1] != steps + 1:
        raise ValueError(
            f"times must have T+1 = {steps + 1} entries on its last axis for T = {steps} "
            f"steps, got shape {tuple(t.shape)}"
        )
    return t


def _sample_function(function: WheelFunction, times: np.ndarray, name: str) -> np.ndarray:
    """Wheel velocities ``(..., T, 2)`` from ``function`` at the mid-point of each step."""
    if times.ndim != 1:
        raise ValueError(f"with a function, times must be one-dimensional, got {times.shape}")
    mid = 0.5 * (times[1:] + times[:-1])
    try:
        values = function(mid)
    except Exception as exc:
        raise ValueError(f"{name} raised {type(exc).__name__}: {exc}") from exc
    values = floating(np, values, f"the values of {name}")
    if values.ndim < 2 or values.shape[-2:] != (mid.shape[0], 2):
        raise ValueError(
            f"{name} must return shape (..., {mid.shape[0]}, 2) [left, right] for "
            f"{mid.shape[0]} times, got {values.shape}"
        )
    return values


def simulate(
    robot: Robot,
    wheel_velocities: object = None,
    *,
    wheel_positions: object = None,
    dt: float | None = None,
    times: object = None,
    duration: float | None = None,
    initial_pose: object = None,
    method: Method = "exact",
    backend: Backend = "auto",
) -> Trajectory:
    """Integrate a driving history from an initial pose into a ``Trajectory``.

    The history is one of:

    - ``wheel_velocities``, an array ``(..., T, 2)`` ``[left, right]`` in rad/s, each held
      over its step, with a uniform ``dt`` (s) or sample ``times`` ``(..., T+1)`` (s, strictly
      increasing, possibly irregular);
    - ``wheel_positions``, accumulated wheel angles ``(..., T+1, 2)`` in rad (seed 000's
      ``phi_L(t)``, ``phi_R(t)``), with ``dt`` or ``times``; each step uses the angle
      increment between its two samples;
    - ``wheel_velocities`` as a function of time: it is called once with the mid-point times of
      all steps, an array ``(T,)``, and returns ``(..., T, 2)``. Give ``times``, or ``dt`` and
      ``duration`` (which must be a whole number of steps, to a relative 1e-9).

    ``initial_pose`` is ``(3,)`` for every robot or ``(..., 3)`` per robot (default: the
    origin, as seed 002 says). Leading axes broadcast: N robots times T steps is one call.
    ``method`` is ``"euler"``, ``"rk2"`` or ``"exact"`` (the default, exact for constant wheel
    velocities). ``backend`` is ``"numpy"`` (blocked prefix sums), ``"numba"`` (the compiled
    kernel on every core; ``pip install diffdrive[fast]``) or ``"auto"``: the one with the
    lower expected cost, counting the kernel's call, and loading it into this process (about
    0.1 s, from machine code cached on disk) or compiling it when there is no cache of it
    (about 5 s, once per dtype): numba from about 2**16 robot-steps once loaded, 0.9 million
    with a cache, 27 million without. A history of another array library (JAX, PyTorch, CuPy,
    array-api-strict) is integrated in that library on its device by ``batch.rollout``'s
    arithmetic, and the ``Trajectory`` holds arrays of it (``backend="numba"`` is refused; to
    jit or differentiate, call ``batch.rollout`` itself).
    All checks run before any integration.
    """
    check_method(method)
    _check_backend(backend)
    if (wheel_velocities is None) == (wheel_positions is None):
        raise ValueError("give exactly one of wheel_velocities or wheel_positions")
    xp = np
    if not callable(wheel_velocities):
        xp = namespace(wheel_velocities, wheel_positions, times, initial_pose)
    if xp is not np and backend == "numba":
        raise ValueError(
            f"backend='numba' takes NumPy arrays; {xp.__name__} arrays are simulated in "
            "their own library (backend='auto')"
        )
    if callable(wheel_velocities):
        if times is None and (dt is None or duration is None):
            raise ValueError("with a wheel-velocity function, give times, or dt and duration")
        steps = _whole_steps(duration, dt) if times is None else None
        sample_times = _step_times(steps, dt, times, None)
        wheels = _sample_function(wheel_velocities, sample_times, "wheel_velocities")
    elif duration is not None:
        raise ValueError("duration is only for a wheel-velocity function")
    elif wheel_velocities is not None:
        wheels = components(xp, wheel_velocities, "wheel_velocities", WHEELS)
        _check_history_shape("wheel_velocities", wheels, "T")
        sample_times = _step_times(wheels.shape[-2], dt, times, wheels)
    if wheel_velocities is not None:
        _check_finite("wheel_velocities", wheels)
        history = _History(wheels, sample_times, angles=False)
        return _build(robot, history, wheels, initial_pose, method, backend, dt)
    angles = components(xp, wheel_positions, "wheel_positions", WHEELS)
    _check_history_shape("wheel_positions", angles, "T+1")
    _check_finite("wheel_positions", angles)
    if angles.shape[-2] < 2:
        raise ValueError(
            f"wheel_positions needs at least 2 samples, got shape {tuple(angles.shape)}"
        )
    sample_times = _step_times(angles.shape[-2] - 1, dt, times, angles)
    history = _History(angles, sample_times, angles=True)
    with np.errstate(over="ignore", invalid="ignore"):
        wheels = xp.diff(angles, axis=-2) / xp.diff(sample_times, axis=-1)[..., None]
    _check_finite("the wheel velocities of wheel_positions (angle steps over time steps)", wheels)
    return _build(robot, history, wheels, initial_pose, method, backend, dt)


def _check_backend(backend: str) -> None:
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    if backend == "numba" and importlib.util.find_spec("numba") is None:
        raise ImportError("backend='numba' needs numba: pip install 'diffdrive[fast]'")


def _whole_steps(duration: object, dt: object) -> int:
    total = floating(np, duration, "duration")
    step = floating(np, dt, "dt")
    if not (np.isfinite(total) and np.isfinite(step) and total > 0 and step > 0):
        raise ValueError(f"duration and dt must be finite and > 0, got {duration!r}, {dt!r}")
    with np.errstate(over="ignore"):  # refused below
        ratio = float(total / step)
    if not ratio <= _MOST_FUNCTION_STEPS:
        raise ValueError(
            f"duration {duration!r} s in steps of dt {dt!r} s is {ratio:.3g} steps, "
            f"{ratio * 56 / 2**30:.3g} GiB of poses and wheel velocities: more than "
            f"{_MOST_FUNCTION_STEPS:.0e} steps; use a longer dt or a shorter duration"
        )
    steps = round(ratio)
    if steps < 1 or abs(steps * float(step) - float(total)) > 1e-9 * float(total):
        raise ValueError(f"duration {duration!r} is not a whole number of steps of dt {dt!r}")
    return steps


# A wheel-velocity function's history is made whole in memory: past this many steps
# (5.6 GB of poses and wheel velocities) it would not fit.
_MOST_FUNCTION_STEPS = 1e8


def _check_history_shape(name: str, array: np.ndarray, length: str) -> None:
    if array.ndim < 2:
        raise ValueError(
            f"{name} must have shape (..., {length}, 2) [left, right], got {array.shape}"
        )


@dataclass(frozen=True)
class _History:
    """A checked driving history: wheel ``angles`` ``(..., T+1, 2)`` (rad) when ``angles``,
    else wheel velocities ``(..., T, 2)`` (rad/s) held over each step; ``times`` ``(..., T+1)``."""

    values: np.ndarray
    times: np.ndarray
    angles: bool

    def wheel_travel(self, k0: int, k1: int) -> np.ndarray:
        """Wheel-angle increments ``(..., k1-k0, 2)`` (rad) of steps ``k0:k1``."""
        if self.angles:
            return np.diff(self.values[..., k0 : k1 + 1, :], axis=-2)
        durations = np.diff(self.times[..., k0 : k1 + 1], axis=-1)
        return self.values[..., k0:k1, :] * durations[..., None]


def _build(robot, history: _History, wheels, initial_pose, method, backend, dt) -> Trajectory:
    """Check that the parts broadcast, integrate with the chosen backend, wrap the result."""
    xp = namespace(wheels)
    start = xp.zeros(3, dtype=wheels.dtype, device=device(wheels))
    if initial_pose is not None:
        start = components(xp, initial_pose, "initial_pose", POSE)
    _check_finite("initial_pose", start)
    times = history.times
    try:
        np.broadcast_shapes(wheels.shape[:-1], (*times.shape[:-1], wheels.shape[-2]))
        leading = np.broadcast_shapes(wheels.shape[:-2], times.shape[:-1], start.shape[:-1])
    except ValueError:
        raise ValueError(
            f"leading axes do not broadcast: wheels {tuple(wheels.shape[:-2])}, times "
            f"{tuple(times.shape[:-1])}, initial_pose {tuple(start.shape[:-1])}"
        ) from None
    if xp is not np:
        poses = _integrate_functional(robot, history, wheels, start, method, dt)
    else:
        steps = wheels.shape[-2]
        poses = np.empty((*leading, steps + 1, 3), dtype=wheels.dtype)
        with np.errstate(over="ignore", invalid="ignore"):
            if _use_numba(backend, math.prod(leading) * steps, poses.dtype):
                _integrate_compiled(robot, history, start, method, poses)
            else:
                _integrate_blocks(
                    lambda k0, k1: batch.to_twist(robot, history.wheel_travel(k0, k1)),
                    start,
                    method,
                    poses,
                )
    index = _first_non_finite(poses)
    if index is not None:
        raise ValueError(
            f"the poses overflow (not finite) at index {index[:-1]}: the history's wheel "
            f"travel or times go beyond what {poses.dtype} holds"
        )
    return Trajectory(robot, times, poses, wheels, method)


def _integrate_functional(robot, history: _History, wheels, start, method, dt) -> Any:
    """Poses of another library's history, in that library (``batch.rollout``'s way): the
    increments of wheel angles as they are, wheel velocities times ``dt`` or the steps."""
    xp = namespace(wheels)
    start = xp.astype(start, wheels.dtype)
    if history.angles:
        increments = batch.twists(robot, xp.diff(history.values, axis=-2))
        return batch.accumulate(increments, start, method)
    durations = dt if dt is not None else xp.diff(history.times, axis=-1)
    return batch.rollout(robot, wheels, durations, start, method)


def _use_numba(backend: Backend, robot_steps: int, dtype: np.dtype) -> bool:
    compiled = dtype in (np.float32, np.float64)  # numba has no float16 arithmetic
    if backend == "numba" and not compiled:
        raise ValueError(f"backend='numba' takes float32 or float64 data, got {dtype}")
    if backend == "auto":
        # The cheaper by expected seconds; the cheap tests first, so that a small call (the
        # usual one) neither looks for numba nor reads a folder.
        saved = robot_steps * (_NUMPY_STEP_SECONDS - _KERNEL_STEP_SECONDS) - _KERNEL_CALL_SECONDS
        if not compiled or saved <= 0 or importlib.util.find_spec("numba") is None:
            return False
        from diffdrive.backends import simulate_kernel

        if simulate_kernel.loaded(dtype):
            return True
        cached = simulate_kernel.cached(dtype)
        return saved > (_KERNEL_LOAD_SECONDS if cached else _KERNEL_COMPILE_SECONDS)
    return backend == "numba"


def _integrate_compiled(robot, history: _History, start, method, poses: np.ndarray) -> None:
    """Hand the history to the numba kernel with the leading axes flattened to one.

    A history or times shared by every robot goes as a single row, not a broadcast copy.
    """
    from diffdrive.backends.simulate_kernel import integrate_history

    model, robot = robot, robot.equivalent
    start = model.to_reference(start)  # the point the equivalent drive moves
    leading, samples = poses.shape[:-2], poses.shape[-2]
    robots = math.prod(leading)
    if robots == 0:  # no robot: nothing to integrate
        return

    def rows(array: np.ndarray, items: int) -> np.ndarray:
        tail = array.shape[array.ndim - items :]
        if math.prod(array.shape[: array.ndim - items]) == 1:
            return array.reshape(1, *tail)
        return np.broadcast_to(array, (*leading, *tail)).reshape(robots, *tail)

    values = history.values
    if values.dtype not in (np.float32, np.float64):  # float16 angles: no arithmetic in numba
        values = values.astype(poses.dtype)
    integrate_history(
        robot,
        rows(values, 2),
        rows(history.times, 1),
        history.angles,
        np.broadcast_to(start, (*leading, 3)).reshape(robots, 3),
        method,
        poses.reshape(robots, samples, 3),
    )
    if model.reference_offset:
        poses[...] = model.from_reference(poses)
