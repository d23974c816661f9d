"""The compiled encoder kernel (numba): ``sensors.encoder_readings`` for a batch of different
trajectories when numba is installed.

One pass per robot, robots spread over the cores (``prange``), of what the NumPy path does in
stages over whole arrays: each interval's motion of the equivalent drive's point (the relative
pose and its SE(2) logarithm, as ``sensors.motion.motion_of`` takes them, in the same
operations), the forward travel and turn summed with each wheel's slip factor, each wheel's
angle (``forward / r -+ half track * turn / r``, times the counts per radian), the wheel noise
the caller drew (``sqrt(k |arc|)`` times its standard normals, summed), and the whole counts
rolled over as the counter does. Importing this module imports numba.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from diffdrive._step import TAYLOR_LIMIT
from diffdrive.backends.numba_simulate import STEP

__all__ = ["read_encoders", "read_encoders_serial", "scan"]

_sinc = STEP["sinc"]
_TAU = 2.0 * math.pi
_INT64 = 2.0**63
_TAYLOR = TAYLOR_LIMIT  # turns below it rotate the heading's cos and sin by Taylor forms ...
_ANCHOR = 64  # ... for at most this many steps between fresh ones (a few ulp of drift)


@numba.njit(cache=True, inline="always")
def _wrapped(angle):
    """``batch.wrap_angle``'s NumPy rule: the remainder by 2 pi, then one shift into (-pi, pi]
    (inside that interval already, the remainder is the angle itself: no division)."""
    if -math.pi < angle <= math.pi:
        return angle
    wide = np.fmod(angle, _TAU)
    if wide > math.pi:
        return wide - _TAU
    if wide <= -math.pi:
        return wide + _TAU
    return wide


@numba.njit(cache=True, inline="always")
def _small_cos_sin(u):
    """``(cos u, sin u)`` by their Taylor forms, for ``|u| < 1/16`` (to about 1e-19)."""
    u2 = u * u
    a, b, c, d = 1.0 / 12, 1.0 / 30, 1.0 / 56, 1.0 / 6
    cosine = 1.0 - u2 * 0.5 * (1.0 - u2 * a * (1.0 - u2 * b * (1.0 - u2 * c)))
    e, f, g = 1.0 / 20, 1.0 / 42, 1.0 / 72
    sine = u * (1.0 - u2 * d * (1.0 - u2 * e * (1.0 - u2 * f * (1.0 - u2 * g))))
    return cosine, sine


@numba.njit(cache=True, inline="always")
def _small_inverse_sinc(u):
    """``u / sin u`` by its Taylor form, for ``|u| < 1/32`` (to about 1e-19): no division."""
    u2 = u * u
    a, b, c, d = 1.0 / 6, 7.0 / 360, 31.0 / 15120, 127.0 / 604800
    return 1.0 + u2 * (a + u2 * (b + u2 * (c + u2 * d)))


@numba.njit(cache=True, inline="always")
def _rolled(count, bits, signed):
    """A whole count as a ``bits``-bit counter shows it (0 or 64 bits: as it is)."""
    if bits == 0 or bits == 64:
        return count
    mask = (np.int64(1) << np.int64(bits)) - np.int64(1)  # a power of two: modulo is a mask
    if signed:
        half = np.int64(1) << np.int64(bits - 1)
        return ((count + half) & mask) - half
    return count & mask


@numba.njit(cache=True, inline="always")
def _reference(poses, b, k, offset):
    """Pose ``k`` of trajectory ``b`` moved to the point ``offset`` m to its left."""
    x, y, heading = poses[b, k, 0], poses[b, k, 1], poses[b, k, 2]
    if offset == 0.0:
        return x, y, heading
    c, s = math.cos(heading), math.sin(heading)
    return x - s * offset, y + c * offset, heading  # as ReferencePoint.to_reference


@numba.njit(cache=True, parallel=True)
def scan(poses):
    """``(finite, span)``: whether every number of ``poses`` ``(n, T+1, 3)`` is finite, and
    the largest span of one robot's headings (rad, ``sensors.motion.heading_span``), in one
    parallel pass."""
    robots = poses.shape[0]
    bad = np.zeros(robots, dtype=np.bool_)
    spans = np.zeros(robots)
    for i in numba.prange(robots):
        low, high = poses[i, 0, 2], poses[i, 0, 2]
        for k in range(poses.shape[1]):
            x, y, heading = poses[i, k, 0], poses[i, k, 1], poses[i, k, 2]
            if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(heading)):
                bad[i] = True
            low, high = min(low, heading), max(high, heading)
        spans[i] = high - low
    return not bad.any(), spans.max()


@numba.njit(cache=True, parallel=True)
def read_encoders(
    poses,
    offset,
    unwrapped,
    factor,
    geometry,
    k,
    normals,
    noisy,
    scale,
    counts,
    bits,
    signed,
    out,
):
    """Fill ``out`` ``(n, T+1, 2)`` with robot ``i``'s readings along trajectory ``i`` of
    ``poses`` ``(n, T+1, 3)`` (or ``(1, T+1, 3)``, shared): ``factor`` ``(2, T)`` each
    wheel's slip factor, ``geometry`` ``(n, 3)`` ``[r_left, r_right, track]``, ``k`` ``(2,)``
    the wheel noise (m) with the standard ``normals`` ``(n, 2, T)`` (used if ``noisy``),
    ``scale`` counts per rad (1: rad), ``counts``: whole counts of a ``bits``-bit counter (0:
    never rolls over), else angles.
    Returns ``(n,)``: whether each robot's counts would leave an int64."""
    robots, steps = out.shape[0], out.shape[1] - 1
    overflow = np.zeros(robots, dtype=np.bool_)
    for i in numba.prange(robots):
        r_l, r_r, track = geometry[i, 0], geometry[i, 1], geometry[i, 2]
        by_forward_l, by_forward_r = scale / r_l, scale / r_r
        half_l, half_r = 0.5 * track * -1.0, 0.5 * track * 1.0
        by_turn_l, by_turn_r = (scale * half_l) / r_l, (scale * half_r) / r_r
        forward_l = forward_r = turn_l = turn_r = noise_l = noise_r = 0.0
        own = np.int64(i) if poses.shape[0] > 1 else np.int64(0)  # its trajectory
        x0, y0, h0 = _reference(poses, own, 0, offset)
        c0, s0 = math.cos(h0), math.sin(h0)
        since = 0  # small turns since the last fresh cos and sin
        for step in range(steps + 1):
            if step > 0:
                x1, y1, h1 = _reference(poses, own, step, offset)
                # relative_to: inverse(before) * after, written as batch.se2 writes it
                ix, iy = (-c0) * x0 - s0 * y0, s0 * x0 - c0 * y0
                rx, ry = (ix + c0 * x1) + s0 * y1, (iy - s0 * x1) + c0 * y1
                theta = _wrapped(h1 + (-h0))
                half = 0.5 * theta
                if abs(theta) < _TAYLOR and since < _ANCHOR:
                    # A small turn: the heading's cos and sin turned by it, no fresh sine.
                    ct, st = _small_cos_sin(theta)
                    c1, s1 = c0 * ct - s0 * st, s0 * ct + c0 * st
                    ch, sh = _small_cos_sin(half)
                    stretch = _small_inverse_sinc(half)
                    since += 1
                else:
                    c1, s1 = math.cos(h1), math.sin(h1)
                    ch, sh = math.cos(half), math.sin(half)
                    stretch = 1.0 / _sinc(half)
                    since = 0
                forward = stretch * (ch * rx + sh * ry)
                turn = h1 - h0 if unwrapped else theta
                j = step - 1
                forward_l += forward * factor[0, j]
                forward_r += forward * factor[1, j]
                turn_l += turn * factor[0, j]
                turn_r += turn * factor[1, j]
                if noisy:
                    arc_l, arc_r = half_l * turn + forward, half_r * turn + forward
                    noise_l += math.sqrt(k[0] * abs(arc_l)) * normals[i, 0, j] * by_forward_l
                    noise_r += math.sqrt(k[1] * abs(arc_r)) * normals[i, 1, j] * by_forward_r
                x0, y0, h0, c0, s0 = x1, y1, h1, c1, s1
            left = forward_l * by_forward_l
            left += turn_l * by_turn_l
            right = forward_r * by_forward_r
            right += turn_r * by_turn_r
            if noisy and step > 0:
                left += noise_l
                right += noise_r
            if counts:
                left, right = math.floor(left), math.floor(right)
                if not (-_INT64 < left < _INT64 and -_INT64 < right < _INT64):
                    overflow[i] = True
                    break
                out[i, step, 0] = _rolled(np.int64(left), bits, signed)
                out[i, step, 1] = _rolled(np.int64(right), bits, signed)
            else:
                out[i, step, 0], out[i, step, 1] = left, right
    return overflow


# The same kernel on the calling thread alone, without the GIL: several threads run it side
# by side on blocks of robots while another draws the next blocks' normals.
read_encoders_serial = numba.njit(cache=True, nogil=True)(read_encoders.py_func)
