"""Nav2 AMCL's differential motion model as its source has it, and the alphas that match a
noise model to it.

The sampler (``nav2_amcl::DifferentialMotionModel::odometryUpdate``, after Thrun, Burgard and
Fox, *Probabilistic Robotics*, table 5.6): each filter update splits the odometry's motion
since the last update, in the odom frame, into a turn ``rot1`` to the motion's bearing (0 for
a motion under 1 cm), a straight ``trans`` and a turn ``rot2``; for the noise each turn is
folded to the nearer of forward and backward (``min(|rot|, pi - |rot|)``). Every particle then
moves by ``rot1 - n1``, ``trans - nt``, ``rot2 - n2`` with

- ``n1 ~ N(0, alpha1 rot1^2 + alpha2 trans^2)``, ``n2 ~ N(0, alpha1 rot2^2 + alpha2 trans^2)``:
  the translation spreads **both** turns;
- ``nt ~ N(0, alpha3 trans^2 + alpha4 (rot1^2 + rot2^2))``.

AMCL updates when the odometry, sampled at each laser scan, has moved more than
``update_min_d`` along the odom frame's x or y, or turned more than ``update_min_a``, since the
last update (``AmclNode::shouldUpdateFilter``): the noise is applied per update, so the
variance a motion collects depends on how it is cut, and the motion after the last update
waits for the next.

Matching (``match_alphas``): along the reference motions (``distance`` m straight, a turn in
place of ``turn`` rad at ``turn_rate``, arcs of twice ``distance`` of radius ``distance`` and
twice it), all from heading 0 in the odom frame, sampled at ``scan_rate`` and cut into updates
by that rule, each up to its last update, the particles' covariance is linear in the four
alphas: the sampler's Jacobians along the nominal path (``sampler_terms``). The alphas make
the largest relative miss of its diagonal against the noise model's covariance over the same
motion least (Lawson's iteratively reweighted least squares toward the minimax fit, kept
non-negative); that miss is reported with them, and an alpha that would be 0 is refused.
Where the rule cuts motions into updates of uneven size (an arc's turn crossing
``update_min_a`` before its distance crosses ``update_min_d``), no four alphas match every
motion: at Nav2's defaults and 10 Hz the least largest miss is 14 % (13.5 %, the linear
programme's optimum, even on one straight, one turn and the tighter arc alone: AMCL's noise
grows with the square of each update's length, and the arc's updates are 0.25 m where the
straight's are 0.30 m), and motions the fit never saw (1.5 m straight, 1.5 rad turn, arcs of
radius 1 and 1.5 m) land within it (``tests/test_export.py``, a Monte Carlo of the sampler).
No alphas can do better than the sampler's own spread between directions: a straight at 45
degrees to the odom frame's axes updates every 0.40 m and collects a third more heading
variance per metre than one along an axis.

One split no alphas can set: in a turn in place the sampler moves a particle along its heading
at the update's start (a pure turn has no ``rot1`` noise), so a 1 rad turn cut into a few
updates puts its position spread on the headings 0, 0.3, 0.6, ... where the wheels' noise is
spread over every heading of the turn. Only ``alpha4`` acts there, on x and y alike; so for
the turn the fit takes the position's total variance (x plus y) and the heading's, and
``AlphaFit.split`` gives how far each of x and y is off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from diffdrive import batch
from diffdrive._stats import nonnegative_least_squares

# The reference arcs' radii, in units of the Reference's distance: two, since the update rule
# cuts arcs of different radii into updates of different sizes (one radius alone left a 2 m
# arc of radius 1 m 20 % low at 10 Hz).
RADII = (1.0, 2.0)

__all__ = ["AlphaFit", "ReferenceMotion", "match_alphas", "reference_motions", "sampler_terms"]


@dataclass(frozen=True, eq=False)
class ReferenceMotion:
    """A reference motion: its ``name``, the wheel-angle ``increments`` ``(S, 2)`` rad that
    drive it (for the noise model), the odometry ``poses`` ``(K, 3)`` at each scan, and
    whether it turns in place (``spin``: its x and y are matched as their sum)."""

    name: str
    increments: np.ndarray
    poses: np.ndarray
    spin: bool = False


@dataclass(frozen=True, eq=False)
class AlphaFit:
    """``match_alphas``' result: ``alphas`` ``(4,)`` (alpha1 to alpha4), per motion the
    ``model`` and ``sampler`` covariances ``(M, 3, 3)`` (motion, then 3x3) after it,
    ``worst``, the largest relative miss of a term matched, and ``split``, the relative miss
    of the turn in place's x and y each (see the module)."""

    alphas: np.ndarray
    motions: tuple[str, ...]
    model: np.ndarray
    sampler: np.ndarray
    worst: float
    split: tuple[float, float]


def angle_diff(a: float, b: float) -> float:
    """``a - b`` (rad) as Nav2's ``angleutils::angle_diff`` has it: both normalised by
    ``atan2(sin, cos)``, then the shorter way round. AMCL's thresholds compare these values,
    so the same rounding decides a motion that lands on one."""
    a, b = math.atan2(math.sin(a), math.cos(a)), math.atan2(math.sin(b), math.cos(b))
    d1 = a - b
    d2 = 2.0 * math.pi - abs(d1)
    if d1 > 0.0:
        d2 = -d2
    return d1 if abs(d1) < abs(d2) else d2


def update_points(poses: np.ndarray, update_min_d: float, update_min_a: float) -> list[int]:
    """The indices of ``poses`` ``(K, 3)`` (the odometry at each scan) where AMCL updates:
    the first, then each scan more than ``update_min_d`` along x or y, or ``update_min_a`` of
    turn, from the last update. The motion after the last waits for the next update."""
    points, last = [0], poses[0]
    for k in range(1, len(poses)):
        dx, dy = poses[k, 0] - last[0], poses[k, 1] - last[1]
        turned = abs(angle_diff(poses[k, 2], last[2]))
        if abs(dx) > update_min_d or abs(dy) > update_min_d or turned > update_min_a:
            points.append(k)
            last = poses[k]
    return points


def _folded(rot: float) -> float:
    """A turn folded to the nearer of forward and backward, as the sampler's noise takes it."""
    return min(abs(angle_diff(rot, 0.0)), abs(angle_diff(rot, math.pi)))


def sampler_terms(poses: np.ndarray) -> np.ndarray:
    """The particles' covariance ``(4, 3, 3)`` after AMCL updates at ``poses`` ``(U, 3)`` (the
    odometry at each update, from a start known exactly), per unit of each alpha: the
    sampler's noise propagated through its Jacobians along the nominal path. The covariance
    for ``alphas`` is ``alphas @ terms`` over the first axis."""
    terms = np.zeros((4, 3, 3))
    for before, after in pairwise(poses):
        dx, dy = after[0] - before[0], after[1] - before[1]
        trans = math.hypot(dx, dy)
        rot1 = 0.0 if trans < 0.01 else angle_diff(math.atan2(dy, dx), before[2])
        rot2 = angle_diff(angle_diff(after[2], before[2]), rot1)
        r1, r2 = _folded(rot1), _folded(rot2)
        # Per alpha, the variances of (n1, nt, n2).
        variances = np.array(
            [
                [r1 * r1, 0.0, r2 * r2],
                [trans * trans, 0.0, trans * trans],
                [0.0, trans * trans, 0.0],
                [0.0, r1 * r1 + r2 * r2, 0.0],
            ]
        )
        bearing = before[2] + rot1
        c, s = math.cos(bearing), math.sin(bearing)
        moved = np.array([[1.0, 0.0, -trans * s], [0.0, 1.0, trans * c], [0.0, 0.0, 1.0]])
        by_noise = np.array([[trans * s, -c, 0.0], [-trans * c, -s, 0.0], [-1.0, 0.0, -1.0]])
        terms = moved @ terms @ moved.T + np.einsum("ij,aj,kj->aik", by_noise, variances, by_noise)
    return terms


def reference_motions(robot, at) -> list[ReferenceMotion]:
    """The motions the alphas are matched on, each from heading 0 at ``at``'s speed and turn
    rate, seen at its scan rate: ``distance`` m straight, a turn in place of ``turn`` rad, and
    arcs of 2 ``distance`` m of radius ``RADII`` times ``distance``. Each is cut where AMCL
    has applied it, at its last update (``update_points``: the motion after it waits for the
    next), its ``poses`` those at its updates; its wheels' increments drive it that far in
    100 even steps. A motion too short
    for AMCL to update on is left out. ``robot``: the (equivalent) differential drive."""
    r_l, r_r, track = robot.left_wheel_radius, robot.right_wheel_radius, robot.track_width
    d, v = at.distance, at.speed
    specs = [
        (f"{d:g} m straight", (v, 0.0), d / v),
        (f"{at.turn:g} rad turn in place", (0.0, at.turn_rate), at.turn / at.turn_rate),
    ]
    specs += [
        (f"{2 * d:g} m arc of radius {radius * d:g} m", (v, v / (radius * d)), 2.0 * d / v)
        for radius in RADII
    ]
    made = []
    for name, (speed, omega), duration in specs:
        scans = np.unique(np.append(np.arange(0.0, duration, 1.0 / at.scan_rate), duration))
        poses = batch.exp(np.tile([speed, 0.0, omega], (len(scans), 1)), scans)
        points = update_points(poses, at.update_min_d, at.update_min_a)
        if len(points) < 2:
            continue
        applied = scans[points[-1]]
        left = (speed - 0.5 * track * omega) * applied / r_l
        right = (speed + 0.5 * track * omega) * applied / r_r
        increments = np.tile([left / 100, right / 100], (100, 1))
        made.append(ReferenceMotion(name, increments, poses[points], spin=speed == 0.0))
    if not made:
        raise ValueError(
            f"AMCL would update on none of the reference motions: update_min_d "
            f"{at.update_min_d:g} m and update_min_a {at.update_min_a:g} rad, seen at "
            f"{at.scan_rate:g} Hz, are past them (distance {d:g} m, turn {at.turn:g} rad)"
        )
    return made


def _matched(covariance: np.ndarray, spin: bool) -> np.ndarray:
    """The terms matched of covariances ``(..., 3, 3)``: the diagonal, or for a turn in place
    the position's total and the heading's."""
    diagonal = np.diagonal(covariance, axis1=-2, axis2=-1)
    if spin:
        return np.stack([diagonal[..., 0] + diagonal[..., 1], diagonal[..., 2]], axis=-1)
    return diagonal


def _minimax(rows: np.ndarray, rounds: int = 100) -> np.ndarray:
    """Non-negative ``x`` making the largest ``|rows @ x - 1|`` least, near enough: least
    squares reweighted each round by the residuals (Lawson 1961), floors keeping every row in
    play."""
    weights = np.ones(len(rows))
    for _ in range(rounds):
        root = np.sqrt(weights)
        found = nonnegative_least_squares(rows * root[:, None], root)
        residual = np.abs(rows @ found - 1.0)
        weights = weights * np.maximum(residual, 1e-4 * residual.max())
        # Each row keeps a share: one matched exactly early on would otherwise shrink by
        # 1e-4 a round until it no longer counts, and the alpha it alone sets go to 0.
        weights = np.maximum(weights / weights.max(), 1e-6)
    return found


def match_alphas(motions: list[ReferenceMotion], model_covariances: np.ndarray) -> AlphaFit:
    """The alphas whose sampler covariance (``sampler_terms`` at each motion's update poses)
    best matches ``model_covariances`` ``(M, 3, 3)`` (the noise model's after each motion as
    AMCL has applied it), term by term relative to its own size: the least largest miss. An
    alpha the fit leaves at 0 is refused, naming the motion and term matched worst: AMCL would
    then spread none of the noise that term needs."""
    rows, per_motion = [], []
    for motion, covariance in zip(motions, model_covariances, strict=True):
        terms = sampler_terms(motion.poses)
        per_motion.append(terms)
        wanted = _matched(covariance, motion.spin)
        made = _matched(terms, motion.spin)  # (4, terms)
        rows += [made[:, i] / wanted[i] for i in range(len(wanted)) if wanted[i] > 0.0]
    alphas = _minimax(np.array(rows))
    sampler = np.array([np.tensordot(alphas, terms, axes=1) for terms in per_motion])
    misses: list[tuple[float, str]] = []
    split = (0.0, 0.0)
    for motion, made, wanted in zip(motions, sampler, model_covariances, strict=True):
        ours, theirs = _matched(made, motion.spin), _matched(wanted, motion.spin)
        labels = ("x + y", "heading") if motion.spin else ("x", "y", "heading")
        misses += [
            (abs(a / b - 1.0), f"{motion.name}'s {label}")
            for a, b, label in zip(ours, theirs, labels, strict=True)
            if b > 0.0
        ]
        if motion.spin:
            split = (made[0, 0] / wanted[0, 0] - 1.0, made[1, 1] / wanted[1, 1] - 1.0)
    worst, where = max(misses)
    if not np.all(alphas > 0.0):
        zero = ", ".join(f"alpha{i + 1}" for i in np.flatnonzero(~(alphas > 0.0)))
        raise ValueError(
            f"AMCL's {zero} fit to 0: its sampler cannot match the noise model at these "
            f"update settings; {where} is off by {worst:.0%} (give other update_min_d, "
            "update_min_a or scan rate)"
        )
    names = tuple(motion.name for motion in motions)
    return AlphaFit(alphas, names, np.asarray(model_covariances), sampler, worst, split)
