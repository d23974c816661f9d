"""A plan made to clear obstacles: the reference a sampling controller follows among them.

A sampling controller sees as far as its horizon: an obstacle squarely on the plan leaves it a
local minimum in front (every sample that turns away pays for leaving the plan before it
gains), and it stops there or dithers (Nav2's MPPI users report exactly that, navigation2#5661).
``guide`` removes the minimum before the controller starts: where the plan's path comes
closer to an obstacle than ``footprint + inflation``, the stretch is replaced by the cheapest
way around on the clearance grid (scipy's Dijkstra over the nodes clear by ``footprint +
margin``, diagonal moves included, each move's length weighted up by ``1 + 4 s^2`` where ``s``
is the share of the inflation band it enters, so a way through a gap keeps to its middle),
straightened where the straight line keeps the clearance the way had (or the footprint and
inflation where it had more), and the whole path re-timed within the plan's limits
(``plan``). Should the spline through those corners bulge into an obstacle, waypoints are
added along the straight runs, 1 m, then 0.5 m, then 0.25 m apart, until it does not. A plan
already clear is returned as it is.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from diffdrive._validate import check_samples, nonnegative, positive
from diffdrive.batch import wrap_angle
from diffdrive.control.obstacles import Obstacles
from diffdrive.control.planning import Plan, plan

__all__ = ["guide"]

# Plan states kept as waypoints where the plan is clear: one every this many metres.
_SPACING = 1.0
# How far before and after a blocked stretch the way around starts and rejoins (m).
_APPROACH = 1.5


def guide(
    reference: Plan,
    obstacles: Obstacles,
    footprint: float,
    *,
    inflation: float = 0.3,
    margin: float = 0.05,
) -> Plan:
    """``reference`` with every stretch closer than ``footprint + inflation`` (m) to an
    obstacle replaced by a way around (see the module); ``ValueError`` if none clears
    ``footprint + margin``."""
    if not isinstance(reference, Plan):
        raise TypeError(f"reference must be a Plan, got {type(reference).__name__}")
    footprint, inflation = nonnegative("footprint", footprint), nonnegative("inflation", inflation)
    margin = positive("margin", margin)
    poses = reference.poses
    blocked = obstacles.clearance_at(poses[:, :2]) < footprint + inflation
    if not blocked.any():
        return reference
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))])
    ways: dict[tuple[int, int], np.ndarray] = {}
    for spacing in (math.inf, 1.0, 0.5, 0.25):
        waypoints = _waypoints(
            obstacles, poses, blocked, travelled, ways, spacing, (footprint, inflation, margin)
        )
        made = plan(waypoints, reference.robot, reference.limits)
        gaps = obstacles.clearance_at(made.poses[:, :2])
        if gaps.min() >= footprint:
            return made
    worst = made.poses[int(np.argmin(gaps)), :2]
    raise ValueError(
        f"no way around the obstacles that a spline keeps to: the closest comes "
        f"{footprint - gaps.min():.3f} m into an obstacle at ({worst[0]:.2f}, {worst[1]:.2f})"
    )


def _waypoints(obstacles, poses, blocked, travelled, ways, spacing, sizes) -> np.ndarray:
    """The guide's waypoints ``(K, 3)``: the plan's states ``_SPACING`` m apart where it is
    clear, each blocked stretch's way around (found once into ``ways``) with points at most
    ``spacing`` m apart along its straight runs."""
    waypoints: list[np.ndarray] = [poses[0]]
    last = 0.0  # the distance along the plan of the last waypoint kept
    i = 0
    while i < len(poses):
        if not blocked[i]:
            if travelled[i] - last >= _SPACING:
                waypoints.append(poses[i])
                last = travelled[i]
            i += 1
            continue
        before, after = _leave(blocked, travelled, i), _rejoin(blocked, travelled, i)
        while (
            len(waypoints) > 1 and _along(waypoints[-1], poses, travelled) > travelled[before] - 0.2
        ):
            waypoints.pop()
        if (before, after) not in ways:
            ways[before, after] = _way_around(
                obstacles, poses[before, :2], poses[after, :2], *sizes
            )
        way = _subdivided(ways[before, after], spacing)
        waypoints.extend(_with_headings(way[1:-1], poses[before], poses[after]))
        waypoints.append(poses[after])
        last, i = travelled[after], after + 1
    if not np.allclose(waypoints[-1], poses[-1]):
        waypoints.append(poses[-1])
    return np.array(waypoints)


def _subdivided(points: np.ndarray, spacing: float) -> np.ndarray:
    """``points`` with points added along each straight run, at most ``spacing`` m apart: a
    spline through them keeps to the runs (through their ends alone it could bulge)."""
    out = [points[0]]
    for a, b in itertools.pairwise(points):
        pieces = max(1, int(np.ceil(np.hypot(*(b - a)) / spacing)))
        out += [a + (b - a) * k / pieces for k in range(1, pieces + 1)]
    return np.array(out)


def _leave(blocked: np.ndarray, travelled: np.ndarray, i: int) -> int:
    """The state where the way around the stretch blocked from state ``i`` leaves the plan:
    ``_APPROACH`` m before it, and before any stretch blocked there."""
    before = int(np.searchsorted(travelled, travelled[i] - _APPROACH))
    while before > 0 and blocked[before]:
        clear = np.flatnonzero(~blocked[:before])
        start = int(clear[-1]) + 1 if len(clear) else 0
        before = int(np.searchsorted(travelled, travelled[start] - _APPROACH))
    return before


def _rejoin(blocked: np.ndarray, travelled: np.ndarray, i: int) -> int:
    """The state where the way around the stretch blocked from state ``i`` rejoins the plan:
    ``_APPROACH`` m past its end, and past any stretch blocked again by then."""
    after = i
    while after < len(blocked) - 1 and blocked[after]:
        clear = np.flatnonzero(~blocked[after:])
        end = after + int(clear[0]) if len(clear) else len(blocked) - 1
        after = int(np.searchsorted(travelled, travelled[end] + _APPROACH))
        after = min(after, len(blocked) - 1)
    return after


def _along(pose: np.ndarray, poses: np.ndarray, travelled: np.ndarray) -> float:
    """The distance along the plan of the state at ``pose``."""
    return float(travelled[int(np.argmin(np.sum((poses[:, :2] - pose[:2]) ** 2, axis=1)))])


def _way_around(
    obstacles: Obstacles,
    start: np.ndarray,
    goal: np.ndarray,
    footprint: float,
    inflation: float,
    margin: float,
) -> np.ndarray:
    """The cheapest way ``(M, 2)`` from ``start`` to ``goal`` over the grid's nodes clear by
    ``footprint + margin``, straightened (see the module)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    grid, res = obstacles.clearance, obstacles.resolution
    rows, cols = grid.shape
    check_samples(4 * rows * cols, "the obstacle grid's moves", "a coarser grid")
    allowed = grid >= footprint + margin
    band = np.clip((footprint + inflation - grid) / max(inflation, margin), 0.0, 1.0)
    weight = 1.0 + 4.0 * band**2
    index = np.arange(rows * cols).reshape(rows, cols)
    heads, tails, lengths = [], [], []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = (slice(0, rows - di), slice(max(0, -dj), cols - max(0, dj)))
        b = (slice(di, rows), slice(max(0, dj), cols - max(0, -dj)))
        both = allowed[a] & allowed[b]
        heads.append(index[a][both])
        tails.append(index[b][both])
        lengths.append(res * np.hypot(di, dj) * 0.5 * (weight[a] + weight[b])[both])
    graph = coo_matrix(
        (np.concatenate(lengths), (np.concatenate(heads), np.concatenate(tails))),
        shape=(rows * cols, rows * cols),
    ).tocsr()

    def node(point: np.ndarray) -> int:
        i = int(np.clip(round((point[1] - obstacles.origin[1]) / res), 0, rows - 1))
        j = int(np.clip(round((point[0] - obstacles.origin[0]) / res), 0, cols - 1))
        return int(index[i, j])

    source, target = node(start), node(goal)
    for end, name in ((source, "the stretch's start"), (target, "its end")):
        if not allowed.flat[end]:
            raise ValueError(
                f"no way around the obstacles: {name} is within {footprint} m + {margin} m of one"
            )
    _, previous = dijkstra(graph, directed=False, indices=source, return_predecessors=True)
    if previous[target] < 0:
        raise ValueError(
            f"no way around the obstacles for a robot of radius {footprint} m (+ {margin} m) "
            f"between {start.round(2)} and {goal.round(2)}"
        )
    nodes = [target]
    while nodes[-1] != source:
        nodes.append(int(previous[nodes[-1]]))
    ij = np.array(nodes[::-1])
    points = np.column_stack(
        [obstacles.origin[0] + res * (ij % cols), obstacles.origin[1] + res * (ij // cols)]
    )
    points[0], points[-1] = start, goal
    return _straightened(obstacles, points, grid.flat[ij], footprint + inflation)


def _straightened(
    obstacles: Obstacles, points: np.ndarray, clear: np.ndarray, enough: float
) -> np.ndarray:
    """``points`` with the nodes dropped that a straight line skips while keeping the
    clearance the skipped stretch had, or ``enough`` (m) where it had more."""
    kept = [0]
    while kept[-1] < len(points) - 1:
        here, best = kept[-1], kept[-1] + 1
        for there in range(len(points) - 1, here + 1, -1):
            need = min(clear[here : there + 1].min(), enough) - 0.5 * obstacles.resolution
            chord = points[there] - points[here]
            count = max(2, int(np.hypot(*chord) / (0.5 * obstacles.resolution)))
            line = points[here] + np.linspace(0.0, 1.0, count)[:, None] * chord
            if obstacles.clearance_at(line).min() >= need:
                best = there
                break
        kept.append(best)
    return points[kept]


def _with_headings(points: np.ndarray, before: np.ndarray, after: np.ndarray) -> list[np.ndarray]:
    """Waypoints ``(x, y, theta)`` at ``points``, each heading the way from the point before
    to the one after (the stretch's ends are ``before`` and ``after``)."""
    chain = np.vstack([before[:2], points, after[:2]])
    out = []
    for k in range(1, len(chain) - 1):
        dx, dy = chain[k + 1] - chain[k - 1]
        # Unwrapped as the plan's headings are: the turn from the stretch's start.
        heading = before[2] + wrap_angle(np.arctan2(dy, dx) - before[2])
        out.append(np.array([*chain[k], heading]))
    return out
