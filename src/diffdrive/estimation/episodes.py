"""Slip episodes in a whole log: runs of intervals that one slipping wheel explains.

The streaming slip test judges each interval alone: the wheels' turn against the gyro's,
squared over its variance, above ``SLIP_THRESHOLD`` (chi-square, one degree of freedom; 0.1 %
of intervals without slip). An interval whose slip turns the robot by three standard
deviations of that difference passes it about half the time, however long the slip lasts: a
slowly turning wheel that spins half again as far as the ground moves is such a slip.

A whole log can pool them. A wheel slipping by ``ratio`` turns ``1 + ratio`` times as far as
the ground moves, so the wheels' turn is off by ``ratio / (1 + ratio)`` times that wheel's own
turn share: the innovations of an episode lie along a known direction (each interval's
``by_left`` or ``by_right``) with one unknown size. Over a run of intervals the
generalised likelihood ratio of "one wheel slips by one unknown fraction" against "no slip" is
``(sum u z)^2 / sum u^2`` (``z`` each innovation over its standard deviation, ``u`` its
direction likewise scaled), chi-square with one degree of freedom without slip. The runs are
chosen by optimal partitioning (dynamic programming; Jackson et al., IEEE Signal Processing
Letters 12(2), 2005): the partition of the log into plain intervals and episodes of at most
``longest`` intervals that maximises the summed ratios of its episodes less ``penalty`` each
and ``edge_cost`` for each interval in them.

The penalty pays for having looked at every run (a scan statistic): without slip, runs whose
ratio passes 22 still flag 0.02-0.1 % of intervals, none at ``EPISODE_PENALTY`` (40) over 2 x
10^5 simulated intervals each of driving straight, turning in place and stop-and-go, nor over
10^5 intervals of the synthetic runs in ``benchmarks/bench_slip_detection.py``. A weak slip's
edges are uncertain by an interval or more; the edge cost keeps an episode from reaching into
the intervals beside it unless they lean its way (with none, a slip of 20 % doubled the false
alarms there).

A wrong wheel radius, track or gyro scale moves every interval's innovation along the same
directions, all the time; pooled, that looks like one long slip. ``steady_episodes`` first
takes out the log's steady share of each wheel's turn, fitted outside the flagged intervals.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np

# The C programme beside the estimator's core where it was built (DIFFDRIVE_PURE_PYTHON=1: the
# twin anyway, as the cores).
_partition: Callable[..., None] | None
try:
    if os.environ.get("DIFFDRIVE_PURE_PYTHON") == "1":
        raise ImportError("DIFFDRIVE_PURE_PYTHON=1")
    from diffdrive.backends._odometry import _partition
except ImportError:
    _partition = None

__all__ = [
    "EDGE_COST",
    "EPISODE_PENALTY",
    "LONGEST",
    "episode_ratio",
    "partition",
    "slip_episodes",
    "steady_episodes",
]

EPISODE_PENALTY = 40.0
EDGE_COST = 0.5
LONGEST = 50  # intervals; a longer slip is found as several episodes


def slip_episodes(
    scaled: np.ndarray,
    directions: np.ndarray,
    penalty: float = EPISODE_PENALTY,
    edge_cost: float = EDGE_COST,
    longest: int = LONGEST,
) -> np.ndarray:
    """Which intervals lie in a slip episode: ``scaled`` ``(N,)`` innovations over their
    standard deviations, ``directions`` ``(N, 2)`` how far each moves per unit of the left and
    right wheel's slip fraction, on the same scale. Returns ``(N,)`` bool."""
    flagged = np.zeros(len(scaled), dtype=bool)
    for first, end in partition(scaled, directions, penalty, edge_cost, longest):
        flagged[first:end] = True
    return flagged


def steady_episodes(
    scaled: np.ndarray,
    directions: np.ndarray,
    flagged: np.ndarray,
    bias: np.ndarray,
    shared: np.ndarray,
) -> np.ndarray:
    """``slip_episodes`` after the log's steady disagreement is taken out: one fraction per
    wheel and a gyro bias error, fitted by least squares over the intervals outside
    ``flagged`` ``(N,)`` (those the per-interval test flags) and then outside the episodes
    found too. ``bias`` ``(N,)``: how far each scaled innovation moves per rad/s of bias;
    ``shared`` ``(N, 2)``: each wheel's noise variance in it, which its direction carries too
    (both come from the measured turn), so a plain fit would find a fraction of about
    ``k / travel`` in pure noise; the fit takes that expectation out (errors in variables),
    as far as the innovations show that noise (``_steady``).

    A radius, track or gyro scale error moves every interval's innovation along the wheels'
    directions all the time: the geometry's error, which a slip test should not call slip;
    a bias the filter has not settled on leans the same way wherever the robot turns one way
    more than the other."""
    design = np.column_stack([directions, bias])
    outside = ~flagged
    found = np.zeros(len(scaled), dtype=bool)
    for _ in range(2):
        if not outside.any():
            break
        found = slip_episodes(
            scaled - design @ _steady(scaled, design, shared, outside), directions
        )
        outside = ~(flagged | found)
    return found


def _steady(scaled, design, shared, outside) -> np.ndarray:
    """The steady share (each wheel's fraction, the bias error) fitted over ``outside``, the
    wheels' noise in the directions taken out as far as the innovations show it: scaled by
    their mean square (1 when the noise is as modelled; near 0 on a log with less noise than
    modelled, a noise-free one, where taking it all out leaves a matrix that is not positive
    definite and a share of hundreds), and not at all if it would still leave one."""
    z, rows = scaled[outside], design[outside]
    seen = min(1.0, float(np.mean(z * z)))
    noise = np.zeros(3)
    noise[:2] = seen * shared[outside].sum(axis=0)
    plain = rows.T @ rows
    normal = plain - np.diag(noise)
    if np.linalg.eigvalsh(normal)[0] <= 1e-9 * max(np.abs(np.diag(plain)).max(), 1e-300):
        normal, noise = plain, np.zeros(3)
    return np.linalg.lstsq(normal, rows.T @ z - noise, rcond=None)[0]


def episode_ratio(scaled: np.ndarray, directions: np.ndarray) -> float:
    """The generalised likelihood ratio of one run of intervals: the larger of the two
    wheels' ``(sum u z)^2 / sum u^2``."""
    pooled = directions.T @ scaled
    spread = np.einsum("ij,ij->j", directions, directions)
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.where(spread > 0.0, pooled * pooled / spread, 0.0).max())


def partition(
    scaled: np.ndarray, directions: np.ndarray, penalty: float, edge_cost: float, longest: int
) -> list[tuple[int, int]]:
    """The episodes ``[first, end)`` of the best partition (see the module), in order: by the
    C core's dynamic programme where it was built (``backends/_partition.c``), else by its
    twin here (``partition_python``); the same sums in the same order, the same episodes."""
    if _partition is None:
        return partition_python(scaled, directions, penalty, edge_cost, longest)
    along = np.ascontiguousarray(directions * scaled[:, None], dtype=float)
    weight = np.ascontiguousarray(directions * directions, dtype=float)
    start = np.empty(len(scaled) + 1)
    _partition(along, weight, float(penalty), float(edge_cost), int(longest), start)
    ends = np.flatnonzero(start >= 0.0)
    return list(zip(start[ends].astype(int).tolist(), ends.tolist(), strict=True))


def partition_python(
    scaled: np.ndarray, directions: np.ndarray, penalty: float, edge_cost: float, longest: int
) -> list[tuple[int, int]]:
    """``partition`` in NumPy: the reference the C programme is held to."""
    n = len(scaled)
    along, weight = directions * scaled[:, None], directions * directions
    best = np.zeros(n + 1)
    start = np.full(n + 1, -1)  # where the episode ending here starts; -1: no episode ends here
    for end in range(1, n + 1):
        first = max(0, end - longest)
        # each run's sums directly (not as differences of running sums, which lose a wheel
        # that barely turns beside one that turns fast)
        pooled = np.cumsum(along[first:end][::-1], axis=0)[::-1]
        spread = np.cumsum(weight[first:end][::-1], axis=0)[::-1]
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(spread > 0.0, pooled * pooled / spread, 0.0).max(axis=1)
        gain = best[first:end] + ratio - penalty - edge_cost * (end - np.arange(first, end))
        k = int(np.argmax(gain))
        if gain[k] > best[end - 1]:
            best[end], start[end] = gain[k], first + k
        else:
            best[end] = best[end - 1]
    # back from the end, episode by episode
    found = []
    end = len(start) - 1
    while end > 0:
        if start[end] >= 0:
            found.append((int(start[end]), end))
            end = start[end]
        else:
            end -= 1
    return found[::-1]
