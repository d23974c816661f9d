"""Sampled rollouts for sampling-based controllers (MPPI and kin): many twist sequences
driven at once through a known actuation delay and acceleration limits.

``rollouts`` takes ``N`` candidate sequences ``(N, T, 2)`` of ``(v, omega)`` commands from one
start. The robot first executes the commands already in flight (the delay), then each
candidate's; every applied twist may change by at most ``max_acceleration * dt`` per step from
the one before (``(v, omega)`` limits in m/s^2 and rad/s^2; a sequential clamp over ``T``,
vectorised over ``N``). Poses come from ``batch.accumulate``, the library's prefix-sum
integration, so the step is the one every backend shares.
"""

from __future__ import annotations

import importlib.util
from typing import Literal

import numpy as np

from diffdrive._step import method_flags
from diffdrive._validate import positive
from diffdrive.batch.integration import accumulate
from diffdrive.integrate import Method

__all__ = ["rollouts"]


def rollouts(
    start: object,
    commands: object,
    dt: float,
    *,
    in_flight: object = None,
    current: object = (0.0, 0.0),
    max_acceleration: tuple[float, float] | None = None,
    method: Method = "exact",
    backend: Literal["auto", "numpy", "numba"] = "auto",
) -> tuple[np.ndarray, np.ndarray]:
    """Poses ``(N, T+1, 3)`` and applied twists ``(N, T, 2)`` of candidate ``commands``
    ``(N, T, 2)`` ``(v, omega)`` from pose ``start`` ``(3,)``, each held ``dt`` s.

    ``in_flight`` ``(D, 2)``: the commands sent before and not yet applied (a delay of ``D``
    steps; the candidates' last ``D`` fall beyond the horizon); ``current`` the twist applied
    now, from which the first step's change is limited. ``backend``: ``"numba"`` (compiled,
    over every core), ``"numpy"``, or ``"auto"``: numba where it is installed.
    """
    dt = positive("dt", dt)
    sequences = np.asarray(commands, dtype=float)
    if sequences.ndim != 3 or sequences.shape[2] != 2:
        raise ValueError(f"commands must be (N, T, 2) (v, omega), got {sequences.shape}")
    if not np.all(np.isfinite(sequences)):
        raise ValueError("commands must be finite")
    origin = np.asarray(start, dtype=float)
    now = np.asarray(current, dtype=float)
    if origin.shape != (3,) or now.shape != (2,) or not np.all(np.isfinite([*origin, *now])):
        raise ValueError("start must be a finite (3,) pose and current a finite (2,) twist")
    flight = np.zeros((0, 2)) if in_flight is None else np.asarray(in_flight, float).reshape(-1, 2)
    limit = np.full(2, np.inf)
    if max_acceleration is not None:
        limit = np.array([positive("max_acceleration", a) for a in max_acceleration]) * dt
    if backend not in ("auto", "numpy", "numba"):
        raise ValueError(f"backend must be 'auto', 'numpy' or 'numba', got {backend!r}")
    count, steps = sequences.shape[:2]
    if backend == "numba" or (backend == "auto" and importlib.util.find_spec("numba")):
        from diffdrive.backends.numba_rollouts import drive

        weight, chord = method_flags(method)
        poses = np.empty((count, steps + 1, 3))
        applied = np.empty((count, steps, 2))
        drive(origin, sequences, flight, now, limit, dt, weight, chord, poses, applied)
        return poses, applied
    queued = np.broadcast_to(flight[None], (count, len(flight), 2))
    sequences = np.concatenate([queued, sequences], axis=1)[:, :steps]
    applied = np.empty_like(sequences)
    previous = np.broadcast_to(now, (count, 2))
    for k in range(steps):
        previous = previous + np.clip(sequences[:, k] - previous, -limit, limit)
        applied[:, k] = previous
    increments = np.zeros((count, steps, 3))
    increments[..., 0] = applied[..., 0] * dt
    increments[..., 2] = applied[..., 1] * dt
    return accumulate(increments, origin, method), applied
