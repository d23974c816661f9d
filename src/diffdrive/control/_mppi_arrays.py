"""MPPI's cycle in an array library (NumPy, JAX, PyTorch, ... through the array API): the same
rollout and costs as the compiled cycle (``backends.numba_mppi``), every candidate at once and
the steps in turn, on the library's device (PyTorch: CUDA where there is one).

The drive, the step and every cost term are those ``control.mppi`` states; the half-turn's
cos and sin come from the library (the compiled cycle's Taylor forms agree to an ulp). The
noise is drawn by the library's own generator (NumPy's ``Generator``, ``torch.Generator``,
a JAX key split every cycle), so a GPU draws its own.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

import array_api_compat
import numpy as np

from diffdrive.backends.settings import MPPISettings

__all__ = ["ArrayCycle", "drive_period", "feasible_commands"]


class ArrayCycle:
    """The cycle in the array library ``library`` (``"numpy"``, ``"jax"`` or ``"torch"``),
    seeded by ``seed``."""

    def __init__(self, library: str, seed: int | None) -> None:
        self.library = library
        self.device: Any = None  # the library's default: NumPy's CPU, JAX's first device
        if library == "numpy":
            self.xp: ModuleType = np
            self._rng: Any = np.random.default_rng(seed)
        elif library == "torch":
            import torch

            self.xp = array_api_compat.array_namespace(torch.zeros(1))
            # On the GPU where there is one, its generator there too.
            self.device = "cuda" if torch.cuda.is_available() else "cpu"
            self._rng = torch.Generator(device=self.device)
            if seed is None:
                self._rng.seed()
            else:
                self._rng.manual_seed(seed)
        elif library == "jax":
            import jax

            self.xp = array_api_compat.array_namespace(jax.numpy.zeros(1))
            self._rng = jax.random.key(np.random.SeedSequence(seed).generate_state(1)[0])
        else:
            raise ValueError(f"array library must be numpy, jax or torch, got {library!r}")
        self.dtype = self.xp.float64 if _has_float64(library) else self.xp.float32
        self.index = self.xp.int64 if self.dtype == self.xp.float64 else self.xp.int32
        self._grid: tuple[np.ndarray, Any] | None = None

    def generator_state(self) -> Any:
        """Where the draws stand, for ``restore_generator``: a refused cycle draws nothing."""
        if self.library == "numpy":
            return self._rng.bit_generator.state
        if self.library == "torch":
            return self._rng.get_state()
        return self._rng  # a JAX key is a value

    def restore_generator(self, state: Any) -> None:
        """Put the draws back where ``generator_state`` found them."""
        if self.library == "numpy":
            self._rng.bit_generator.state = state
        elif self.library == "torch":
            self._rng.set_state(state)
        else:
            self._rng = state

    def draw(self, shape: tuple[int, ...], sigma: np.ndarray) -> Any:
        """Perturbations ``(T, 2, K)``, standard deviations ``sigma`` ``(2,)`` on axis 1."""
        if self.library == "numpy":
            normal = self._rng.standard_normal(shape)
        elif self.library == "torch":
            import torch

            normal = torch.randn(
                shape, generator=self._rng, dtype=torch.float64, device=self.device
            )
        else:
            import jax

            self._rng, key = jax.random.split(self._rng)
            normal = jax.random.normal(key, shape, dtype=self.dtype)
        scale = self.xp.asarray(sigma[None, :, None], dtype=self.dtype, device=self.device)
        return self.xp.astype(normal, self.dtype) * scale

    def costs(
        self,
        q: MPPISettings,
        mean: np.ndarray,
        noise: Any,
        start: np.ndarray,
        wheels: np.ndarray,
        flight: np.ndarray,
        reference: np.ndarray,
        grid: np.ndarray | None,
        positions: list | None = None,
    ) -> Any:
        """Each candidate's cost ``(K,)`` (see ``numba_mppi.cycle``): ``noise`` ``(T, 2, K)``
        added to ``mean`` ``(T, 2)``, after the commands in ``flight`` ``(D, 2)``, from pose
        ``start`` and the wheels' velocities ``wheels`` (rad/s). ``positions``: a list that
        gets each step's ``(x, y)`` of every candidate, for a picture."""
        xp, dtype = self.xp, self.dtype
        count = noise.shape[2]

        def constant(value: object) -> Any:
            return xp.asarray(value, dtype=dtype, device=self.device)

        x, y = constant(start[0]), constant(start[1])
        c, s = xp.cos(constant(start[2])), xp.sin(constant(start[2]))
        wl, wr = constant(wheels[0]), constant(wheels[1])
        pv, pw = q.b00 * wl + q.b01 * wr, q.b20 * wl + q.b21 * wr
        for command in flight:
            wl, wr, pv, vy, pw = _drive(xp, q, wl, wr, constant(command[0]), constant(command[1]))
            x, y, c, s = _move(xp, q, x, y, c, s, pv, vy, pw)
        total = xp.zeros(count, dtype=dtype, device=self.device)
        x, y, c, s, wl, wr = (xp.broadcast_to(a, (count,)) for a in (x, y, c, s, wl, wr))
        means, ref = constant(mean), constant(reference)
        table = None if grid is None else self._device_grid(grid)
        for t in range(mean.shape[0]):
            el, er, vx, vy, omega = _drive(
                xp, q, wl, wr, means[t, 0] + noise[t, 0], means[t, 1] + noise[t, 1]
            )
            total = total + _wheel_cost(xp, q, wl, el, (q.ks_left, q.kv_left, q.ka_left))
            total = total + _wheel_cost(xp, q, wr, er, (q.ks_right, q.kv_right, q.ka_right))
            total = total + q.effort * (vx * vx + omega * omega)
            total = total + q.rate * ((vx - pv) ** 2 + (omega - pw) ** 2)
            wl, wr, pv, pw = el, er, vx, omega
            x, y, c, s = _move(xp, q, x, y, c, s, vx, vy, omega)
            if positions is not None:
                positions.append((to_numpy(x), to_numpy(y)))
            dx, dy = x - ref[t, 0], y - ref[t, 1]
            along, cross = dx * ref[t, 2] + dy * ref[t, 3], dy * ref[t, 2] - dx * ref[t, 3]
            total = total + q.cross_track * cross * cross + q.along_track * along * along
            total = total + q.heading * 2.0 * (1.0 - (c * ref[t, 2] + s * ref[t, 3]))
            if table is not None:
                gap = _clearance(xp, q, table, x, y, self.index) - q.footprint
                near = xp.clip(ref[t, 4] - gap, min=0.0)
                total = total + q.clearance * near * near + q.collision * xp.astype(gap < 0, dtype)
        end = ref[mean.shape[0] - 1]
        behind = xp.clip(-((x - end[0]) * end[2] + (y - end[1]) * end[3]), min=0.0)
        return total + q.goal * ((x - q.goal_x) ** 2 + (y - q.goal_y) ** 2) + q.progress * behind

    def _device_grid(self, grid: np.ndarray) -> Any:
        """The clearance grid in the library, on its device: copied once, kept."""
        if self._grid is None or self._grid[0] is not grid:
            table = self.xp.asarray(np.array(grid), dtype=self.dtype, device=self.device)
            self._grid = (grid, table)
        return self._grid[1]

    def update(self, costs: Any, noise: Any, temperature: float) -> tuple[np.ndarray, Any]:
        """The weighted mean of ``noise`` ``(T, 2, K)`` (as ``weighted_update``), on the host,
        and the weights ``(K,)``."""
        xp = self.xp
        weights = xp.exp(-(costs - xp.min(costs)) / temperature)
        weights = weights / xp.sum(weights)
        step = xp.sum(noise * weights, axis=-1)
        return to_numpy(step), weights


def drive_period(q: MPPISettings, wheels: np.ndarray, command: np.ndarray) -> np.ndarray:
    """The wheels' velocities (rad/s) a period after ``wheels`` under the twist ``command``
    ``(v, omega)``: the drive's state a controller carries from cycle to cycle."""
    wl, wr, *_ = _drive(np, q, np.float64(wheels[0]), np.float64(wheels[1]), *command)
    return np.array([wl, wr])


def to_numpy(array: Any) -> np.ndarray:
    """An array of any library as a NumPy array on the host."""
    if array_api_compat.is_torch_array(array):
        return array.detach().cpu().numpy()
    return np.asarray(array)


def _has_float64(library: str) -> bool:
    """Whether the library computes in float64 (JAX only with x64 enabled)."""
    if library != "jax":
        return True
    import jax

    return bool(getattr(jax.config, "jax_enable_x64"))  # noqa: B009 (no stubs for it)


def feasible_commands(q: MPPISettings, wheels: np.ndarray, commands: np.ndarray) -> np.ndarray:
    """The twist ``commands`` ``(T, 2)`` ``(v, omega)``, from the wheels' velocities
    ``wheels`` (rad/s) when the first takes effect, each projected into what the drive can
    do (``numba_mppi._lag``): the commands the rollouts move with, and the one sent."""
    out = np.array(commands, dtype=float)
    wl, wr = np.float64(wheels[0]), np.float64(wheels[1])
    det = q.a00 * q.a11 - q.a01 * q.a10
    for t, (cv, cw) in enumerate(out):
        _, tl = _target(np, q, wl, q.gain * (q.a00 * cv + q.a01 * cw), _left(q))
        _, tr = _target(np, q, wr, q.gain * (q.a10 * cv + q.a11 * cw), _right(q))
        ul, ur = tl / q.gain, tr / q.gain  # the wheel commands back to the twist
        out[t] = ((q.a11 * ul - q.a01 * ur) / det, (q.a00 * ur - q.a10 * ul) / det)
        wl, wr, *_ = _drive(np, q, wl, wr, *out[t])
    return out


def _left(q: MPPISettings) -> tuple[float, float, float]:
    """The left wheel's projection constants (kS, kA / dt, 1 / (kV + kA / dt))."""
    return q.ks_left, q.ka_dt_left, q.volts_left


def _right(q: MPPISettings) -> tuple[float, float, float]:
    """The right wheel's projection constants."""
    return q.ks_right, q.ka_dt_right, q.volts_right


def _drive(xp: ModuleType, q: MPPISettings, wl: Any, wr: Any, cv: Any, cw: Any) -> tuple:
    """``numba_mppi._drive`` over arrays."""
    wl, ml = _lag(xp, q, wl, q.gain * (q.a00 * cv + q.a01 * cw), _left(q))
    wr, mr = _lag(xp, q, wr, q.gain * (q.a10 * cv + q.a11 * cw), _right(q))
    return wl, wr, q.b00 * ml + q.b01 * mr, q.b10 * ml + q.b11 * mr, q.b20 * ml + q.b21 * mr


def _target(xp: ModuleType, q: MPPISettings, w: Any, target: Any, ff: tuple) -> tuple[Any, Any]:
    """``numba_mppi._target`` over arrays: the lag's end and the target that gives it, within
    the limits (``ff``: kS, kA / dt, 1 / (kV + kA / dt))."""
    free = target + (w - target) * q.decay
    step = q.max_wheel_acceleration * q.dt
    end = xp.clip(free, min=-q.max_wheel_velocity, max=q.max_wheel_velocity)
    low, high = w - step, w + step
    if q.voltage_bound > 0.0:
        ks, ka_dt, per_volt = ff
        base = ka_dt * w
        top = (q.max_voltage - ks + base) * per_volt
        backward = xp.minimum((q.max_voltage + ks + base) * per_volt, 0.0)
        top = xp.where(top < 0.0, backward, top)
        bottom = (-q.max_voltage + ks + base) * per_volt
        forward = xp.maximum((-q.max_voltage - ks + base) * per_volt, 0.0)
        bottom = xp.where(bottom > 0.0, forward, bottom)
        low, high = xp.maximum(low, bottom), xp.minimum(high, top)
    end = xp.minimum(xp.maximum(end, low), high)
    # The target whose lag ends there (the given one where it was free).
    return end, xp.where(end == free, target, (end - w * q.decay) * q.undecay)


def _lag(xp: ModuleType, q: MPPISettings, w: Any, target: Any, ff: tuple) -> tuple[Any, Any]:
    """``numba_mppi._lag`` over arrays."""
    end, target = _target(xp, q, w, target, ff)
    moved = xp.clip(end - w, min=-q.wheel_step, max=q.wheel_step)
    mean = target + (w - target) * q.lag_mean
    return w + moved, xp.where(moved == end - w, mean, w + 0.5 * moved)


def _move(xp: ModuleType, q: MPPISettings, x, y, c, s, vx, vy, omega) -> tuple:
    """``numba_mppi._move`` over arrays, the half-turn's functions from the library."""
    half = 0.5 * omega * q.dt
    cos_h, sin_h = xp.cos(half), xp.sin(half)
    sinc = xp.where(half == 0.0, 1.0, sin_h / xp.where(half == 0.0, 1.0, half))
    ca, sa = c * cos_h - s * sin_h, s * cos_h + c * sin_h
    fx, fy = sinc * vx * q.dt, sinc * vy * q.dt
    moved = (x + ca * fx - sa * fy, y + sa * fx + ca * fy)
    return (*moved, ca * cos_h - sa * sin_h, sa * cos_h + ca * sin_h)


def _over(xp: ModuleType, value: Any, limit: float) -> Any:
    excess = xp.clip(xp.abs(value) - limit, min=0.0)
    return excess * excess


def _wheel_cost(xp: ModuleType, q: MPPISettings, w0: Any, w1: Any, ff: tuple) -> Any:
    """``numba_mppi._wheel_cost`` over arrays."""
    acceleration = (w1 - w0) / q.dt
    cost = q.wheel_limit * _over(xp, w1, q.max_wheel_velocity)
    cost = cost + q.acceleration_limit * _over(xp, acceleration, q.max_wheel_acceleration)
    if q.voltage_limit > 0.0:
        moving = xp.where(w1 != 0.0, w1, w0)  # numba_mppi._wheel_cost's friction
        voltage = ff[0] * xp.sign(moving) + ff[1] * w1 + ff[2] * acceleration
        cost = cost + q.voltage_limit * _over(xp, voltage, q.max_voltage)
    return cost


def _clearance(xp: ModuleType, q: MPPISettings, grid: Any, x: Any, y: Any, index: Any) -> Any:
    """``Obstacles.clearance_at`` over arrays of the library."""
    rows, cols = grid.shape
    gx = xp.clip((x - q.origin_x) / q.resolution, min=0.0, max=cols - 1.0)
    gy = xp.clip((y - q.origin_y) / q.resolution, min=0.0, max=rows - 1.0)
    i = xp.clip(xp.astype(xp.floor(gy), index), max=rows - 2)
    j = xp.clip(xp.astype(xp.floor(gx), index), max=cols - 2)
    fy, fx = gy - xp.astype(i, gy.dtype), gx - xp.astype(j, gx.dtype)
    flat = xp.reshape(grid, (-1,))

    def at(di: int, dj: int) -> Any:
        return xp.take(flat, (i + di) * cols + (j + dj), axis=0)

    top = at(0, 0) + fx * (at(0, 1) - at(0, 0))
    bottom = at(1, 0) + fx * (at(1, 1) - at(1, 0))
    return top + fy * (bottom - top)
