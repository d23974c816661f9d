"""The compiled response kernel (numba): ``dynamics.simulate_response``'s loop when numba is
installed, the same operations in the same order as its pure-Python loop, so both give the
same numbers to the bit. Importing this module imports numba.
"""

from __future__ import annotations

import numba

__all__ = ["respond"]


@numba.njit(cache=True)
def respond(keep, target, limits, initial, out):
    """Fill ``out`` ``(E, W)``: from ``initial`` ``(W,)``, each piece ``i`` moves every wheel
    the share ``1 - keep[i]`` of the way to ``target[i]`` ``(E-1, W)``, at most
    ``limits[i]`` either way."""
    for w in range(target.shape[1]):
        v = initial[w]
        out[0, w] = v
        for i in range(keep.shape[0]):
            change = (1.0 - keep[i]) * (target[i, w] - v)
            if change > limits[i]:
                change = limits[i]
            elif change < -limits[i]:
                change = -limits[i]
            v += change
            out[i + 1, w] = v
