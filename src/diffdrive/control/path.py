"""Paths: the geometry a robot is asked to drive, before any timing.

A path is a list of *legs*. A drive leg is a curve the robot's reference point follows,
forward or in reverse; a turn leg is a turn in place. Each leg is sampled densely into
``Leg`` arrays: the path parameter ``s`` (m along a drive leg, rad through a turn), the
position, the heading of the robot, the path's curvature ``kappa`` (rad/m, the tangent's turn
per metre) and its rate ``dkappa`` (rad/m^2, per metre), and the leg's direction.
``diffdrive.control.planning`` times them.

``from_waypoints`` joins waypoints ``(x, y)`` or ``(x, y, theta)`` by quintic Hermite splines
with tangents 1.2 times the chord long (WPILib's choice, ``SplineHelper``: between two
waypoints both libraries drive the same curve). At the first and last waypoint the second
derivative is zero; at an interior one it is chosen for the smoothest curve (``_smoothest``)
and scaled on each side so that the curvature is continuous there (WPILib's is not, so its
wheels are asked for a step in velocity). Headings not given are the direction from the
waypoint before to the one after (Catmull-Rom's). Two waypoints at one position with
different headings make a turn in place, the short way round. ``from_segments`` chains
straight lines, circular arcs and turns in place (by any angle) from a start pose.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from diffdrive._validate import check_samples, finite, positive, whole
from diffdrive.angles import wrap_angle
from diffdrive.batch import sinc
from diffdrive.batch import wrap_angle as wrap_angles

__all__ = ["TANGENT_SCALE", "Leg", "from_segments", "from_waypoints"]

TANGENT_SCALE = 1.2  # tangent length over chord length at each waypoint (WPILib's)
_STEP = 0.02  # m (drive) or rad (turn): the default spacing of samples along a leg


# Coefficients of t^0..t^5 of the quintic Hermite basis, in the order
# p0, p0', p0'', p1'', p1', p1.
_HERMITE = np.array(
    [
        [1.0, 0.0, 0.0, -10.0, 15.0, -6.0],
        [0.0, 1.0, 0.0, -6.0, 8.0, -3.0],
        [0.0, 0.0, 0.5, -1.5, 1.5, -0.5],
        [0.0, 0.0, 0.0, 0.5, -1.0, 0.5],
        [0.0, 0.0, 0.0, -4.0, 7.0, -3.0],
        [0.0, 0.0, 0.0, 10.0, -15.0, 6.0],
    ]
)


@dataclass(frozen=True, eq=False)
class Leg:
    """One leg, sampled: ``s``, ``x``, ``y``, ``heading``, ``kappa``, ``dkappa`` are ``(N,)``.

    ``kind`` is ``"drive"`` or ``"turn"``; ``direction`` is +1 (forward, or a left turn) or -1
    (reverse, or a right turn). ``heading`` is the robot's (rad, unwrapped): the tangent's for
    a forward leg, the tangent's plus pi in reverse. ``kappa`` and ``dkappa`` are the path's
    (the tangent's turn per metre and its rate), zero on a turn leg.
    """

    kind: str
    direction: int
    s: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    kappa: np.ndarray
    dkappa: np.ndarray

    @property
    def length(self) -> float:
        """m along a drive leg, rad through a turn."""
        return float(self.s[-1])


def _waypoint_array(waypoints: object) -> np.ndarray:
    try:
        array = np.asarray(waypoints, dtype=float)
    except (TypeError, ValueError):
        raise TypeError("waypoints must be numbers, rows of (x, y) or (x, y, theta)") from None
    if array.ndim != 2 or array.shape[1] not in (2, 3) or len(array) < 2:
        raise ValueError(
            f"waypoints must be at least 2 rows of (x, y) or (x, y, theta), got shape {array.shape}"
        )
    bad = np.argwhere(~np.isfinite(array))
    if len(bad):
        row, column = bad[0]
        raise ValueError(f"waypoint {row} has a non-finite value in column {column}")
    if array.shape[1] == 3 and np.abs(array[:, 2]).max() > 2.0 * math.pi:
        row = int(np.argmax(np.abs(array[:, 2])))
        raise ValueError(
            f"waypoint {row} has a heading of {array[row, 2]:g}: headings are radians, within "
            "[-2 pi, 2 pi]; this looks like degrees (multiply by pi/180)"
        )
    return array


def _headings(points: np.ndarray) -> np.ndarray:
    """Catmull-Rom tangent directions for waypoints that have no heading."""
    before = np.concatenate([points[:1], points[:-1]])
    after = np.concatenate([points[1:], points[-1:]])
    chord = after - before
    return np.arctan2(chord[:, 1], chord[:, 0])


def _derivative_of_powers() -> np.ndarray:
    """``(4, 6, 6)``: for each order, the matrix taking the powers ``t^0..t^5`` to that
    derivative of each power, written in the same powers (d/dt t^p = p t^(p-1))."""
    step = np.diag(np.arange(1.0, 6.0), k=1).T  # the derivative, as a map on coefficients
    orders = [np.eye(6)]
    for _ in range(3):
        orders.append(orders[-1] @ step.T)
    return np.stack(orders)


# Per order, the powers of t to the Hermite controls' weights: ``powers @ _BY_ORDER[order]``.
_BY_ORDER = np.einsum("oqp,kp->oqk", _derivative_of_powers(), _HERMITE)


def _basis(t: np.ndarray) -> np.ndarray:
    """``(4, M, 6)``: the rows that turn Hermite controls into the value and its first three
    derivatives at ``t``."""
    powers = np.vander(t, 6, increasing=True)
    return np.matmul(powers[None], _BY_ORDER)


def _controls(points: np.ndarray, bend: np.ndarray) -> np.ndarray:
    """``(..., S, 6, 2)`` Hermite controls of the segments between poses ``points`` ``(K, 3)``.

    ``bend`` ``(..., K, 2)`` (1/m) sets the second derivative at each waypoint: ``lambda^2
    bend`` on each side, ``lambda`` being that side's tangent length. The curvature at a
    waypoint, ``T x bend``, is then the same on both sides (the curve is G2), so no wheel is
    asked for a step in velocity there.
    """
    chord = np.hypot(*np.diff(points[:, :2], axis=0).T)
    direction = np.column_stack([np.cos(points[:, 2]), np.sin(points[:, 2])])
    scale = (TANGENT_SCALE * chord)[:, None]
    fixed = np.stack(
        [points[:-1, :2], scale * direction[:-1], scale * direction[1:], points[1:, :2]], axis=1
    )
    fixed = np.broadcast_to(fixed, bend.shape[:-2] + fixed.shape)
    square = (scale * scale)[:, None, :]
    second = np.concatenate([bend[..., :-1, None, :], bend[..., 1:, None, :]], axis=-2) * square
    return np.concatenate([fixed[..., :2, :], second, fixed[..., 2:, :]], axis=-2)


def _derivatives(controls: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """``(4, ..., S, M, 2)``: position and first three derivatives at the sample rows of
    ``basis`` (``_basis``)."""
    shaped = basis.reshape((4,) + (1,) * (controls.ndim - 2) + basis.shape[1:])
    return np.matmul(shaped, controls)


def _geometry(d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Speed ``|p'|``, curvature and its rate per metre from the derivatives ``d``."""
    d1, d2, d3 = d[1], d[2], d[3]
    speed = np.hypot(d1[..., 0], d1[..., 1])
    cross = d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]
    dot = (d1 * d2).sum(axis=-1)
    cross3 = d1[..., 0] * d3[..., 1] - d1[..., 1] * d3[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = cross / speed**3
        dkappa = (cross3 / speed**3 - 3.0 * cross * dot / speed**5) / speed
    return speed, kappa, dkappa


_COARSE = np.linspace(0.0, 1.0, 33)
_COARSE_BASIS = _basis(_COARSE)
_COARSE_WEIGHTS = np.gradient(_COARSE)  # quadrature weights along a segment


def _smoothest(points: np.ndarray) -> np.ndarray:
    """The bends (see ``_controls``) at the interior waypoints that make the curve smoothest:
    least ``sum over segments of lambda^2 times the integral of |d^3p/ds^3|^2 ds``, ``lambda``
    a segment's tangent length. For a curve at unit speed ``|d^3p/ds^3|^2`` is
    ``(dkappa/ds)^2 + kappa^4``: the rate of curvature (what the ``v^2 dkappa/ds`` part of a
    wheel's acceleration grows with) and the curvature itself; the weight ``lambda^2`` favours
    the long segments, which are driven fast. With the parameter standing in for arc length
    (``ds = lambda dt``) the third derivative is linear in the bends, so the fit is one linear
    least-squares solve. (On the 300 paths of ``benchmarks/bench_planning.py`` its plans are as
    fast on average as those of an iterative fit of ``(dkappa/ds)^2`` alone.)"""
    count = len(points)
    bends = np.zeros((count, 2))
    if count < 3:
        return bends
    third = _COARSE_BASIS[3]  # (M, 6): controls to the third derivative
    tangent = TANGENT_SCALE * np.hypot(*np.diff(points[:, :2], axis=0).T)
    # The third derivative squared, dt over lambda^5, is |d^3p/ds^3|^2 ds; times lambda^2.
    weights = np.sqrt(_COARSE_WEIGHTS[None, :] / tangent[:, None] ** 3)  # (S, M)
    base = (third @ _controls(points, bends)) * weights[..., None]  # (S, M, 2), bends zero
    # A bend enters the segment before its waypoint as p1'' and the one after as p0'', each
    # times that segment's lambda^2; x and y do not mix, so both solve with one matrix.
    inner = np.arange(count - 2)
    design = np.zeros((count - 1, len(_COARSE), count - 2))
    design[inner, :, inner] = tangent[:-1, None] ** 2 * third[:, 3] * weights[:-1]
    design[inner + 1, :, inner] = tangent[1:, None] ** 2 * third[:, 2] * weights[1:]
    flat = design.reshape(-1, count - 2)
    bends[1:-1] = np.linalg.lstsq(flat, -base.reshape(-1, 2), rcond=None)[0]
    return bends


def _quintics(points: np.ndarray, step: float, first: int, smooth: bool) -> list[Leg]:
    """The quintic Hermite splines through poses ``points`` ``(K, 3)`` (tangent headings),
    every segment sampled in one pass at ``step`` or closer."""
    bends = _smoothest(points) if smooth else np.zeros((len(points), 2))
    controls = _controls(points, bends)
    coarse_speed = _geometry(_derivatives(controls, _COARSE_BASIS))[0]
    lengths = np.trapezoid(coarse_speed, _COARSE, axis=-1)
    check_samples(
        float(np.sum(lengths)) / step,
        f"the splines from waypoint {first} ({float(np.sum(lengths)):.4g} m long)",
        "are the waypoints in metres? A larger step samples fewer",
    )
    intervals = np.maximum(np.ceil(lengths / step).astype(int), 16)
    counts = intervals + 1  # samples per segment
    segment = np.repeat(np.arange(len(intervals)), counts)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    local = np.arange(len(segment)) - starts[segment]
    t = local / intervals[segment]
    basis = _basis(t)
    d = np.concatenate(
        [
            basis[:, a : a + n] @ controls[k]
            for k, (a, n) in enumerate(zip(starts, counts, strict=True))
        ],
        axis=1,
    )
    speed, kappa, dkappa = _geometry(d)
    chords = np.hypot(*np.diff(points[:, :2], axis=0).T)
    # A cusp: the tangent vanishes, or flips between neighbouring samples of a segment.
    inside = segment[1:] == segment[:-1]
    flips = inside & (np.sum(d[1][1:] * d[1][:-1], axis=-1) <= 0.0)
    cusp = np.minimum.reduceat(speed, starts) <= 1e-9 * np.maximum(chords, 1.0)
    cusp[segment[1:][flips]] = True
    # Arc length: the trapezoid with its end correction, from the speed and its rate
    # (d|p'|/dt = p'.p''/|p'|); its error is of the order of Simpson's rule's.
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.sum(d[1] * d[2], axis=-1) / speed
    h = 1.0 / intervals[segment[1:]]
    pieces = h / 2.0 * (speed[1:] + speed[:-1]) + h * h / 12.0 * (rate[:-1] - rate[1:])
    total = np.concatenate([[0.0], np.cumsum(np.where(inside, pieces, 0.0))])
    s = total - total[starts][segment]
    steps = np.where(inside, np.abs(kappa[1:] + kappa[:-1]) * np.diff(s) / 2.0, 0.0)
    turned = np.bincount(segment[1:], steps, len(intervals))
    net = np.abs(wrap_angles(np.diff(points[:, 2])))
    loops = turned > net + 1.5 * math.pi  # three quarters of a circle more than asked
    for index in range(len(intervals)):
        where = f"the spline from waypoint {first + index} to {first + index + 1}"
        if cusp[index]:
            raise ValueError(
                f"{where} has a cusp (its tangent vanishes): move the waypoints apart or "
                "change their headings (theta is the robot's heading: driving in reverse, the "
                "path leaves against it)"
            )
        if loops[index]:
            raise ValueError(
                f"{where} loops (its tangent turns {math.degrees(turned[index]):.0f} degrees to "
                f"change heading by {math.degrees(net[index]):.0f}): change the headings or add "
                "a waypoint"
            )
    tangent = np.unwrap(np.arctan2(d[1][:, 1], d[1][:, 0]))
    tangent += (points[:-1, 2] - tangent[starts])[segment]
    return [
        Leg(
            "drive",
            1,
            s[part],
            d[0][part, 0],
            d[0][part, 1],
            tangent[part],
            kappa[part],
            dkappa[part],
        )
        for part in np.split(np.arange(len(segment)), starts[1:])
    ]


def _turn(x: float, y: float, start: float, angle: float, step: float) -> Leg:
    """A turn in place from heading ``start`` by ``angle`` (rad; positive to the left)."""
    check_samples(abs(angle) / step, f"a turn of {angle:g} rad", "is the angle in radians?")
    count = max(math.ceil(abs(angle) / step), 8)
    s = np.linspace(0.0, abs(angle), count + 1)
    zeros = np.zeros(count + 1)
    heading = start + math.copysign(1.0, angle) * s
    return Leg("turn", 1 if angle > 0 else -1, s, zeros + x, zeros + y, heading, zeros, zeros)


def _reversed(leg: Leg) -> Leg:
    """The same curve driven backward: the robot faces away from the tangent."""
    return Leg("drive", -1, leg.s, leg.x, leg.y, leg.heading - math.pi, leg.kappa, leg.dkappa)


def _directions(reverse: bool | Sequence[bool], count: int) -> list[bool]:
    if isinstance(reverse, bool | np.bool_):
        return [bool(reverse)] * count
    flags = list(reverse)
    if len(flags) != count or not all(isinstance(f, bool | np.bool_) for f in flags):
        raise ValueError(
            f"reverse must be one bool or one per waypoint pair ({count}), got {reverse!r}"
        )
    return [bool(f) for f in flags]


def from_waypoints(
    waypoints: object,
    *,
    reverse: bool | Sequence[bool] = False,
    stops: Sequence[int] = (),
    step: float = _STEP,
    smooth: bool = True,
) -> list[list[Leg]]:
    """The path through ``waypoints`` ``(K, 2)`` or ``(K, 3)`` (m, m, rad), as runs of legs.

    A heading is the robot's: in reverse the curve leaves against it. ``reverse`` is one flag
    or one per waypoint pair; a change of direction, a turn in place (two waypoints at one
    position) and an index in ``stops`` halt the robot. Returns the runs between halts, each
    a list of legs that the robot drives without stopping. ``step``: sample spacing (m, rad).
    ``smooth``: choose the second derivatives at interior waypoints for the smoothest curve
    (``_smoothest``; WPILib's ``OptimizeCurvature`` does the like by its own measure);
    otherwise zero.
    """
    points = _waypoint_array(waypoints)
    step = positive("step", step)
    count = len(points) - 1
    backward = _directions(reverse, count)
    halts = {whole("stops", i, 1) for i in stops}
    for index in halts:
        if not 0 < index < count:
            raise ValueError(f"stops: {index} is not an interior waypoint (1 to {count - 1})")
    gaps = np.hypot(*np.diff(points[:, :2], axis=0).T)
    scale = max(float(np.abs(points[:, :2]).max()), 1.0)
    same_place = gaps <= 1e-9 * scale
    if points.shape[1] == 2:
        if same_place.any():
            first = int(np.argmax(same_place))
            raise ValueError(f"waypoints {first} and {first + 1} repeat: every pair must differ")
        headings = _headings(points[:, :2])
        headings += np.pi * np.array(backward + backward[-1:])  # the robot faces backward
        headings = wrap_angles(headings)
        points = np.column_stack([points, headings])
    # Runs of waypoints driven without halting: split at turns, stops and reversals.
    runs: list[list[Leg]] = []
    first = 0
    for index in range(count + 1):
        last = index == count
        continues = not last and not same_place[index] and index > first
        if continues and index not in halts and backward[index] == backward[index - 1]:
            continue
        if index > first:
            runs.append(_drive(points[first : index + 1], backward[first], step, first, smooth))
        if not last and same_place[index]:
            start, end = points[index], points[index + 1]
            # Between two waypoints' headings: the short way round.
            angle = wrap_angle(end[2] - start[2])
            if abs(angle) <= 1e-12:
                raise ValueError(
                    f"waypoints {index} and {index + 1} repeat: every pair must differ"
                )
            runs.append([_turn(start[0], start[1], start[2], angle, step)])
            first = index + 1
        else:
            first = index
    return runs


def _drive(points: np.ndarray, backward: bool, step: float, first: int, smooth: bool) -> list[Leg]:
    """The legs through ``points`` driven one way without halting."""
    if not backward:
        return _quintics(points, step, first, smooth)
    flipped = points + np.array([0.0, 0.0, math.pi])
    return [_reversed(leg) for leg in _quintics(flipped, step, first, smooth)]


def from_segments(
    start: object, segments: Sequence[Sequence[object]], step: float = _STEP
) -> list[list[Leg]]:
    """Lines and arcs from pose ``start`` ``(x, y, theta)``, driven without stopping.

    ``segments``: ``("line", length)`` (m; negative drives backward) or
    ``("arc", radius, angle)`` (m, rad; a positive angle turns left, a negative length
    radius drives the arc backward) or ``("turn", angle)`` (rad, in place; halts the robot).
    """
    pose = np.asarray(start, dtype=float)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"start must be a finite (x, y, theta), got {start!r}")
    step = positive("step", step)
    x, y, heading = (float(value) for value in pose)
    runs: list[list[Leg]] = [[]]
    for index, segment in enumerate(segments):
        kind, *values = segment
        where = f"segment {index} ({kind!r})"
        if kind == "turn" and len(values) == 1:
            angle = finite(f"{where}: angle", values[0])
            if angle == 0.0:
                raise ValueError(f"{where}: a turn of 0 rad")
            runs += [[_turn(x, y, heading, angle, step)], []]
            heading += angle
            continue
        if kind == "line" and len(values) == 1:
            length, curvature = finite(f"{where}: length", values[0]), 0.0
        elif kind == "arc" and len(values) == 2:
            radius = finite(f"{where}: radius", values[0])
            angle = finite(f"{where}: angle", values[1])
            if radius == 0.0 or angle == 0.0:
                raise ValueError(f"{where}: radius and angle must be non-zero")
            length, curvature = (
                math.copysign(abs(radius * angle), radius),
                angle / abs(radius * angle),
            )
        else:
            raise ValueError(
                f"{where}: expected ('line', length), ('arc', radius, angle) or ('turn', angle)"
            )
        if length == 0.0:
            raise ValueError(f"{where}: a length of 0 m")
        direction = 1 if length > 0 else -1
        check_samples(abs(length) / step, where, "is the length in metres?")
        count = max(math.ceil(abs(length) / step), 8)
        s = np.linspace(0.0, abs(length), count + 1)
        tangent0 = heading if direction > 0 else heading + math.pi
        tangent = tangent0 + curvature * s
        # The chord of the arc, as the core integrates one: no (sin t - sin t0) / kappa to
        # cancel on a gentle arc, and a line is the same formula at kappa = 0.
        half = 0.5 * curvature * s
        chord = s * sinc(half)
        px, py = x + chord * np.cos(tangent0 + half), y + chord * np.sin(tangent0 + half)
        zeros = np.zeros(count + 1)
        robot_heading = tangent if direction > 0 else tangent - math.pi
        leg = Leg("drive", direction, s, px, py, robot_heading, zeros + curvature, zeros)
        if runs[-1] and runs[-1][-1].direction != direction:
            runs.append([])
        runs[-1].append(leg)
        x, y, heading = float(px[-1]), float(py[-1]), float(robot_heading[-1])
    runs = [run for run in runs if run]
    if not runs:
        raise ValueError("segments is empty")
    return runs
