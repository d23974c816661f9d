"""Synthetic wheel encoders: what a robot's counters would read along a trajectory.

Each robot's wheels turn as its true geometry makes them turn along the trajectory (the
nominal radii and track with ``radius_bias``, ``track_bias`` and a per-robot draw of
``geometry_sigma``, the errors calibration fits), then, in this order:

1. slip episodes (``Slip``): over an episode a wheel turns ``1 + ratio`` times as far as the
   ground under it moves; the intervals are labelled;
2. wheel random-walk noise, ``wheel_noise`` (a ``WheelNoise``, none by default): each
   interval's travel of a wheel (m) gets a variance of ``k |travel|`` (m^2);
3. the angles accumulate from 0 and are read at each sample's instant: its stamp less the
   ``latency`` plus a ``jitter`` (s, standard deviation), interpolated along the interval;
4. quantisation to whole counts (``ticks_per_revolution``; None: angles in rad), and
   roll-over of a ``counter_bits``-bit counter, ``signed`` or not (``diffdrive.encoders``'s
   widths);
5. dropped samples: each row after the first is lost with probability ``drop``.

Everything is drawn from one seeded generator, batched over robots: ``(N, T+1, 2)`` readings.
"""

from __future__ import annotations

import importlib.util
import math
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from diffdrive._validate import finite, rng_of
from diffdrive.encoders import check_counter_bits
from diffdrive.io.run import Run
from diffdrive.model import Robot
from diffdrive.sensor_noise import NONE as NO_NOISE
from diffdrive.sensor_noise import WheelNoise, draw_travel
from diffdrive.sensors.motion import (
    NOT_FINITE,
    ONE_TURN,
    Motion,
    checked_trajectory,
    motion_of,
    robot_count,
    robot_geometry,
)

__all__ = ["EncoderModel", "EncoderReadings", "Slip", "encoder_readings"]

Wheel = Literal["left", "right", "both"]


@dataclass(frozen=True)
class Slip:
    """A slip episode from ``start`` to ``stop`` (s): the ``wheel`` (``"left"``, ``"right"``
    or ``"both"``) turns ``1 + ratio`` times as far as the ground under it moves (``ratio``
    > -1: 0.5 spins half again as far, -0.5 slides half its travel)."""

    start: float
    stop: float
    wheel: Wheel = "left"
    ratio: float = 0.5

    def __post_init__(self) -> None:
        start, stop = finite("start", self.start), finite("stop", self.stop)
        if not stop > start:
            raise ValueError(f"a slip episode must end after it starts, got {start} to {stop}")
        if self.wheel not in ("left", "right", "both"):
            raise ValueError(f"wheel must be left, right or both, got {self.wheel!r}")
        if not finite("ratio", self.ratio) > -1.0:
            raise ValueError(
                f"ratio must be > -1 (a wheel cannot turn backwards), got {self.ratio}"
            )


def _at_least(name: str, value: object, smallest: float = 0.0) -> float:
    number = finite(name, value)
    if number < smallest:
        raise ValueError(f"{name} must be >= {smallest:g}, got {value!r}")
    return number


@dataclass(frozen=True)
class EncoderModel:
    """The encoders' error sources (see the module); every default is the ideal encoder."""

    ticks_per_revolution: float | None = None
    counter_bits: int | None = None
    signed: bool = True
    radius_bias: tuple[float, float] = (0.0, 0.0)
    track_bias: float = 0.0
    geometry_sigma: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wheel_noise: WheelNoise = NO_NOISE
    slips: tuple[Slip, ...] = field(default=())
    jitter: float = 0.0
    latency: float = 0.0
    drop: float = 0.0

    def __post_init__(self) -> None:
        if self.ticks_per_revolution is not None:
            ticks = finite("ticks_per_revolution", self.ticks_per_revolution)
            if not ticks > 0:
                raise ValueError(f"ticks_per_revolution must be > 0, got {ticks!r}")
        check_counter_bits(self.counter_bits)
        if self.counter_bits is not None and self.ticks_per_revolution is None:
            raise ValueError("counter_bits needs ticks_per_revolution: a counter counts ticks")
        object.__setattr__(self, "wheel_noise", WheelNoise.coerce(self.wheel_noise))
        for name in ("jitter", "latency"):
            _at_least(name, getattr(self, name))
        if not 0.0 <= finite("drop", self.drop) < 1.0:
            raise ValueError(f"drop must be a probability in [0, 1), got {self.drop!r}")
        biases = [*self.radius_bias, self.track_bias]
        if len(self.radius_bias) != 2 or not all(finite("bias", b) > -1.0 for b in biases):
            raise ValueError(
                "radius_bias (left, right) and track_bias are relative errors > -1, got "
                f"{self.radius_bias!r} and {self.track_bias!r}"
            )
        if len(self.geometry_sigma) != 3:
            raise ValueError(
                f"geometry_sigma must be 3 relative deviations, got {self.geometry_sigma!r}"
            )
        for value in self.geometry_sigma:
            _at_least("geometry_sigma", value)
        if not all(isinstance(slip, Slip) for slip in self.slips):
            raise TypeError("slips must be Slip episodes")


@dataclass(frozen=True, eq=False)
class EncoderReadings:
    """``readings`` ``(N, T+1, 2)`` ``[left, right]``: counts (int64; uint64 for an unsigned
    64-bit counter) or angles (rad) without ``ticks_per_revolution``, at ``times`` ``(T+1,)``;
    ``kept`` ``(N, T+1)`` the rows not dropped; ``slipping`` ``(N, T, 2)`` each wheel's slip
    label per interval; ``geometry`` ``(N, 3)`` each robot's true ``[r_left, r_right, track]``;
    ``truth`` ``(B, T+1, 3)`` the trajectory."""

    times: np.ndarray
    readings: np.ndarray
    kept: np.ndarray
    slipping: np.ndarray
    geometry: np.ndarray
    truth: np.ndarray
    model: EncoderModel

    def run(self, robot: int = 0) -> Run:
        """Robot ``robot``'s readings as a ``Run`` (its kept rows, the trajectory as truth)."""
        keep = self.kept[robot]
        truth = self.truth[robot if len(self.truth) > 1 else 0][keep]
        ticks = self.model.ticks_per_revolution
        return Run(
            self.times[keep],
            "ticks" if ticks is not None else "angle",
            self.readings[robot][keep],
            truth,
            f"synthetic encoders, robot {robot}",
            ticks_per_revolution=ticks,
        )


def encoder_readings(
    robot: Robot,
    times: object,
    poses: object,
    model: EncoderModel | None = None,
    *,
    robots: int | None = None,
    seed: int | None = None,
) -> EncoderReadings:
    """What the encoders of ``robots`` robots (default: one per trajectory) read along the
    trajectory ``times`` ``(T+1,)``, ``poses`` ``(T+1, 3)`` or ``(N, T+1, 3)``, with the
    errors of ``model`` drawn from ``seed``."""
    model = EncoderModel() if model is None else model
    t, p = checked_trajectory(times, poses, finite=False)
    # Through the compiled kernel where numba is, which checks the poses as it reads them.
    fast = not (model.latency or model.jitter) and _compiled()
    if not fast and not np.all(np.isfinite(p)):
        raise ValueError(NOT_FINITE)
    count = robot_count(len(p), robots)
    rng = rng_of(seed)
    geometry = robot_geometry(
        robot, count, model.radius_bias, model.track_bias, model.geometry_sigma, rng
    )
    factor, slipping = _slip_factors(t, model)
    ticks = model.ticks_per_revolution
    scale = 1.0 if ticks is None else ticks / (2.0 * math.pi)
    readings = np.empty((count, len(t), 2), dtype=np.float64 if ticks is None else np.int64)
    if fast:
        _read_compiled(robot, p, factor, geometry, model, rng, scale, readings)
    else:
        _read_in_numpy(robot, t, p, factor, geometry, model, rng, scale, readings)
    if ticks is not None and model.counter_bits == 64 and not model.signed:
        readings = readings.view(np.uint64)  # the same bits, read without a sign
    kept = np.ones((count, len(t)), dtype=bool)
    if model.drop:
        kept[:, 1:] = rng.random((count, len(t) - 1)) >= model.drop
    slipping = np.broadcast_to(slipping, (count, *slipping.shape))
    return EncoderReadings(t, readings, kept, slipping, geometry, p, model)


def _compiled() -> bool:
    """Whether numba is installed (the compiled kernel's ``fast`` extra)."""
    return importlib.util.find_spec("numba") is not None


def _read_compiled(robot, poses, factor, geometry, model, rng, scale, readings) -> None:
    """The readings through ``backends.numba_encoders``, one pass a robot on every core (a
    trajectory each, or one they share). With wheel noise, block by block: the standard
    normals drawn as the NumPy path draws them (so that a seed gives the same robots either
    way), one block at a time, while other threads run the kernel on theirs: the draw is half
    the work, and one generator fills in order."""
    from diffdrive.backends.numba_encoders import read_encoders, read_encoders_serial, scan
    from diffdrive.backends.simulate_kernel import threads

    finite, span = scan(poses)
    if not finite:
        raise ValueError(NOT_FINITE)
    noise, turned = model.wheel_noise, bool(span > ONE_TURN)  # as motion.unwrapped
    counts = model.ticks_per_revolution is not None
    bits = 0 if model.counter_bits is None else model.counter_bits

    def run(kernel, rows: slice, normals: np.ndarray) -> None:
        own = poses[rows] if len(poses) > 1 else poses  # one shared trajectory serves all
        overflow = kernel(
            own,
            robot.reference_offset,
            turned,
            factor,
            geometry[rows],
            noise.k,
            normals,
            bool(noise),
            scale,
            counts,
            bits,
            model.signed,
            readings[rows],
        )
        if overflow.any():
            raise ValueError(_TOO_MANY_COUNTS)

    if not noise:
        run(read_encoders, slice(None), _NONE)
        return
    # Blocks of half a million normals, each drawn in turn under a lock (the stream is the
    # NumPy path's whatever the block or thread, as a generator fills in order) and read by
    # the kernel on the thread that drew it, while the other threads draw or read theirs.
    steps = poses.shape[1] - 1
    block = max(1, (1 << 19) // (2 * steps))
    starts, lock = iter(range(0, len(readings), block)), threading.Lock()

    def work() -> None:
        normals = np.empty((block, 2, steps))  # one buffer a thread, used again
        while True:
            with lock:
                first = next(starts, None)
                if first is None:
                    return
                rows = slice(first, min(len(readings), first + block))
                drawn = normals[: rows.stop - first]
                rng.standard_normal(out=drawn)
            run(read_encoders_serial, rows, drawn)

    with ThreadPoolExecutor(threads()) as pool:
        for job in [pool.submit(work) for _ in range(threads())]:
            job.result()  # raises what the thread raised


_NONE = np.zeros((1, 2, 1))  # no noise: the kernel reads no normals
_TOO_MANY_COUNTS = "the wheels turn more counts than an int64 holds: fewer ticks or steps"


def _read_in_numpy(robot, times, poses, factor, geometry, model, rng, scale, readings) -> None:
    """The readings in NumPy stages over blocks of robots (see ``_read_compiled``)."""
    motion = motion_of(robot, times, poses)
    forward, turn = _ground_travel(motion, factor)
    ticks = model.ticks_per_revolution
    # A robot's wheel angle is (forward travel -+ half its track times the turn) over its
    # radius, summed: with the sums of the trajectory's shared, a few robots at a time keep
    # every temporary in the cache, whatever the batch.
    block = max(1, _BLOCK_ELEMENTS // readings[0].size)
    for first in range(0, len(readings), block):
        rows = slice(first, min(len(readings), first + block))
        own = rows if len(forward) > 1 else slice(None)  # a batch's own trajectories
        travel = (forward[own], turn[own], motion.increments[own])
        angles = _angles(travel, geometry[rows], model, rng, scale)
        angles = _sampled(motion.times, angles, model, rng)
        # The readings are (time, wheel) a robot, as every array of the project is.
        if ticks is None:
            readings[rows] = angles.transpose(0, 2, 1)
        else:
            _counts(angles, readings[rows].transpose(0, 2, 1), model.counter_bits, model.signed)


# Float64 elements of one block's angles: a few robots' worth, well inside a core's cache.
_BLOCK_ELEMENTS = 1 << 16


def _slip_factors(times: np.ndarray, model: EncoderModel) -> tuple[np.ndarray, np.ndarray]:
    """Each wheel's travel factor over each interval ``(2, T)`` (1 where it does not slip,
    ``1 + ratio`` in a slip episode) and the slip labels ``(T, 2)``; ``ValueError`` for an
    episode outside the run."""
    factor = np.ones((2, len(times) - 1))
    middle = 0.5 * (times[1:] + times[:-1])
    for slip in model.slips:
        if slip.start < times[0] or slip.stop > times[-1]:
            raise ValueError(
                f"slip episode {slip.start:g} to {slip.stop:g} s lies outside the run "
                f"({times[0]:g} to {times[-1]:g} s)"
            )
        inside = (middle >= slip.start) & (middle < slip.stop)
        for side in {"left": [0], "right": [1], "both": [0, 1]}[slip.wheel]:
            factor[side, inside] *= 1.0 + slip.ratio
    return factor, (factor != 1.0).T


def _ground_travel(motion: Motion, factor: np.ndarray):
    """Each wheel's share of the trajectory, accumulated from 0: ``(B, 2, T+1)`` sums (wheels
    before time, so that every loop runs along time) of the forward travel (m) and of the turn
    (rad), each interval's scaled by its slip ``factor`` ``(2, T)``."""
    steps = len(motion.times) - 1
    sums = []
    for part in (motion.increments[..., 0], motion.increments[..., 2]):  # (B, T)
        summed = np.zeros((len(part), 2, steps + 1))
        np.cumsum(part[:, None, :] * factor, axis=-1, out=summed[..., 1:])
        sums.append(summed)
    return sums[0], sums[1]


def _angles(travel, geometry, model, rng, scale) -> np.ndarray:
    """The wheel angles ``(n, 2, T+1)`` of robots of ``geometry`` ``(n, 3)``, times ``scale``
    (counts per rad, or 1), with their wheel noise; ``travel`` is ``_ground_travel``'s sums
    and the increments ``(1 or n, T, 3)`` of their trajectories."""
    forward, turn, increments = travel
    radii = geometry[:, :2]
    half_track = 0.5 * geometry[:, 2:3] * np.array([-1.0, 1.0])  # left -, right +
    by_forward = (scale / radii)[..., None]  # (n, 2, 1)
    by_turn = (scale * half_track / radii)[..., None]
    angles = forward * by_forward
    angles += turn * by_turn
    if model.wheel_noise:
        arcs = half_track[..., None] * increments[:, None, :, 2]
        arcs += increments[:, None, :, 0]  # (n, 2, T) m
        noise = draw_travel(arcs, model.wheel_noise.k[:, None], rng)
        noise *= by_forward  # m to counts (or rad)
        np.cumsum(noise, axis=-1, out=noise)
        angles[..., 1:] += noise
    return angles


def _sampled(times: np.ndarray, angles: np.ndarray, model: EncoderModel, rng) -> np.ndarray:
    """The angles ``(n, 2, T+1)`` at each sample's instant: its stamp less the latency, plus
    the jitter (one instant for both wheels of a sample)."""
    if not (model.latency or model.jitter):
        return angles
    shape = (len(angles), len(times))
    instants = np.broadcast_to(times - model.latency, shape)
    if model.jitter:
        instants = instants + model.jitter * rng.standard_normal(shape)
    instants = np.clip(instants, times[0], times[-1])
    k = np.clip(np.searchsorted(times, instants, side="right") - 1, 0, len(times) - 2)
    into = ((instants - times[k]) / (times[k + 1] - times[k]))[:, None, :]
    rows = np.arange(len(angles))[:, None, None]
    wheels = np.arange(2)[None, :, None]
    before, after = angles[rows, wheels, k[:, None, :]], angles[rows, wheels, k[:, None, :] + 1]
    return before + into * (after - before)


def _counts(scaled: np.ndarray, counts: np.ndarray, bits: int | None, signed: bool) -> None:
    """Whole counts into ``counts`` (int64) of angles already in counts, rolled over as a
    ``bits``-bit counter would (an unsigned 64-bit counter's bits are read without a sign
    by the caller)."""
    np.floor(scaled, out=scaled)
    if not (scaled.min() > -(2.0**63) and scaled.max() < 2.0**63):
        raise ValueError(_TOO_MANY_COUNTS)
    counts[...] = scaled
    if bits is None or bits == 64:
        return
    span = np.int64(1) << np.int64(bits)
    if signed:
        half = span >> np.int64(1)
        counts += half
        np.mod(counts, span, out=counts)
        counts -= half
    else:
        np.mod(counts, span, out=counts)
