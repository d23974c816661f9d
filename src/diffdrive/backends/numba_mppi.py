"""The compiled MPPI cycle (numba): sampling, rollouts through the drive and every cost in one
pass per candidate, candidates spread over the cores (``prange``).

``control.mppi`` owns the maths and states it; this is its loop. The parameters come as one
``backends.settings.MPPISettings`` named tuple (``control.mppi`` fills it). Three choices make
it fast:

- each candidate draws its own normals from a counter-based stream (splitmix64 seeded by the
  cycle's seed and the candidate's index) by the ziggurat method of Marsaglia and Tsang
  (2000) in Doornik's form (2005, 128 layers; one random word and one comparison for 98.8 %
  of draws), so nothing is shared between threads and the draw does not depend on how many
  threads there are;
- the heading's cos and sin turn with each step's rotation, from short Taylor forms of the
  half-turn (libm only for a half-turn over 1/16 rad), instead of two libm calls a step;
- candidates go in blocks of ``LANES``, each step a branch-free loop over the block that the
  compiler turns into vector instructions; the noise is kept ``(T, 2, K)`` in float32, so
  that a block's perturbations of a step are contiguous, at half the memory.

Importing this module imports numba.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from diffdrive._step import TAYLOR_LIMIT
from diffdrive.backends import simulate_kernel
from diffdrive.backends.numba_simulate import STEP

__all__ = ["LANES", "cycle", "feasible", "free_threads", "in_flight", "update"]

_sinc_cos_small, _sinc_cos = STEP["sinc_cos_small"], STEP["sinc_cos"]
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)


@numba.njit(cache=True, inline="always")
def _splitmix(state):
    """The next state of the stream and its 64 random bits."""
    state = state + _GOLDEN
    z = state
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return state, z ^ (z >> np.uint64(31))


def _ziggurat_tables(layers: int = 128) -> tuple[np.ndarray, np.ndarray]:
    """The layers' right edges ``X`` ``(layers + 1,)`` and the ratios ``X[i+1] / X[i]`` of
    the standard normal's ziggurat (Doornik 2005: the base strip's tail starts at ``R``, each
    layer's area is ``V``)."""
    r, v = 3.442619855899, 9.91256303526217e-3
    x = np.zeros(layers + 1)
    f = math.exp(-0.5 * r * r)
    x[0], x[1] = v / f, r
    for i in range(2, layers):
        x[i] = math.sqrt(-2.0 * math.log(v / x[i - 1] + f))
        f = math.exp(-0.5 * x[i] * x[i])
    return x, x[1:] / x[:-1]


_ZIG_X, _ZIG_RATIO = _ziggurat_tables()
_ZIG_R = _ZIG_X[1]
_LAYER = np.uint64(127)
_TO_SIGNED = 2.0**-52  # 53 random bits to [0, 2)


@numba.njit(cache=True, inline="always")
def _uniform(state):
    """A uniform in (0, 1] and the stream's state."""
    state, bits = _splitmix(state)
    return state, (float(bits >> np.uint64(11)) + 1.0) * 2.0**-53


@numba.njit(cache=True)
def _normal_slow(state, u, i):
    """The ziggurat's rare cases for ``u`` in (-1, 1) that fell outside layer ``i``'s core:
    the tail beyond ``R`` (layer 0) or the wedge under the curve; a fresh draw when
    rejected."""
    while True:
        if i == 0:
            while True:
                state, a = _uniform(state)
                state, b = _uniform(state)
                a = -math.log(a) / _ZIG_R
                if -2.0 * math.log(b) > a * a:
                    return state, (_ZIG_R + a) if u > 0.0 else -(_ZIG_R + a)
        x = u * _ZIG_X[i]
        f0 = math.exp(-0.5 * (_ZIG_X[i] * _ZIG_X[i] - x * x))
        f1 = math.exp(-0.5 * (_ZIG_X[i + 1] * _ZIG_X[i + 1] - x * x))
        state, w = _uniform(state)
        if f1 + w * (f0 - f1) < 1.0:
            return state, x
        state, bits = _splitmix(state)
        u = float(bits >> np.uint64(11)) * _TO_SIGNED - 1.0
        i = np.int64(bits & _LAYER)
        if abs(u) < _ZIG_RATIO[i]:
            return state, u * _ZIG_X[i]


# Candidates go in blocks of LANES, one block a task: every step of the rollout is a loop over
# the block's lanes with no branch in it, which the compiler makes vector instructions of.
LANES = 16
# The vector loops may reorder and fuse arithmetic, but infinities stay (an absent limit is
# inf) and so do NaNs.
_VECTOR = {"nsz", "arcp", "contract", "afn", "reassoc"}
# Rows of a block's state.
_X, _Y, _C, _S, _WL, _WR, _PV, _PW, _TOTAL, _STREAM = range(10)
# Rows of a step's scratch: the wheels' end and mean velocities, the twist, the half-turn.
_EL, _ER, _VX, _VY, _OM, _CH, _SH, _SINC = range(8)
# Half-turns (rad) below this have a Taylor form to an ulp in the vector loop; larger ones
# (a turn of over 1/8 rad in one step) are recomputed by libm after it.
_TAYLOR = TAYLOR_LIMIT


@numba.njit(cache=True, inline="always")
def _over(value, limit):
    excess = max(abs(value) - limit, 0.0)
    return excess * excess


@numba.njit(cache=True, inline="always")
def _wheel_cost(w0, w1, ks, kv, ka, q):
    """The limit terms of one wheel over one period, from ``w0`` to ``w1`` (rad/s)."""
    acceleration = (w1 - w0) / q.dt
    # Friction opposes the motion, that of the period's start where the wheel ends at rest.
    moving = w1 if w1 != 0.0 else w0
    sign = (1.0 if moving > 0.0 else 0.0) - (1.0 if moving < 0.0 else 0.0)
    cost = q.wheel_limit * _over(w1, q.max_wheel_velocity)
    cost += q.acceleration_limit * _over(acceleration, q.max_wheel_acceleration)
    return cost + q.voltage_limit * _over(ks * sign + kv * w1 + ka * acceleration, q.max_voltage)


@numba.njit(cache=True, inline="always")
def _target(w, target, ks, ka_dt, per_volt, q):
    """A command projected into what the drive can do (see ``control.mppi``): the lag's end
    over the period from ``w`` toward ``target`` (rad/s), brought within the wheel's velocity
    limit, then within its acceleration limit and its voltage limit (``kS sgn w + kV w + kA a``:
    ``ks``, ``ka_dt`` = kA / dt, ``per_volt`` = 1 / (kV + kA / dt)), which win where the
    velocity is past its limit already; and the target whose lag ends there (``target``
    itself where it was within). Branch-free, and with no division, for the vector loop."""
    free = target + (w - target) * q.decay
    step = q.max_wheel_acceleration * q.dt
    base = ka_dt * w
    top = (q.max_voltage - ks + base) * per_volt
    # No forward end holds: a backward one (kS then on the other side), at most 0.
    top = min((q.max_voltage + ks + base) * per_volt, 0.0) if top < 0.0 else top
    bottom = (-q.max_voltage + ks + base) * per_volt
    bottom = max((-q.max_voltage - ks + base) * per_volt, 0.0) if bottom > 0.0 else bottom
    top = top if q.voltage_bound > 0.0 else math.inf
    bottom = bottom if q.voltage_bound > 0.0 else -math.inf
    end = min(max(free, -q.max_wheel_velocity), q.max_wheel_velocity)
    end = min(max(end, max(w - step, bottom)), min(w + step, top))
    return end, target if end == free else (end - w * q.decay) * q.undecay


@numba.njit(cache=True, inline="always")
def _lag(w, target, ks, ka_dt, per_volt, q):
    """A wheel's velocity at the period's end and its mean over it (rad/s), as
    ``DriveModel.step``: the lag toward ``target`` projected by ``_target``, the change
    limited by the drive (then the mean is the ends' mean)."""
    end, target = _target(w, target, ks, ka_dt, per_volt, q)
    moved = min(max(end - w, -q.wheel_step), q.wheel_step)
    mean = target + (w - target) * q.lag_mean
    return w + moved, mean if moved == end - w else w + 0.5 * moved


@numba.njit(cache=True, inline="always")
def _drive(wl, wr, cv, cw, q):
    """One period of the drive under the twist command ``(cv, cw)``: the wheels' velocities
    at its end, then the body twist (forward, sideways, turn) they move with."""
    wl, ml = _lag(wl, q.gain * (q.a00 * cv + q.a01 * cw), q.ks_left, q.ka_dt_left, q.volts_left, q)
    wr, mr = _lag(
        wr, q.gain * (q.a10 * cv + q.a11 * cw), q.ks_right, q.ka_dt_right, q.volts_right, q
    )
    return wl, wr, q.b00 * ml + q.b01 * mr, q.b10 * ml + q.b11 * mr, q.b20 * ml + q.b21 * mr


@numba.njit(cache=True, inline="always")
def _taylor(half):
    """cos, sin and sinc of a half-turn (rad) under ``_TAYLOR``, to an ulp, branch-free."""
    sinc, cos = _sinc_cos_small(half)
    return cos, half * sinc, sinc


@numba.njit(cache=True, inline="always")
def _half_turn(half):
    """cos, sin and sinc of any half-turn (rad), by ``_step``'s rule."""
    sinc, cos = _sinc_cos(half)
    return cos, half * sinc, sinc


@numba.njit(cache=True, inline="always")
def _move(x, y, c, s, vx, vy, cos_h, sin_h, sinc, dt):
    """The exact step of a body twist ``(vx, vy)`` held ``dt`` s from ``(x, y)`` heading
    ``(c, s)``, turning twice the half-turn whose cos, sin and sinc are given: the chord
    (the body move turned by the half-turn, scaled by its sinc), then the whole turn."""
    ca, sa = c * cos_h - s * sin_h, s * cos_h + c * sin_h
    fx, fy = sinc * vx * dt, sinc * vy * dt
    return (
        x + ca * fx - sa * fy,
        y + sa * fx + ca * fy,
        ca * cos_h - sa * sin_h,
        sa * cos_h + ca * sin_h,
    )


@numba.njit(cache=True, inline="always")
def _clearance(grid, x, y, q):
    """The clearance (m) at ``(x, y)``: bilinear between the grid's nodes, the edge held."""
    rows, cols = grid.shape
    gx = min(max((x - q.origin_x) / q.resolution, 0.0), cols - 1.0)
    gy = min(max((y - q.origin_y) / q.resolution, 0.0), rows - 1.0)
    i, j = min(int(gy), rows - 2), min(int(gx), cols - 2)
    fy, fx = gy - i, gx - j
    top = grid[i, j] + fx * (grid[i, j + 1] - grid[i, j])
    bottom = grid[i + 1, j] + fx * (grid[i + 1, j + 1] - grid[i + 1, j])
    return top + fy * (bottom - top)


@numba.njit(cache=True)
def in_flight(start, wheels, flight, q):
    """The state after the commands in flight ``(D, 2)`` (twists): ``x, y, cos, sin, left,
    right, v, omega`` (the last applied twist), from pose ``start`` and ``wheels`` (rad/s)."""
    x, y = start[0], start[1]
    c, s = math.cos(start[2]), math.sin(start[2])
    wl, wr = wheels[0], wheels[1]
    vx, omega = q.b00 * wl + q.b01 * wr, q.b20 * wl + q.b21 * wr
    for t in range(flight.shape[0]):
        wl, wr, vx, vy, omega = _drive(wl, wr, flight[t, 0], flight[t, 1], q)
        cos_h, sin_h, sinc = _half_turn(0.5 * omega * q.dt)
        x, y, c, s = _move(x, y, c, s, vx, vy, cos_h, sin_h, sinc, q.dt)
    return np.array([x, y, c, s, wl, wr, vx, omega])


@numba.njit(cache=True, fastmath=_VECTOR, inline="always")
def _draw(stream, uniform, layer, normal, q):
    """Each lane's two perturbations of a step into ``normal`` ``(2, LANES)``, scaled by the
    sigmas: the ziggurat's fast case in a vector loop, its rare other cases after it."""
    rejected = 0
    for j in range(LANES):
        for row in range(2):
            stream[j], bits = _splitmix(stream[j])
            u = float(bits >> np.uint64(11)) * _TO_SIGNED - 1.0
            i = np.int64(bits & _LAYER)
            uniform[row, j], layer[row, j] = u, i
            normal[row, j] = u * _ZIG_X[i]
            rejected += abs(u) >= _ZIG_RATIO[i]
    if rejected:
        for j in range(LANES):
            for row in range(2):
                u, i = uniform[row, j], int(layer[row, j])
                if abs(u) >= _ZIG_RATIO[i]:
                    stream[j], normal[row, j] = _normal_slow(stream[j], u, int(i))
    for j in range(LANES):
        normal[0, j] *= q.sigma_v
        normal[1, j] *= q.sigma_omega


@numba.njit(cache=True, fastmath=_VECTOR)
def _block(first, mean, q, state, reference, grid, seed, draw, noise, costs):
    """The candidates ``first`` to ``first + LANES`` (see ``cycle``)."""
    steps = mean.shape[0]
    st = np.empty((10, LANES))
    work = np.empty((8, LANES))
    stream = np.empty(LANES, dtype=np.uint64)
    uniform = np.empty((2, LANES))
    layer = np.empty((2, LANES), dtype=np.int64)
    normal = np.empty((2, LANES))
    for row in range(8):
        st[row, :] = state[row]
    st[_TOTAL, :] = 0.0
    for j in range(LANES):
        stream[j] = np.uint64(seed) ^ (np.uint64(first + j) * _MIX2)
    obstacles = q.has_map > 0.0
    # The rollout's loop below counts the large half-turns rather than keeping the largest:
    # a float max (which may meet a NaN) cannot be split into vector lanes, and with it the
    # compiler left the whole loop one lane at a time (3.5 against 1.3 ms on one thread for
    # 2,048 x 100). An unsigned index spares each lane numba's wrap-around of negative ones.
    base = np.uint64(first)
    for t in range(steps):
        if draw:
            _draw(stream, uniform, layer, normal, q)
            for j in range(LANES):
                noise[t, 0, base + np.uint64(j)] = normal[0, j]
                noise[t, 1, base + np.uint64(j)] = normal[1, j]
        large = 0
        for j in range(LANES):
            cv = mean[t, 0] + noise[t, 0, base + np.uint64(j)]
            cw = mean[t, 1] + noise[t, 1, base + np.uint64(j)]
            wl, wr = st[_WL, j], st[_WR, j]
            el, er, vx, vy, omega = _drive(wl, wr, cv, cw, q)
            half = 0.5 * omega * q.dt
            large += abs(half) >= _TAYLOR
            work[_CH, j], work[_SH, j], work[_SINC, j] = _taylor(half)
            work[_EL, j], work[_ER, j] = el, er
            work[_VX, j], work[_VY, j], work[_OM, j] = vx, vy, omega
        if large:
            for j in range(LANES):
                ch, sh, sinc = _half_turn(0.5 * work[_OM, j] * q.dt)
                work[_CH, j], work[_SH, j], work[_SINC, j] = ch, sh, sinc
        rx, ry, rc, rs = reference[t, 0], reference[t, 1], reference[t, 2], reference[t, 3]
        for j in range(LANES):
            wl, wr, el, er = st[_WL, j], st[_WR, j], work[_EL, j], work[_ER, j]
            vx, vy, omega = work[_VX, j], work[_VY, j], work[_OM, j]
            # The terms are summed as a tree and added to the total once a step.
            wheels = _wheel_cost(wl, el, q.ks_left, q.kv_left, q.ka_left, q) + _wheel_cost(
                wr, er, q.ks_right, q.kv_right, q.ka_right, q
            )
            pv, pw = st[_PV, j], st[_PW, j]
            effort = q.effort * (vx * vx + omega * omega)
            effort += q.rate * ((vx - pv) * (vx - pv) + (omega - pw) * (omega - pw))
            x, y, c, s = _move(
                st[_X, j],
                st[_Y, j],
                st[_C, j],
                st[_S, j],
                vx,
                vy,
                work[_CH, j],
                work[_SH, j],
                work[_SINC, j],
                q.dt,
            )
            dx, dy = x - rx, y - ry
            along, cross = dx * rc + dy * rs, dy * rc - dx * rs
            tracking = q.cross_track * cross * cross + q.along_track * along * along
            tracking += q.heading * 2.0 * (1.0 - (c * rc + s * rs))
            st[_X, j], st[_Y, j], st[_C, j], st[_S, j] = x, y, c, s
            st[_WL, j], st[_WR, j], st[_PV, j], st[_PW, j] = el, er, vx, omega
            st[_TOTAL, j] += (wheels + effort) + tracking
        if obstacles:
            band = reference[t, 4]
            for j in range(LANES):
                gap = _clearance(grid, st[_X, j], st[_Y, j], q) - q.footprint
                near = max(band - gap, 0.0)
                st[_TOTAL, j] += q.clearance * near * near + (q.collision if gap < 0.0 else 0.0)
    for j in range(LANES):
        gx, gy = st[_X, j] - q.goal_x, st[_Y, j] - q.goal_y
        dx, dy = st[_X, j] - reference[steps - 1, 0], st[_Y, j] - reference[steps - 1, 1]
        behind = max(-(dx * reference[steps - 1, 2] + dy * reference[steps - 1, 3]), 0.0)
        costs[first + j] = st[_TOTAL, j] + q.goal * (gx * gx + gy * gy) + q.progress * behind


@numba.njit(cache=True)
def feasible(mean, q, wheels):
    """``_mppi_arrays.feasible_commands`` compiled: the twist commands ``mean`` ``(T, 2)``
    each projected into what the drive can do, from the wheels' velocities ``wheels`` when
    the first takes effect."""
    out = np.empty_like(mean)
    wl, wr = wheels[0], wheels[1]
    det = q.a00 * q.a11 - q.a01 * q.a10
    for t in range(mean.shape[0]):
        cv, cw = mean[t, 0], mean[t, 1]
        left = q.gain * (q.a00 * cv + q.a01 * cw)
        _, tl = _target(wl, left, q.ks_left, q.ka_dt_left, q.volts_left, q)
        right = q.gain * (q.a10 * cv + q.a11 * cw)
        _, tr = _target(wr, right, q.ks_right, q.ka_dt_right, q.volts_right, q)
        ul, ur = tl / q.gain, tr / q.gain  # the wheel commands back to the twist
        out[t, 0] = (q.a11 * ul - q.a01 * ur) / det
        out[t, 1] = (q.a00 * ur - q.a10 * ul) / det
        wl, wr, _, _, _ = _drive(wl, wr, out[t, 0], out[t, 1], q)
    return out


def free_threads() -> int:
    """The threads a cycle runs on: the CPUs no other task is running on now
    (``simulate_kernel.idle_threads``, as ``simulate``'s kernel counts them), within numba's
    pool. A cycle's blocks wait for the slowest thread, so a thread on a CPU another process
    holds slows the whole cycle: 95 ms on two threads against 29 ms on one for 2,048 x 100
    with the other core busy."""
    pool = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
    return min(simulate_kernel.idle_threads(simulate_kernel.threads()), pool)


@numba.njit(cache=True, parallel=True)
def cycle(mean, q, state, reference, grid, seed, draw, noise, costs):
    """Each candidate's cost ``costs`` ``(K,)``, ``K`` a multiple of ``LANES``: its
    perturbations ``noise`` ``(T, 2, K)`` (drawn here when ``draw``, from ``seed``; read
    otherwise) added to ``mean`` ``(T, 2)``, rolled out from ``state`` (``in_flight``'s) and
    scored against ``reference`` ``(T, 5)`` (x, y, cos, sin at each step's end, and the
    clearance band there, m) and the clearance ``grid`` (see ``control.mppi``)."""
    for b in numba.prange(costs.shape[0] // LANES):
        _block(b * LANES, mean, q, state, reference, grid, seed, draw, noise, costs)


@numba.njit(cache=True)
def _weights(costs, temperature):
    """``exp(-(cost - min) / temperature)``, their sum 1: in one thread, so that the sum's
    rounding, and the command, do not depend on how many threads the cycle had."""
    weights = np.exp(-(costs - costs.min()) / temperature)
    return weights / weights.sum()


# The weighted sums may be reordered into vector lanes (a fixed order, whatever the threads):
# summed one term after the other, each waiting for the last, they took most of the update.
@numba.njit(cache=True, parallel=True, fastmath={"reassoc", "contract"})
def update(costs, noise, temperature, step):
    """The information-theoretic update into ``step`` ``(T, 2)``: ``noise`` ``(T, 2, K)``
    averaged with weights ``exp(-(cost - min) / temperature)``; returns the weights (their
    sum 1)."""
    weights = _weights(costs, temperature)
    for t in numba.prange(noise.shape[0]):
        for c in range(2):
            total = 0.0
            for k in range(costs.shape[0]):
                total += weights[k] * noise[t, c, k]
            step[t, c] = total
    return weights
