"""The sample times of a fixed-rate publisher whose stamps are a clock tick early at times.

A simulator that steps in ticks (Gazebo: 1 ms) samples a plugin's state at the first tick
past each period, but the node stamps the message with its own copy of the clock, which a
``/clock`` message a tick late leaves one tick behind at times: that stamp is a tick early.
A velocity differenced over one 33 ms interval is then 3 % off, up or down, on both intervals
around such a stamp: on the TurtleBot3 bag, 441 of 2741 ``/joint_states`` stamps are a tick
early, and the velocities' noise, 0.08 rad/s (robust spread of their second differences)
with the stamps, falls to 0.003 rad/s with the sample times.

``sample_times`` finds the period and the phase on which the stamps fall (the first tick past
``start + k period`` for each message ``k``, messages dropped allowed), and returns those
times when the stamps bear it out: at least ``share`` of them exactly on it and every other
a tick early. Otherwise it refuses, saying how many stamps fit: stamps with any other jitter
are not this, and are left to the caller. Where a sample's ideal time lies within a small
fraction of a tick past a tick, a period a hair different can put its early stamp on a tick:
the stamps cannot tell the two apart, and the times with the most stamps on their ticks are
taken (the likelier while fewer than half are early). On 300 random records of 100 to 3000
messages (periods of 5 to 60 ticks, up to 30 % early) that leaves 1 to 4 samples a tick off in
one record in four: 0.2 % of the early stamps, against all of them in the stamps themselves
(the property test has found a record of 400 with 6, whose times leave 113 stamps early where
the truth leaves 117).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diffdrive._validate import finite, increasing, positive

__all__ = ["SampleTimes", "sample_times"]


@dataclass(frozen=True, eq=False)
class SampleTimes:
    """``times`` ``(N,)`` s, the sample times restored; ``period`` (s) the publisher's;
    ``moved`` how many stamps were off them (each by one ``tick``)."""

    times: np.ndarray
    period: float
    moved: int


def sample_times(times: object, tick: float = 1e-3, *, share: float = 0.8) -> SampleTimes:
    """The sample times behind ``times`` ``(N,)`` s, stamps of a fixed-rate publisher on a
    clock of ``tick`` s, some a tick early (see the module). ``ValueError`` when
    the stamps do not fit that within one tick, or fit it exactly at fewer than ``share``."""
    stamps = np.asarray(times, dtype=float)
    if stamps.ndim != 1 or len(stamps) < 10:
        raise ValueError(f"times must be (N,) s with N >= 10, got shape {stamps.shape}")
    increasing("times", stamps)
    tick = positive("tick", tick)
    if not 0.0 < finite("share", share) <= 1.0:
        raise ValueError(f"share must lie in (0, 1], got {share!r}")
    guess = float(np.median(np.diff(stamps)))
    if guess < 4.5 * tick:  # stamps on ticks: a median of 5 ticks is 5, give or take a bit
        raise ValueError(
            f"the stamps' period, {guess:g} s, spans under 5 ticks of {tick:g} s: a tick "
            "early cannot be told from the period"
        )
    # Periods between neighbours (more than one where messages were dropped), counted one
    # gap at a time: rounding the whole span by the median would drift.
    gaps = np.round(np.diff(stamps) / guess)
    if np.any(gaps < 1):
        raise ValueError(
            "the stamps do not follow a fixed period: two fall within half a period of each other"
        )
    counts = np.concatenate([[0.0], np.cumsum(gaps)])
    seen = (stamps - stamps[0]) / tick  # in ticks from the first stamp
    # On ticks, some one early, the stamps stay within 2 ticks of the line through them; the
    # search below would take long to find nothing in stamps that wander further.
    wander = float(np.ptp(seen - np.polyval(np.polyfit(counts, seen, 1), counts)))
    if wander > 3.0:
        raise ValueError(
            f"the stamps are not a fixed period on a {tick:g} s clock, some a tick early: they "
            f"wander {wander:.3g} ticks about a fixed period (at most 2 would be; times and "
            "tick must be in one unit, seconds unless both are given otherwise)"
        )
    grid, period = _ticks(counts, seen)
    off = seen - grid
    on = np.abs(off) < 0.25
    early = np.abs(off + 1.0) < 0.25
    if on.sum() < share * len(stamps) or not np.all(on | early):
        raise ValueError(
            f"the stamps are not a fixed period on a {tick:g} s clock, some a tick early: "
            f"{int(on.sum())} of {len(stamps)} fall on the period's ticks and "
            f"{int(np.sum(~on & ~early))} lie further than a tick from them (needed: at least "
            f"{share:.0%} on them, none further)"
        )
    return SampleTimes(stamps[0] + grid * tick, period * tick, int(early.sum()))


def _ticks(counts: np.ndarray, seen: np.ndarray) -> tuple[np.ndarray, float]:
    """The ticks (from the first stamp) of the samples, the first tick past ``offset + k
    period`` for message ``k`` (``counts``), and the period (ticks): those that leave the
    fewest stamps ``seen`` neither on their tick nor a tick early, then the most on it.

    A stamp on its tick ``s`` bounds the offset to ``(s - 1 - k period, s - k period]``, one
    a tick early to the next tick's interval. For each period tried (a fine grid around the
    least-squares one, which the early stamps pull by a little), every offset between two
    bounds is scored, and the middle of the widest run of the best kept."""
    slope, spread = np.polyfit(counts, seen, 1, cov=True)
    period, error = slope[0], float(np.sqrt(spread[0, 0]))
    # Stamps all on their ticks fit every period within a tick over the span of the log: the
    # least-squares one, pulled by the ticks' rounding, can lie outside 5 of its errors.
    reach = 5.0 * error + 2.0 / counts[-1]
    every = _all_on_their_ticks(counts, seen, period - reach, period + reach)
    if every is not None:  # the most the stamps can say: none early
        trial, offset = every
        return np.ceil(counts * trial + offset - 1e-9), float(trial)
    # Steps of 0.002 / k ticks move the last message's ideal time by a 500th of a tick: the
    # offsets that hold every stamp can be as narrow as that. The same reach: with a period
    # near a whole number of ticks the ticks' rounding is a slow sawtooth, not white, and
    # pulls the least-squares period further than its errors say.
    tries = min(max(11, int(np.ceil(2.0 * reach * counts[-1] / 0.002)) | 1), 4001)
    best = None
    for trial in np.linspace(period - reach, period + reach, tries):
        upper = np.sort(seen - counts * trial)
        lower, early = upper - 1.0, upper + 1.0
        ends = np.unique(np.concatenate([lower, upper, early]))
        middles = 0.5 * (ends[1:] + ends[:-1])
        below = np.searchsorted(lower, middles)
        exact = below - np.searchsorted(upper, middles)
        either = below - np.searchsorted(early, middles)
        score = either * (len(seen) + 1) + exact
        held = np.flatnonzero(score == score.max())
        runs = np.split(held, np.flatnonzero(np.diff(held) > 1) + 1)
        widest = max(runs, key=lambda r: ends[r[-1] + 1] - ends[r[0]])
        width = ends[widest[-1] + 1] - ends[widest[0]]
        if best is None or (score.max(), width) > best[:2]:
            best = (score.max(), width, trial, 0.5 * (ends[widest[0]] + ends[widest[-1] + 1]))
    _, _, trial, offset = best  # type: ignore[misc]
    return np.ceil(counts * trial + offset - 1e-9), float(trial)


def _all_on_their_ticks(
    counts: np.ndarray, seen: np.ndarray, low: float, high: float
) -> tuple[float, float] | None:
    """A period in ``[low, high]`` and an offset that put every stamp on its own tick, if
    there are any: ``(period, offset)`` at the middle of the widest offsets, else None.

    Every stamp on its tick ``s`` bounds the offset to ``(s - 1 - k period, s - k period]``;
    how wide their common part is, ``min(s - k p) - max(s - 1 - k p)``, is concave in the
    period ``p``, so a search by thirds finds its largest. ``_ticks``' grid can step over
    that band, which is as narrow as the stamps' slack allows (a phase exactly on a tick
    leaves almost none)."""

    def width(trial: float) -> float:
        upper = seen - counts * trial
        return float(upper.min() - (upper.max() - 1.0))

    for _ in range(200):
        left, right = low + (high - low) / 3.0, high - (high - low) / 3.0
        if width(left) < width(right):
            low = left
        else:
            high = right
    trial = 0.5 * (low + high)
    if width(trial) <= 1e-6:  # leaves room for the ceiling's 1e-9 below each tick
        return None
    upper = seen - counts * trial
    return trial, 0.5 * (upper.min() + upper.max() - 1.0)
