"""The compiled Monte Carlo kernel (numba): ``monte_carlo(..., backend="numba")``.

One chunk of robots at a time, one robot after another: its geometry drawn, then its steps,
with the step of ``diffdrive._step`` compiled as it is written, its wheel noise drawn
per step, and each pose folded into the chunk's per-step mean and sums of squared deviations
(Welford's update) instead of being stored. The kernel releases the GIL, so chunks run on
threads side by side; each chunk draws from its own NumPy ``Generator`` (numba compiles its
methods), so its numbers depend on the chunk, not on the thread.

Importing this module imports numba; ``diffdrive.montecarlo`` does so only when asked to.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from diffdrive._step import method_flags
from diffdrive.backends.numba_simulate import STEP
from diffdrive.integrate import Method

__all__ = ["run_chunk"]

_wheel_move, _body_move = STEP["wheel_move"], STEP["body_move"]


@numba.njit(cache=True, inline="always")
def _fold(mean, m2, t, share, x, y, heading):
    """Welford's update of step t's mean and sums of squared deviations with one more pose,
    the ``1/count``-th of those seen."""
    d0, d1, d2 = x - mean[t, 0], y - mean[t, 1], heading - mean[t, 2]
    mean[t, 0] += d0 * share
    mean[t, 1] += d1 * share
    mean[t, 2] += d2 * share
    e0, e1, e2 = x - mean[t, 0], y - mean[t, 1], heading - mean[t, 2]
    m2[t, 0, 0] += d0 * e0
    m2[t, 0, 1] += d0 * e1
    m2[t, 0, 2] += d0 * e2
    m2[t, 1, 1] += d1 * e1
    m2[t, 1, 2] += d1 * e2
    m2[t, 2, 2] += d2 * e2


@numba.njit(cache=True, nogil=True)
def _chunk(travel, start, k, sigma, geometry, weight, chord, rng, final, mean, m2):
    """Drive ``final.shape[0]`` robots; write their final poses and the per-step moments."""
    steps = travel.shape[0]
    for n in range(final.shape[0]):
        r_left = geometry[0] * (1.0 + sigma[0] * rng.standard_normal())
        r_right = geometry[1] * (1.0 + sigma[1] * rng.standard_normal())
        track = geometry[2] * (1.0 + sigma[2] * rng.standard_normal())
        x, y, heading = start[0], start[1], start[2]
        share = 1.0 / (n + 1)  # of this robot in each step's mean
        _fold(mean, m2, 0, share, x, y, heading)
        for t in range(steps):
            dl, dr = travel[t, 0], travel[t, 1]
            if k[0] > 0.0:  # noise on the wheel's travel, m: the angle scaled alike
                dl += math.sqrt(k[0] * abs(r_left * dl)) * rng.standard_normal() / r_left
            if k[1] > 0.0:
                dr += math.sqrt(k[1] * abs(r_right * dr)) * rng.standard_normal() / r_right
            forward, sideways, turn = _wheel_move(r_left, r_right, track, geometry[3], dl, dr)
            dx, dy = _body_move(forward, sideways, turn, weight, chord, heading)
            x += dx
            y += dy
            heading += turn
            _fold(mean, m2, t + 1, share, x, y, heading)
        final[n, 0], final[n, 1], final[n, 2] = x, y, heading
    for t in range(steps + 1):  # Welford filled the upper triangle
        m2[t, 1, 0], m2[t, 2, 0], m2[t, 2, 1] = m2[t, 0, 1], m2[t, 0, 2], m2[t, 1, 2]


def run_chunk(
    travel: np.ndarray,
    start: np.ndarray,
    k: np.ndarray,
    sigma: np.ndarray,
    geometry: np.ndarray,
    method: Method,
    rng: np.random.Generator,
    count: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``count`` robots of one chunk: final poses ``(count, 3)``, per-step mean ``(T+1, 3)``
    and sums of squared deviations ``(T+1, 3, 3)``. ``geometry`` is ``[r_left, r_right, track,
    axle_offset]``; ``rng`` draws the chunk's numbers (numba follows NumPy's Generator)."""
    weight, chord = method_flags(method)
    final = np.empty((count, 3))
    mean = np.zeros((len(travel) + 1, 3))
    m2 = np.zeros((len(travel) + 1, 3, 3))
    _chunk(travel, start, k, sigma, geometry, weight, chord, rng, final, mean, m2)
    return final, mean, m2
