"""The compiled rollout kernel (numba): ``control.rollouts`` for NumPy inputs when numba is
installed.

One loop per candidate sequence, candidates spread over the cores (``prange``): the commands
in flight then the candidate's, each clamped to the acceleration limits from the twist before,
then moved by ``diffdrive._step``'s body move compiled as it is written (the same step as
``batch.accumulate``). Importing this module imports numba.
"""

from __future__ import annotations

import numba

from diffdrive.backends.numba_simulate import STEP

__all__ = ["drive"]

_body_move = STEP["body_move"]


@numba.njit(cache=True, parallel=True)
def drive(start, commands, flight, current, limit, dt, weight, chord, poses, applied):
    """Fill ``poses`` ``(N, T+1, 3)`` and ``applied`` ``(N, T, 2)`` (see ``rollouts``)."""
    count, steps = commands.shape[0], commands.shape[1]
    delay = flight.shape[0]
    for n in numba.prange(count):
        x, y, heading = start[0], start[1], start[2]
        v, w = current[0], current[1]
        poses[n, 0, 0], poses[n, 0, 1], poses[n, 0, 2] = x, y, heading
        for k in range(steps):
            if k < delay:
                cv, cw = flight[k, 0], flight[k, 1]
            else:
                cv, cw = commands[n, k - delay, 0], commands[n, k - delay, 1]
            v += min(max(cv - v, -limit[0]), limit[0])
            w += min(max(cw - w, -limit[1]), limit[1])
            applied[n, k, 0], applied[n, k, 1] = v, w
            turn = w * dt
            dx, dy = _body_move(v * dt, 0.0, turn, weight, chord, heading)
            x += dx
            y += dy
            heading += turn
            poses[n, k + 1, 0], poses[n, k + 1, 1], poses[n, k + 1, 2] = x, y, heading
