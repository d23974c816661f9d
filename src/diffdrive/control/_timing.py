"""The time-optimal speed along a sampled path: the forward-backward pass, on scalars.

Along a path sampled at ``N`` states, the robot's speed is ``u >= 0`` (m/s of path, or rad/s
through a turn in place) with acceleration ``a`` held from one state to the next. State ``i``
maps them to the chassis and the wheels by coefficients of its geometry:

    v = lin u,   omega = ang u,   dv/dt = lin a,   domega/dt = ang a + dang u^2,
    wheel j: velocity wc_j u, acceleration wc_j a + wd_j u^2.

A drive leg has ``lin = +-1``, ``ang = kappa``, ``dang = dkappa``; the ``u^2`` terms are the
``v^2 dkappa/ds`` part of each wheel's acceleration that a constant-curvature constraint
misses. Every acceleration limit is ``|p a + q(u)| <= L``, so at a speed ``u`` the allowed
``a`` is an interval (``bounds``); a voltage limit ``|kS sgn(w) + kV w + kA dw/dt| <= V`` is
one more. The speed limit of a state is the largest ``u`` whose interval is not empty (found
by bisection under the velocity caps).

``parameterise`` runs the passes: forward, each state reached with the largest acceleration
the state before allows and the state reached accepts; backward, each state lowered until the
deceleration into the next is allowed at both ends. The segment's acceleration must hold at
both its states, and the step must keep its limits as a controller stepping from state to
state would drive it (``_segment_outside``: the differences between states over the time
between them, the voltage along the way): where it does not, the pass lowers the speed it
sets to the largest that does (``_settle``). The plan is then checked by both measures; a
state still outside its limits (rare: where the intervals of neighbouring states barely
overlap, or the curvature's rate jumps) has its cap lowered and the passes run again.

Written in plain Python on floats and NumPy arrays; ``kernel()`` compiles it with numba when
numba is installed (``diffdrive[fast]``), and otherwise runs it as it is.
"""

from __future__ import annotations

import importlib.util
import math
import os
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

INF = math.inf
BIG = 1e4  # a speed no limit caps (m/s or rad/s): the path has no speed bound there
# Indices into the limits array.
VMAX, AMAX, WMAX, ALPHA, CENTRIPETAL, WHEEL_V, WHEEL_A, VOLTAGE = range(8)
# Statuses ``parameterise`` returns with the index of the state concerned.
OK, UNBOUNDED, STUCK, UNSETTLED = range(4)
_BISECTIONS = 60
_RESOLUTION = 1e-12  # bisections stop when the bracket is this narrow, relative
_ROUNDS = 200


def _narrow(lo: float, hi: float, p: float, q: float, limit: float) -> tuple[float, float]:
    """``[lo, hi]`` cut to where ``|p a + q| <= limit``."""
    if limit == INF:
        return lo, hi
    if limit < 0.0:
        return INF, -INF
    if abs(p) < 1e-12:
        return (lo, hi) if abs(q) <= limit else (INF, -INF)
    first, second = (-limit - q) / p, (limit - q) / p
    if first > second:
        first, second = second, first
    return max(lo, first), min(hi, second)


def bounds(i, u, lin, ang, dang, wc, wd, lim, ff):
    """The accelerations ``(lo, hi)`` state ``i`` allows at speed ``u`` (empty: lo > hi)."""
    lo, hi = -INF, INF
    uu = u * u
    lo, hi = _narrow(lo, hi, lin[i], 0.0, lim[AMAX])
    lo, hi = _narrow(lo, hi, ang[i], uu * dang[i], lim[ALPHA])
    for j in range(2):
        c, d = wc[i, j], wd[i, j]
        lo, hi = _narrow(lo, hi, c, uu * d, lim[WHEEL_A])
        if lim[VOLTAGE] < INF:
            ks, kv, ka = ff[j, 0], ff[j, 1], ff[j, 2]
            w = u * c
            if w == 0.0:  # a wheel at rest: static friction against any acceleration
                lo, hi = _narrow(lo, hi, ka * c, ka * uu * d, lim[VOLTAGE] - ks)
            else:
                sign = 1.0 if w > 0.0 else -1.0
                q = ks * sign + kv * w + ka * uu * d
                lo, hi = _narrow(lo, hi, ka * c, q, lim[VOLTAGE])
    return lo, hi


def cap(i, lin, ang, wc, lim):
    """The speed state ``i``'s velocity limits allow (BIG where none applies)."""
    top = BIG
    if lin[i] != 0.0:
        top = min(top, lim[VMAX] / abs(lin[i]))
    if ang[i] != 0.0:
        top = min(top, lim[WMAX] / abs(ang[i]))
    product = abs(lin[i] * ang[i])
    if product > 0.0:
        top = min(top, math.sqrt(lim[CENTRIPETAL] / product))
    for j in range(2):
        if wc[i, j] != 0.0:
            top = min(top, lim[WHEEL_V] / abs(wc[i, j]))
    return top


def _feasible(i, u, lin, ang, dang, wc, wd, lim, ff):
    lo, hi = bounds(i, u, lin, ang, dang, wc, wd, lim, ff)
    return lo <= hi


def speed_limit(i, lin, ang, dang, wc, wd, lim, ff):
    """The largest speed at state ``i`` within its caps and with some acceleration allowed."""
    top = cap(i, lin, ang, wc, lim)
    if _feasible(i, top, lin, ang, dang, wc, wd, lim, ff):
        return top
    low, high = 0.0, top
    for _ in range(_BISECTIONS):
        if high - low <= _RESOLUTION * high:
            break
        middle = 0.5 * (low + high)
        if _feasible(i, middle, lin, ang, dang, wc, wd, lim, ff):
            low = middle
        else:
            high = middle
    return low


def _passes(top, ds, lin, ang, dang, wc, wd, lim, ff, u):
    n = len(top)
    u[0] = 0.0
    for i in range(n - 1):
        lo, hi = bounds(i, u[i], lin, ang, dang, wc, wd, lim, ff)
        reach = math.sqrt(max(u[i] * u[i] + 2.0 * hi * ds[i], 0.0))
        nxt = min(reach, top[i + 1])
        # The state reached must accept the acceleration that reached it.
        a = (nxt * nxt - u[i] * u[i]) / (2.0 * ds[i])
        lo1, hi1 = bounds(i + 1, nxt, lin, ang, dang, wc, wd, lim, ff)
        if a > hi1:
            # Reached with the acceleration the state reached allows at ``nxt``: a speed that
            # usually passes, and brackets the answer closely.
            low = math.sqrt(max(u[i] * u[i] + 2.0 * hi1 * ds[i], 0.0))
            lo1, hi1 = bounds(i + 1, low, lin, ang, dang, wc, wd, lim, ff)
            if (low * low - u[i] * u[i]) / (2.0 * ds[i]) > hi1:
                low = 0.0
            high = nxt
            for _ in range(_BISECTIONS):
                if high - low <= _RESOLUTION * high:
                    break
                middle = 0.5 * (low + high)
                a = (middle * middle - u[i] * u[i]) / (2.0 * ds[i])
                lo1, hi1 = bounds(i + 1, middle, lin, ang, dang, wc, wd, lim, ff)
                if a <= hi1:
                    low = middle
                else:
                    high = middle
            nxt = low
        u[i + 1] = nxt
        # (Both at rest is a stop the check after the passes names, not a step to time.)
        if u[i] + u[i + 1] > 0.0 and _segment_outside(i, ds, u, lin, ang, wc, lim, ff, 1e-9):
            _settle(i, i + 1, ds, u, lin, ang, wc, lim, ff)
    u[n - 1] = 0.0
    for i in range(n - 2, -1, -1):
        lo1, hi1 = bounds(i + 1, u[i + 1], lin, ang, dang, wc, wd, lim, ff)
        u[i] = min(u[i], math.sqrt(max(u[i + 1] * u[i + 1] - 2.0 * lo1 * ds[i], 0.0)))
        a = (u[i + 1] * u[i + 1] - u[i] * u[i]) / (2.0 * ds[i])
        lo, hi = bounds(i, u[i], lin, ang, dang, wc, wd, lim, ff)
        if a < lo:
            low = math.sqrt(max(u[i + 1] * u[i + 1] - 2.0 * lo * ds[i], 0.0))
            lo, hi = bounds(i, low, lin, ang, dang, wc, wd, lim, ff)
            if (u[i + 1] * u[i + 1] - low * low) / (2.0 * ds[i]) < lo:
                low = 0.0
            high = u[i]
            for _ in range(_BISECTIONS):
                if high - low <= _RESOLUTION * high:
                    break
                middle = 0.5 * (low + high)
                a = (u[i + 1] * u[i + 1] - middle * middle) / (2.0 * ds[i])
                lo, hi = bounds(i, middle, lin, ang, dang, wc, wd, lim, ff)
                if a >= lo:
                    low = middle
                else:
                    high = middle
            u[i] = low
        if u[i] + u[i + 1] > 0.0 and _segment_outside(i, ds, u, lin, ang, wc, lim, ff, 1e-9):
            _settle(i, i, ds, u, lin, ang, wc, lim, ff)


def _settle(k, moved, ds, u, lin, ang, wc, lim, ff):
    """Lower ``u[moved]`` (state ``k`` or ``k + 1``) to the largest speed at which the step
    from state ``k`` to ``k + 1`` keeps its limits (``_segment_outside``), searching down to
    the other state's speed (a step of little change); where that breaks them too, leave it
    for ``lower_where_outside``. The speed found keeps 1e-9 of each limit clear, so that the
    step sits within the limit, not on the rounding slack the checks allow beyond it."""
    high = u[moved]
    other = u[k + 1] if moved == k else u[k]
    low = min(other, high)
    u[moved] = low
    if low <= 0.0 or _segment_outside(k, ds, u, lin, ang, wc, lim, ff, -1e-9):
        u[moved] = high
        return
    for _ in range(_BISECTIONS):
        if high - low <= _RESOLUTION * high:
            break
        middle = 0.5 * (low + high)
        u[moved] = middle
        if _segment_outside(k, ds, u, lin, ang, wc, lim, ff, -1e-9):
            high = middle
        else:
            low = middle
    u[moved] = low


def _outside(i, a, u, lin, ang, dang, wc, wd, lim, ff):
    lo, hi = bounds(i, u, lin, ang, dang, wc, wd, lim, ff)
    slack = 1e-9 * (1.0 + abs(a))
    return a < lo - slack or a > hi + slack


def _segment_outside(k, ds, u, lin, ang, wc, lim, ff, slack):
    """Whether the changes from state ``k`` to ``k + 1``, over the time between them, break a
    limit: the accelerations a controller stepping from state to state asks for (the same
    measure as ``planning.limit_ratios``), and the voltage all the way along, the wheel's
    velocity going in a straight line from one state's to the next (as ``Plan.sample`` gives
    it) with that acceleration: at both ends, and where it passes zero. ``slack``: the share of
    each limit allowed beyond it (negative: that share kept clear of it)."""
    dt = 2.0 * ds[k] / (u[k] + u[k + 1])
    bad = abs(u[k + 1] * lin[k + 1] - u[k] * lin[k]) / dt > lim[AMAX] * (1.0 + slack)
    bad = bad or abs(u[k + 1] * ang[k + 1] - u[k] * ang[k]) / dt > lim[ALPHA] * (1.0 + slack)
    for j in range(2):
        w = u[k] * wc[k, j]
        rate = (u[k + 1] * wc[k + 1, j] - w) / dt
        bad = bad or abs(rate) > lim[WHEEL_A] * (1.0 + slack)
        if lim[VOLTAGE] < INF:
            ks, kv, ka = ff[j, 0], ff[j, 1], ff[j, 2]
            end = u[k + 1] * wc[k + 1, j]
            for v in (w, end):
                sign = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
                volts = ks * sign + kv * v + ka * rate
                bad = bad or abs(volts) > lim[VOLTAGE] * (1.0 + slack)
            if w * end < 0.0:  # through zero: kS either way
                bad = bad or ks + abs(ka * rate) > lim[VOLTAGE] * (1.0 + slack)
    return bad


def lower_where_outside(ds, lin, ang, dang, wc, wd, lim, ff, u, top):
    """Check the profile ``u`` as a controller stepping from state to state would see it (the
    changes over the time between states, ``_segment_outside``) and at each state (its speed
    against the velocity caps, the accelerations leaving and reaching it, ``_outside``);
    lower ``top`` to 0.98 of the speed at every state outside a limit. Returns how many states
    were outside."""
    n = len(lin)
    count = 0
    for k in range(n - 1):
        if _segment_outside(k, ds, u, lin, ang, wc, lim, ff, 1e-9):
            count += 1
            top[k] = min(top[k], 0.98 * u[k])
            top[k + 1] = min(top[k + 1], 0.98 * u[k + 1])
    for i in range(n):
        if u[i] > cap(i, lin, ang, wc, lim) * (1.0 + 1e-9):  # kept by the passes, not by others
            count += 1
            top[i] = min(top[i], 0.98 * u[i])
        for k in (i - 1, i):
            if 0 <= k < n - 1:
                a = (u[k + 1] * u[k + 1] - u[k] * u[k]) / (2.0 * ds[k])
                if _outside(i, a, u[i], lin, ang, dang, wc, wd, lim, ff):
                    count += 1
                    top[i] = min(top[i], 0.98 * u[i])
    return count


def parameterise(ds, lin, ang, dang, wc, wd, lim, ff, ceiling, u):
    """Fill ``u`` (N,) with the fastest speeds from rest to rest, at most ``ceiling`` (N,);
    ``(status, state)``."""
    n = len(lin)
    top = np.empty(n)
    for i in range(n):
        top[i] = min(speed_limit(i, lin, ang, dang, wc, wd, lim, ff), ceiling[i])
        if top[i] >= BIG:
            return UNBOUNDED, i
    for _ in range(_ROUNDS):
        _passes(top, ds, lin, ang, dang, wc, wd, lim, ff, u)
        for i in range(n - 1):
            if u[i] + u[i + 1] <= 0.0:
                return STUCK, i
        if lower_where_outside(ds, lin, ang, dang, wc, wd, lim, ff, u, top) == 0:
            return OK, 0
    return UNSETTLED, 0


def compiles_first() -> bool:
    """Whether the first plan of this process will compile the kernel (numba installed, and
    no machine code of it cached on disk yet: tens of seconds, once)."""
    if importlib.util.find_spec("numba") is None:
        return False
    folders = [Path(__file__).parent / "__pycache__"]
    if os.environ.get("NUMBA_CACHE_DIR"):
        folders.append(Path(os.environ["NUMBA_CACHE_DIR"]))
    return not any(any(folder.rglob("_timing.parameterise-*.nbi")) for folder in folders)


@cache
def kernel() -> Callable[..., Any]:
    """``parameterise``, compiled by numba where it is installed (cached on disk)."""
    return _compiled()["parameterise"]


@cache
def checker() -> Callable[..., Any]:
    """``lower_where_outside``, compiled alike."""
    return _compiled()["lower_where_outside"]


@cache
def _compiled() -> dict[str, Callable[..., Any]]:
    try:
        import numba
    except ImportError:
        return {"parameterise": parameterise, "lower_where_outside": lower_where_outside}
    jit = numba.njit(cache=True)
    module = globals()
    # The small ones inlined into their callers: each is called several times a state.
    for name in ("_narrow", "bounds", "cap", "_feasible"):
        module[name] = numba.njit(cache=True, inline="always")(module[name])
    for name in (
        "speed_limit",
        "_segment_outside",
        "_settle",
        "_passes",
        "_outside",
        "lower_where_outside",
    ):
        module[name] = jit(module[name])
    return {"parameterise": jit(parameterise), "lower_where_outside": module["lower_where_outside"]}
