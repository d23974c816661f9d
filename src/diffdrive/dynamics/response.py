"""A velocity-commanded drive's response, identified from a log.

The model, per wheel: the command ``u`` (rad/s, held from each of its stamps to the next) acts
after a pure ``delay`` (s); the wheel's velocity ``v`` approaches ``gain * u`` as a first-order
lag of ``time_constant`` (s), its change in a step at most ``acceleration`` (rad/s^2) times the
step (``inf``: no limit). Sampled at the log's stamps ``t_k``::

    v_{k+1} = v_k + clip((1 - a_k) (gain * u(t_{k+1} - delay) - v_k), +-acceleration dt_k),
    a_k = exp(-dt_k / time_constant)

``identify_velocity_response`` picks the delay on a grid (a tenth of the mean step, up to
``max_delay``) by a first-order ARX fit's residual, then fits by output error around it: the
gain and time constant that make the model, driven by the commands from the first measured
velocity, closest to the measured velocities (Gauss-Newton from the ARX fit), the best of the
neighbouring delays, then the acceleration limit: the best of ``accelerations``, refined
between its neighbours there (scipy's bounded Brent on its logarithm). The measured
velocities' own noise then does not bias the fit, as it would an ARX fit that takes them as
inputs. The covariance of (gain, time constant) comes from the Gauss-Newton normal matrix and
the residual variance.
"""

from __future__ import annotations

import importlib.util
import itertools
import math
from dataclasses import dataclass

import numpy as np

from diffdrive._optional import optional
from diffdrive._validate import increasing
from diffdrive.dynamics.lag import decay

__all__ = [
    "HeldOutResponse",
    "VelocityResponse",
    "cross_validate_response",
    "held_commands",
    "identify_velocity_response",
    "simulate_response",
]

_LOG_TAU = (math.log(1e-4), math.log(100.0))  # the time constants searched, s


@dataclass(frozen=True, eq=False)
class VelocityResponse:
    """The fitted model (see the module): ``delay`` (s), ``time_constant`` (s), ``gain``,
    ``acceleration`` (rad/s^2, ``inf`` for none), the ``covariance`` (2, 2) of (gain,
    time constant), and the ``rmse`` (rad/s) of its prediction on the log it was fitted on."""

    delay: float
    time_constant: float
    gain: float
    acceleration: float
    covariance: np.ndarray
    rmse: float

    def predict(self, times, command_times, commands, initial) -> np.ndarray:
        """The wheel velocities ``(N, W)`` at ``times`` ``(N,)`` of the model driven by
        ``commands`` ``(M, W)`` held from ``command_times`` ``(M,)``, from ``initial`` ``(W,)``
        at ``times[0]``."""
        times = np.asarray(times, dtype=float)
        return simulate_response(
            times,
            command_times,
            commands,
            self.delay,
            np.asarray(initial, float),
            self.gain,
            self.time_constant,
            self.acceleration,
        )


def held_commands(command_times, commands, at) -> np.ndarray:
    """The commands ``(M, W)`` held from their stamps, at the times ``at``; 0 before the
    first."""
    command_times = np.asarray(command_times, dtype=float)
    commands = np.asarray(commands, dtype=float)
    index = np.searchsorted(command_times, at, side="right") - 1
    values = commands[np.maximum(index, 0)]
    return np.where((index >= 0)[:, None], values, 0.0)


def simulate_response(
    times, command_times, commands, delay, initial, gain, time_constant, acceleration
):
    """The model's wheel velocities ``(N, W)`` at ``times``: integrated exactly between the
    samples and the (delayed) command changes, each piece's command held. Its loop runs
    compiled where numba is installed (``backends/numba_response.py``), in Python else."""
    changes = np.asarray(command_times, dtype=float) + delay
    inside = (changes > times[0]) & (changes < times[-1])
    events = np.union1d(times, changes[inside])
    at_sample = np.isin(events, times)
    held = held_commands(changes, commands, events)  # the command in force from each event on
    pieces = np.diff(events)
    # A time constant of 0: the wheel is at the command at once (as fast as its limit lets).
    keep = decay(pieces, time_constant)
    limits = acceleration * pieces
    target = gain * held[:-1]
    start = np.asarray(initial, dtype=float)
    out = np.empty((len(events), held.shape[1]))
    if _COMPILED:
        from diffdrive.backends.numba_response import respond

        respond(keep, np.ascontiguousarray(target), limits, start, out)
    else:
        _respond(keep.tolist(), target, limits.tolist(), start, out)
    return out[at_sample]


_COMPILED = importlib.util.find_spec("numba") is not None


def _respond(keep: list, target: np.ndarray, limits: list, initial, out: np.ndarray) -> None:
    """``backends.numba_response.respond`` in Python: the same steps in the same order."""
    for w in range(target.shape[1]):
        v = float(initial[w])
        column = [v]
        for remaining, goal, limit in zip(keep, target[:, w].tolist(), limits, strict=True):
            change = (1.0 - remaining) * (goal - v)
            if change > limit:
                change = limit
            elif change < -limit:
                change = -limit
            v += change
            column.append(v)
        out[:, w] = column


def _fit(stretches, command, start, acceleration, iterations=30):
    """Gauss-Newton on (gain, log time constant) over the ``stretches`` ``[(times,
    measured)]``, each driven from its first measured velocity: the parameters, the residual
    sum and the Jacobian at the end."""
    params = np.array([start[0], min(max(math.log(start[1]), _LOG_TAU[0]), _LOG_TAU[1])])
    command_times, commands, delay = command

    def residual(p):
        return np.concatenate(
            [
                (
                    simulate_response(
                        times,
                        command_times,
                        commands,
                        delay,
                        measured[0],
                        p[0],
                        math.exp(p[1]),
                        acceleration,
                    )
                    - measured
                ).ravel()
                for times, measured in stretches
            ]
        )

    current = residual(params)
    for _ in range(iterations):
        jacobian = np.empty((len(current), 2))
        for i, step in enumerate((1e-6 * max(abs(params[0]), 1.0), 1e-6)):
            moved = params.copy()
            moved[i] += step
            jacobian[:, i] = (residual(moved) - current) / step
        delta, *_ = np.linalg.lstsq(jacobian, -current, rcond=None)
        scale = 1.0
        while scale > 1e-4:
            trial = params + scale * delta
            trial[1] = min(max(trial[1], _LOG_TAU[0]), _LOG_TAU[1])  # 0.1 ms to 100 s
            found = residual(trial)
            if found @ found < current @ current:
                break
            scale *= 0.5
        else:
            break
        converged = np.abs(trial - params).max() < 1e-9
        params, current = trial, found
        if converged:
            break
    return params, float(current @ current), jacobian


def identify_velocity_response(
    times: object,
    measured: object,
    command_times: object,
    commands: object,
    *,
    max_delay: float = 0.3,
    accelerations: tuple[float, ...] = (math.inf,),
) -> VelocityResponse:
    """The response of a velocity-commanded drive from wheel velocities ``measured``
    ``(N, W)`` rad/s at ``times`` ``(N,)`` s and the ``commands`` ``(M, W)`` rad/s held from
    ``command_times`` ``(M,)`` s (see the module); ``accelerations`` are the limits tried
    (rad/s^2; ``inf``: none), the best refined between its neighbours (needs scipy).
    ``ValueError`` names what the log lacks."""
    times, measured, command_times, commands = _checked(
        times, measured, command_times, commands, max_delay, accelerations
    )
    return _identify([(times, measured)], command_times, commands, max_delay, accelerations)


def _checked(times, measured, command_times, commands, max_delay, accelerations):
    """The log as float arrays ``(N,), (N, W), (M,), (M, W)``, or ``ValueError`` naming what
    it lacks."""
    times = np.asarray(times, dtype=float)
    measured = np.asarray(measured, dtype=float)
    command_times = np.asarray(command_times, dtype=float)
    commands = np.asarray(commands, dtype=float)
    if measured.ndim == 1:
        measured = measured[:, None]
    if commands.ndim == 1:
        commands = commands[:, None]
    if times.ndim != 1 or len(measured) != len(times) or len(times) < 20:
        raise ValueError(
            f"times (N,) and measured (N, W) must agree, with N >= 20; got {times.shape} and "
            f"{measured.shape}"
        )
    if command_times.ndim != 1 or commands.shape != (len(command_times), measured.shape[1]):
        raise ValueError(
            f"command_times (M,) and commands (M, {measured.shape[1]}) must agree; got "
            f"{command_times.shape} and {commands.shape}"
        )
    arrays = (times, measured, command_times, commands)
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise ValueError("times, measured, command_times and commands must be finite")
    increasing("times", times)
    if np.any(np.diff(command_times) < 0):
        back = int(np.argmax(np.diff(command_times) < 0)) + 1
        raise ValueError(f"command_times must not go back: command_times[{back}] does")
    if len(command_times) == 0 or command_times[0] >= times[-1] or command_times[-1] < times[0]:
        raise ValueError(
            "the commands and the wheels' stamps do not overlap: the log must hold commands "
            "while the wheels are measured"
        )
    if not (math.isfinite(max_delay) and max_delay >= 0.0):
        raise ValueError(f"max_delay must be finite and >= 0 s, got {max_delay}")
    if not accelerations or not all(a > 0.0 for a in accelerations):
        raise ValueError(f"accelerations must be limits > 0 (inf: none), got {accelerations}")
    if np.ptp(commands, axis=0).max() <= 0.0:
        raise ValueError(
            "a constant command cannot show how the drive answers: the log must hold changes "
            "of command"
        )
    return times, measured, command_times, commands


def _identify(stretches, command_times, commands, max_delay, accelerations) -> VelocityResponse:
    """``identify_velocity_response`` on checked ``stretches`` ``[(times, measured)]`` of
    one log (the parts a held-out fold leaves), each its own start."""
    step = float(np.mean(np.concatenate([np.diff(t) for t, _ in stretches])))
    delays = np.arange(0.0, max_delay + 1e-12, step / 10.0)

    def arx(delay: float) -> tuple[float, float, float]:
        held = [held_commands(command_times, commands, t - delay) for t, _ in stretches]
        return _arx([m for _, m in stretches], held)

    # The delay by the first-order ARX fit's residual (fast), then refined by output error
    # over its neighbours.
    centre = int(np.argmin([arx(d)[2] for d in delays]))
    # The sampled ARX sees the delay only to a step: output error over a step either side.
    gain, keep, _ = arx(delays[centre])
    start = (gain, -step / math.log(keep))
    best = None
    for delay in delays[max(centre - 10, 0) : centre + 11]:
        found = _fit(stretches, (command_times, commands, delay), start, math.inf, 6)
        if best is None or found[1] < best[1]:
            best = (delay, found[1], found[0])
    delay, _, params = best  # type: ignore[misc]
    start = (params[0], math.exp(params[1]))

    def fitted(acceleration: float):
        return _fit(stretches, (command_times, commands, delay), start, acceleration)

    tried = sorted(set(accelerations))
    fits = [fitted(a) for a in tried]
    chosen = int(np.argmin([f[1] for f in fits]))
    acceleration, (params, cost, jacobian) = tried[chosen], fits[chosen]
    if math.isfinite(acceleration) and len(tried) > 1:
        acceleration, (params, cost, jacobian) = _refined(tried, chosen, fitted, fits[chosen])
    count = sum(m.size for _, m in stretches)
    variance = cost / max(count - 3, 1)
    normal = np.linalg.pinv(jacobian.T @ jacobian) * variance
    tau = math.exp(params[1])
    by = np.diag([1.0, tau])  # from (gain, log tau) to (gain, tau)
    return VelocityResponse(
        float(delay),
        tau,
        float(params[0]),
        float(acceleration),
        by @ normal @ by,
        math.sqrt(cost / count),
    )


@dataclass(frozen=True, eq=False)
class HeldOutResponse:
    """``cross_validate_response``'s result. Per fold: the ``responses`` identified without it,
    and the held-out RMSE (rad/s) of their predictions, ``rmse``, and of the instant kinematic
    response (the wheels at their commands at once), ``instant``. Pooled over every scored
    sample: ``pooled`` and ``pooled_instant``. ``predicted`` and ``at_once`` ``(N, W)``: what
    was scored at each sample (NaN where nothing was)."""

    responses: tuple[VelocityResponse, ...]
    rmse: np.ndarray
    instant: np.ndarray
    pooled: float
    pooled_instant: float
    predicted: np.ndarray
    at_once: np.ndarray

    @property
    def ratio(self) -> float:
        """``pooled / pooled_instant``: below 1, the response predicts better."""
        return self.pooled / self.pooled_instant


def cross_validate_response(
    times: object,
    measured: object,
    command_times: object,
    commands: object,
    *,
    folds: int = 5,
    segment: float = 5.0,
    max_delay: float = 0.3,
    accelerations: tuple[float, ...] = (math.inf,),
) -> HeldOutResponse:
    """The response scored on time it was not identified on: the log (as
    ``identify_velocity_response`` takes it) cut into ``folds`` blocks of equal length, each
    in turn held out and the response identified on the rest (the parts before and after it,
    each its own start); the held-out block cut into ``segment``-second pieces, each predicted
    from its first measured velocity by the commands alone. ``ValueError`` when a block holds
    no whole piece or leaves too little to identify on."""
    t, v, stamps, wanted = _checked(
        times, measured, command_times, commands, max_delay, accelerations
    )
    if isinstance(folds, bool) or not isinstance(folds, int) or folds < 2:
        raise ValueError(f"folds must be a whole number >= 2, got {folds!r}")
    step = float(np.mean(np.diff(t)))
    if not (math.isfinite(segment) and segment > 0.0):
        raise ValueError(f"segment must be a finite time > 0 s, got {segment!r}")
    piece = max(2, round(segment / step))
    bounds = np.linspace(0, len(t), folds + 1).round().astype(int)
    if np.diff(bounds).min() < piece:
        raise ValueError(
            f"{folds} folds of a {t[-1] - t[0]:.3g} s log are shorter than one "
            f"{segment:g} s segment: fewer folds or shorter segments"
        )
    predicted = np.full(v.shape, np.nan)
    at_once = np.full(v.shape, np.nan)
    responses, rmse, instant = [], [], []
    for lo, hi in itertools.pairwise(bounds.tolist()):
        stretches = [(t[a:b], v[a:b]) for a, b in ((0, lo), (hi, len(t)))]
        stretches = [(part, wheels) for part, wheels in stretches if len(part) >= 20]
        if not stretches:
            raise ValueError(
                f"holding out {t[lo]:.3g}-{t[hi - 1]:.3g} s leaves under 20 samples "
                "to identify on: more folds or a longer log"
            )
        found = _identify(stretches, stamps, wanted, max_delay, accelerations)
        for start in range(lo, hi - piece + 1, piece):
            part = slice(start, start + piece)
            predicted[part] = found.predict(t[part], stamps, wanted, v[start])
            at_once[part] = held_commands(stamps, wanted, t[part])
        block = slice(lo, lo + (hi - lo) // piece * piece)  # its whole pieces
        responses.append(found)
        rmse.append(math.sqrt(np.mean((predicted[block] - v[block]) ** 2)))
        instant.append(math.sqrt(np.mean((at_once[block] - v[block]) ** 2)))
    scored = ~np.isnan(predicted)
    return HeldOutResponse(
        tuple(responses),
        np.array(rmse),
        np.array(instant),
        math.sqrt(np.mean((predicted[scored] - v[scored]) ** 2)),
        math.sqrt(np.mean((at_once[scored] - v[scored]) ** 2)),
        predicted,
        at_once,
    )


def _refined(tried: list[float], best: int, fitted, at_best):
    """The acceleration limit between the grid's neighbours of the best one tried (half and
    twice it at an end), by bounded Brent on its logarithm: the limit and its fit."""
    minimize_scalar = optional(
        "scipy.optimize", "calibration", "refining the acceleration limit between those tried"
    ).minimize_scalar

    low = tried[best - 1] if best > 0 else tried[best] / 2.0
    high = tried[best + 1] if best + 1 < len(tried) else 2.0 * tried[best]
    high = min(high, 2.0 * tried[best])  # the next one tried may be inf: no limit
    fits: dict[float, tuple] = {}

    def cost(log_acceleration: float) -> float:
        fits[log_acceleration] = fitted(math.exp(log_acceleration))
        return fits[log_acceleration][1]

    found = minimize_scalar(
        cost, bounds=(math.log(low), math.log(high)), method="bounded", options={"xatol": 1e-3}
    )
    if found.fun >= at_best[1]:
        return tried[best], at_best
    return math.exp(found.x), fits[found.x]


def _arx(measured, held) -> tuple[float, float, float]:
    """The ARX fit ``v_{k+1} = a v_k + b u_{k+1}`` over every wheel of every stretch
    (``measured`` and ``held``: lists of ``(N_i, W)``): the gain ``b / (1 - a)``, ``a`` (kept
    in (0, 1)) and the residual sum of squares."""
    x = np.column_stack(
        [
            np.concatenate([m[:-1].ravel() for m in measured]),
            np.concatenate([h[1:].ravel() for h in held]),
        ]
    )
    y = np.concatenate([m[1:].ravel() for m in measured])
    (a, b), *_ = np.linalg.lstsq(x, y, rcond=None)
    residual = float(np.sum((x @ np.array([a, b]) - y) ** 2))
    a = min(max(float(a), 1e-3), 0.999)
    return (float(b) / (1.0 - a) if b else 1.0), a, residual
