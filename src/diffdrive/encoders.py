"""Encoder counters: their width, and the change between readings through a roll-over.

A counter of ``b`` bits (2 to 64) counts modulo 2^b. Read as signed (from -2^(b-1)) or as
unsigned (from 0), the change between two readings is the same: the difference modulo 2^b,
taken in [-2^(b-1), 2^(b-1)), so a counter may turn at most half its range between readings.
``Odometry`` applies the same rule in C, one reading at a time; ``count_changes`` is the
whole-array form for logs.

A change read off a counter is rounded at both readings: ``rounding_variance`` is its
variance. A log that gives wheel angles from counters (a ``JointState`` of an encoder-driven
wheel reports whole counts as radians) shows their step, ``wheel_quantum``.
"""

from __future__ import annotations

import math
import operator

import numpy as np

__all__ = [
    "MAX_COUNTER_BITS",
    "MIN_COUNTER_BITS",
    "check_counter_bits",
    "count_changes",
    "rounding_variance",
    "wheel_quantum",
]

MIN_COUNTER_BITS = 2
"""The narrowest encoder counter the readers take, bits."""
MAX_COUNTER_BITS = 64
"""The widest encoder counter the readers take, bits (a counter that never rolls over)."""


def check_counter_bits(bits: object) -> int | None:
    """``bits`` as an int from 2 to 64, or None (a counter that never rolls over)."""
    if bits is None:
        return None
    if isinstance(bits, bool):
        raise TypeError(f"counter_bits must be a whole number of bits or None, got {bits!r}")
    try:
        value = operator.index(bits)  # type: ignore[arg-type]
    except TypeError:
        raise TypeError(
            f"counter_bits must be a whole number of bits or None, got {bits!r}"
        ) from None
    if not MIN_COUNTER_BITS <= value <= MAX_COUNTER_BITS:
        raise ValueError(
            f"counter_bits must be from {MIN_COUNTER_BITS} to {MAX_COUNTER_BITS} (the width "
            f"of the encoder counter), or None; got {value}"
        )
    return value


def count_changes(readings: object, bits: int | None, axis: int = 0) -> np.ndarray:
    """The change between consecutive counter ``readings`` along ``axis``, as int64.

    ``readings`` are whole counts (int64, or uint64 for unsigned 64-bit readings). With
    ``bits`` each change goes through at most one roll-over of a ``bits``-bit counter; with
    None the readings are plain integers, and a change beyond the int64 range is refused.
    """
    bits = check_counter_bits(bits)
    array = np.asarray(readings)
    if not np.issubdtype(array.dtype, np.integer):
        raise TypeError(f"counter readings must be integers, got dtype {array.dtype}")
    if bits is None:
        rough = np.diff(array.astype(np.float64), axis=axis)
        if array.dtype != np.uint64 and (rough.size == 0 or np.abs(rough).max() < 2.0**62):
            return np.diff(array.astype(np.int64), axis=axis)  # no difference can wrap
        # Python ints, so that no difference wraps silently.
        changes = np.diff(array.astype(object), axis=axis)
        if changes.size and not -(2**63) <= min(changes.flat) <= max(changes.flat) < 2**63:
            raise ValueError("a counter changed by 2^63 counts or more between readings")
        return changes.astype(np.int64)
    # Modular arithmetic in uint64: wraps exactly for every width up to 64.
    raw: np.ndarray = np.diff(array.astype(np.uint64), axis=axis)
    if bits < 64:
        mask = np.uint64((1 << bits) - 1)
        raw &= mask
        # Sign-extend the changes of half the range or more: -2^(b-1) to -1.
        raw = np.where(raw >= np.uint64(1 << (bits - 1)), raw | ~mask, raw)
    return raw.view(np.int64)


def rounding_variance(ticks_per_revolution: float) -> float:
    """The variance (rad^2) of a wheel-angle change read off a counter of
    ``ticks_per_revolution`` counts: two readings, each rounded to a count independently and
    uniformly, ``(2 pi / counts)^2 / 6``."""
    count = 2.0 * math.pi / ticks_per_revolution
    return count * count / 6.0


def wheel_quantum(increments: object, largest: int = 4) -> float | None:
    """The step (rad) every wheel-angle increment ``(N-1, 2)`` is a whole multiple of (to
    1e-6 of a step), counters read as radians; None where there is none: angles that are not
    counts, fewer than 10 increments that move, or fewer than 5 sizes of move among them (a
    drive at one speed, whose one size tells no counter's step). The smallest move divided by
    1 to ``largest`` is tried (a log whose wheels never move by one count alone)."""
    moves = np.abs(np.asarray(increments, dtype=float)).ravel()
    moves = moves[np.isfinite(moves) & (moves > 0.0)]
    if len(moves) < 10:
        return None
    smallest = float(moves.min())
    for divisor in range(1, largest + 1):
        step = smallest / divisor
        # the first moves first: angles that are not counts fail there, at once
        if _whole(moves[:1000], step) and _whole(moves, step):
            sizes = len(np.unique(np.round(moves / step)))
            return step if sizes >= 5 else None
    return None


def _whole(moves: np.ndarray, step: float) -> bool:
    """Whether every move is a whole number of ``step`` (to 1e-6 of a step)."""
    counts = moves / step
    return bool(np.all(np.abs(counts - np.round(counts)) <= 1e-6 * np.maximum(1.0, counts)))
