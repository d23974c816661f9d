"""How far an odometry trajectory is from the ground truth.

- ``run_errors``: the OptiOdom paper's measures of one run (Sousa et al. 2022): the maximum
  and the final position error (m) and heading error (deg) over the run; ``worst`` takes the
  largest of each over an experiment's runs.
- ``ate``: the absolute trajectory error as evo's APE on the translation part: the RMSE of the
  position errors, optionally after the rigid SE(2) alignment that minimises it (Umeyama 1991,
  without scale).
- ``rpe``: the relative pose error as evo (Grupp, github.com/MichaelGrupp/evo) defines it:
  for pose pairs ``(i, j)`` a fixed distance, time or number of poses apart, the error of the
  estimated motion from i to j against the true one, ``(Q_i^-1 Q_j)^-1 (P_i^-1 P_j)``; the
  RMSE of its translation (m) and of its rotation angle (deg). Two ways to choose the pairs,
  as evo's: ``"consecutive"`` (evo's default: each pair starts where the last one ended) and
  ``"all"`` (evo's ``--all_pairs``: from every pose, the pose whose distance is nearest to
  ``delta``, within a tolerance of 10 % of it). Pairs are measured along the estimate, as evo
  does by default, or along the ground truth (evo's ``--pairs_from_reference``).
- ``consistency``: whether an estimate's covariance is honest: the normalised estimation error
  squared (NEES, ``e^T C^-1 e``) of every pose, its average over poses and dimensions (ANEES:
  1 for a covariance that matches the errors, below 1 too wide, above too narrow; Bar-Shalom,
  Li and Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 2001, sec.
  5.4.2), and the shares of poses whose truth lies inside the 50 % and 95 % ellipses.
- ``path_errors``: how far robots are from a planned path: the cross-track error (signed
  distance from the path, positive to the left of the plan's heading at the nearest state),
  the along-track error (ahead of the reference pose of the same time, along its heading) and
  the heading error against the reference of the same time.
- ``associate`` pairs the poses of two trajectories by time, as evo does (nearest stamp
  within ``max_diff``, after shifting one by ``offset``); ``interpolate`` samples a trajectory
  at given times along the arc between its poses (the SE(2) geodesic).
- ``through_fixes``: the baseline a fusion of sparse position fixes must beat, the dead
  reckoning fitted onto the fixes plus their residuals interpolated in time between them.

Trajectories are pose arrays ``(T+1, 3)`` ``[x, y, theta]`` sampled at the same times; all
inputs must be finite.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from diffdrive import batch
from diffdrive._stats import chi2_quantile
from diffdrive._validate import floats, increasing, positive

__all__ = [
    "Consistency",
    "PathErrors",
    "RunErrors",
    "align",
    "alignment",
    "associate",
    "ate",
    "consistency",
    "interpolate",
    "interpolate_covariances",
    "path_errors",
    "rpe",
    "run_errors",
    "through_fixes",
    "worst",
]

RpePairs = Literal["consecutive", "all"]
RPE_PAIRS: tuple[RpePairs, ...] = ("consecutive", "all")


@dataclass(frozen=True)
class RunErrors:
    """The paper's four measures: position errors in m, heading errors in degrees."""

    max_position: float
    max_heading: float
    final_position: float
    final_heading: float

    def to_array(self) -> np.ndarray:
        """The four measures ``(4,)`` in the fields' order."""
        return np.array(
            [self.max_position, self.max_heading, self.final_position, self.final_heading]
        )


def _check(estimate: object, truth: object) -> tuple[np.ndarray, np.ndarray]:
    estimate, truth = floats("estimate", estimate), floats("truth", truth)
    if estimate.ndim != 2 or estimate.shape[1] != 3 or estimate.shape != truth.shape:
        raise ValueError(
            f"estimate and truth must both have shape (T+1, 3), got {estimate.shape} and "
            f"{truth.shape}"
        )
    if len(estimate) == 0:
        raise ValueError("estimate and truth hold no poses")
    for name, poses in (("estimate", estimate), ("truth", truth)):
        if not np.all(np.isfinite(poses)):
            row = int(np.argmin(np.all(np.isfinite(poses), axis=1)))
            raise ValueError(f"{name} must be finite; pose {row} is {poses[row].tolist()}")
    return estimate, truth


def run_errors(estimate: object, truth: object) -> RunErrors:
    """Maximum and final position (m) and heading (deg) errors of one run."""
    estimate, truth = _check(estimate, truth)
    position = np.hypot(*(estimate[:, :2] - truth[:, :2]).T)
    heading = np.degrees(np.abs(batch.wrap_angle(estimate[:, 2] - truth[:, 2])))
    return RunErrors(position.max(), heading.max(), position[-1], heading[-1])


def worst(errors: list[RunErrors]) -> RunErrors:
    """The largest of each measure over runs (an experiment's figure in the paper)."""
    if not errors:
        raise ValueError("worst needs the errors of at least one run")
    for k, error in enumerate(errors):
        if not isinstance(error, RunErrors):
            raise TypeError(f"errors[{k}] must be RunErrors (run_errors'), got {error!r}")
    return RunErrors(*np.max([e.to_array() for e in errors], axis=0))


def alignment(estimate: object, truth: object) -> np.ndarray:
    """The rigid motion ``(x, y, angle)`` (m, m, rad) that best fits ``estimate``'s positions
    onto ``truth``'s: least squares over the positions (Umeyama's method without scale)."""
    estimate, truth = _check(estimate, truth)
    p, q = estimate[:, :2], truth[:, :2]
    p_mean, q_mean = _mean(p), _mean(q)
    # Scaled to order one first: the cross moments of positions of 1e200 m overflow.
    centred_p, centred_q = p - p_mean, q - q_mean
    scale = max(float(np.abs(centred_p).max()), float(np.abs(centred_q).max()), 1e-300)
    cross = (centred_q / scale).T @ (centred_p / scale)
    u, _, vt = np.linalg.svd(cross)
    d = np.sign(np.linalg.det(u @ vt))
    rotation = u @ np.diag([1.0, d]) @ vt
    angle = np.arctan2(rotation[1, 0], rotation[0, 0])
    return np.array([*(q_mean - rotation @ p_mean), angle])


def align(estimate: object, truth: object) -> np.ndarray:
    """``estimate`` moved by ``alignment``'s rigid motion onto ``truth``: ``(T+1, 3)``."""
    return batch.compose(alignment(estimate, truth), np.asarray(estimate, dtype=float))


def ate(estimate: object, truth: object, aligned: bool = False) -> float:
    """Absolute trajectory error, m: RMSE of the position errors (after ``align`` if asked)."""
    estimate, truth = _check(estimate, truth)
    if aligned:
        estimate = align(estimate, truth)
    return _rms(np.hypot(*(estimate[:, :2] - truth[:, :2]).T))


def _rms(values: np.ndarray) -> float:
    """The root mean square of ``values``, scaled first: errors of 1e200 m square past the
    floats, their RMS does not."""
    scale = float(np.abs(values).max()) if len(values) else 0.0
    if not scale > 0.0:
        return 0.0
    if not np.isfinite(scale):
        return math.inf
    return scale * float(np.sqrt(np.mean((values / scale) ** 2)))


def _mean(points: np.ndarray) -> np.ndarray:
    """The mean of ``points`` ``(N, 2)`` without overflow: scaled to order one first."""
    scale = max(float(np.abs(points).max()), 1e-300)
    return scale * (points / scale).mean(axis=0)


def rpe(
    estimate: object,
    truth: object,
    delta: float,
    unit: Literal["m", "s", "poses"] = "m",
    times: object = None,
    pairs: RpePairs = "consecutive",
    pairs_from_truth: bool = False,
) -> tuple[float, float]:
    """Relative pose error over pairs ``delta`` apart: RMSE of translation (m), rotation (deg).

    ``unit`` is ``"m"`` (distance travelled), ``"s"`` (needs ``times``) or ``"poses"``;
    ``pairs`` is ``"consecutive"`` (evo's default) or ``"all"`` (evo's ``--all_pairs``); see
    the module. Distances are measured along the estimate unless ``pairs_from_truth``.
    """
    estimate, truth = _check(estimate, truth)
    delta = positive("delta", delta)
    if pairs not in RPE_PAIRS:
        raise ValueError(f"pairs must be one of {', '.join(RPE_PAIRS)}, got {pairs!r}")
    if unit == "m":
        path = truth if pairs_from_truth else estimate
        along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path[:, :2], axis=0).T))])
    elif unit == "s":
        if times is None:
            raise ValueError("rpe with unit 's' needs the times")
        along = floats("times", times)
        if along.shape != (len(truth),) or not np.all(np.isfinite(along)):
            raise ValueError(f"times must be finite with shape ({len(truth)},), got {along.shape}")
    elif unit == "poses":
        if delta != int(delta):
            raise ValueError(f"delta in poses must be a whole number, got {delta!r}")
        along = np.arange(len(truth), dtype=float)
    else:
        raise ValueError(f"unit must be 'm', 's' or 'poses', got {unit!r}")
    tolerance = 0.0 if unit == "poses" else 0.1 * delta
    i, j = (_all_pairs if pairs == "all" else _consecutive_pairs)(along, delta, tolerance)
    if not len(i):
        raise ValueError(f"no pair of poses is {delta} {unit} apart")
    moved = batch.relative_to(estimate[j], estimate[i])
    true_moved = batch.relative_to(truth[j], truth[i])
    error = batch.relative_to(moved, true_moved)
    translation = np.sqrt(np.mean(np.sum(error[:, :2] ** 2, axis=1)))
    rotation = np.degrees(np.sqrt(np.mean(batch.wrap_angle(error[:, 2]) ** 2)))
    return float(translation), float(rotation)


def _consecutive_pairs(along: np.ndarray, delta: float, _tolerance: float):
    """Pairs end to end: each starts where the last ended, and ends at the first pose at
    least ``delta`` further along."""
    ids = [0]
    while True:
        start = ids[-1]
        j = int(np.searchsorted(along, along[start] + delta, side="left"))
        j = max(j - 1, start + 1)  # the sum may round either way: step to the first that counts
        while j < len(along) and along[j] - along[start] < delta:
            j += 1
        if j >= len(along):
            break
        ids.append(j)
    ids_array = np.array(ids)
    return ids_array[:-1], ids_array[1:]


def _all_pairs(along: np.ndarray, delta: float, tolerance: float):
    """From every pose, the later pose whose distance along is nearest ``delta``, if within
    ``tolerance`` of it."""
    first = np.arange(len(along) - 1)
    target = along[first] + delta
    above = np.clip(np.searchsorted(along, target, side="left"), first + 1, len(along) - 1)
    below = np.maximum(above - 1, first + 1)
    # The nearest of the two neighbours of the target; on a tie, the earlier one (argmin).
    gap_below = np.abs(along[below] - along[first] - delta)
    gap_above = np.abs(along[above] - along[first] - delta)
    second = np.where(gap_below <= gap_above, below, above)
    gap = np.minimum(gap_below, gap_above)
    keep = gap <= tolerance
    return first[keep], second[keep]


def associate(
    times: object, reference_times: object, max_diff: float = 0.01, offset: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(i, j)`` pairing ``times[i] + offset`` with the nearest ``reference_times[j]``
    within ``max_diff`` (s), both increasing; each pose of the shorter one is paired at most
    once, as in evo's association."""
    times, reference = np.asarray(times, dtype=float), np.asarray(reference_times, dtype=float)
    for name, stamps in (("times", times), ("reference_times", reference)):
        if stamps.ndim != 1 or not np.all(np.isfinite(stamps)) or np.any(np.diff(stamps) <= 0):
            raise ValueError(f"{name} must be finite and increasing, one-dimensional")
    if not (math.isfinite(max_diff) and max_diff >= 0 and math.isfinite(offset)):
        raise ValueError(f"max_diff must be >= 0 and offset finite, got {max_diff}, {offset}")
    shifted = times + offset
    # Search the longer for each stamp of the shorter, as evo does; ties go to the earlier.
    estimate_longer = len(shifted) > len(reference)
    short, long = (reference, shifted) if estimate_longer else (shifted, reference)
    above = np.clip(np.searchsorted(long, short, side="right"), 0, len(long) - 1)
    below = np.maximum(above - 1, 0)
    gap_above, gap_below = np.abs(long[above] - short), np.abs(short - long[below])
    nearest = np.where(gap_above < gap_below, above, below)
    keep = np.minimum(gap_above, gap_below) <= max_diff
    found_short, found_long = np.flatnonzero(keep), nearest[keep]
    return (found_long, found_short) if estimate_longer else (found_short, found_long)


def interpolate(times: object, poses: object, at: object) -> np.ndarray:
    """Poses ``(M, 3)`` at the times ``at`` ``(M,)`` s, each along the constant-twist arc
    between the two poses around it (the SE(2) geodesic; exact for odometry with ``exact``).
    Positions without headings (every heading NaN, as GPS fixes) are interpolated along the
    straight line between them, their headings left NaN."""
    times, at = np.asarray(times, dtype=float), np.asarray(at, dtype=float)
    poses = np.asarray(poses, dtype=float)
    if poses.shape != (len(times), 3) or len(times) < 2:
        raise ValueError(f"poses must have shape ({len(times)}, 3), at least 2, got {poses.shape}")
    increasing("times", times)
    positions_only = bool(np.isnan(poses[:, 2]).all())
    usable = np.isfinite(poses[:, :2] if positions_only else poses).all(axis=1)
    if not usable.all():
        raise ValueError(f"poses must be finite; pose {int(np.argmin(usable))} is not")
    if not (np.all(np.isfinite(at)) and at.min() >= times[0] and at.max() <= times[-1]):
        raise ValueError(f"times to interpolate at must lie within [{times[0]}, {times[-1]}] s")
    step = np.clip(np.searchsorted(times, at, side="right") - 1, 0, len(times) - 2)
    fraction = (at - times[step]) / (times[step + 1] - times[step])
    if positions_only:  # the NaN headings stay NaN
        return poses[step] + fraction[:, None] * (poses[step + 1] - poses[step])
    motion = batch.log(batch.relative_to(poses[step + 1], poses[step]))
    return batch.compose(poses[step], batch.exp(motion, fraction))


def through_fixes(
    times: object, poses: object, fix_times: object, fixes: object, at: object
) -> np.ndarray:
    """Positions ``(L, 2)`` m at the stamps ``at`` ``(L,)`` s (inside the fixes' span) of the
    dead reckoning ``poses`` ``(N, 3)`` at ``times`` ``(N,)`` s moved onto position ``fixes``
    ``(M, 2)`` at ``fix_times`` ``(M,)`` s by the rigid motion that best fits them, plus the
    fixes' residuals from it interpolated in time: the path passes through every fix and keeps
    the dead reckoning's shape between them. What fusing sparse fixes with wheels trusted
    between them gives at best, and what a smoother across gaps must not do worse than."""
    fix_times, fixes = floats("fix_times", fix_times), floats("fixes", fixes)
    if fixes.shape != (len(fix_times), 2) or len(fix_times) < 2:
        raise ValueError(
            f"fix_times (M,) and fixes (M, 2) with M >= 2 must match, got {fix_times.shape} "
            f"and {fixes.shape}"
        )
    increasing("fix_times", fix_times)
    stamps = np.concatenate([fix_times, np.asarray(at, dtype=float)])
    path = interpolate(times, poses, stamps)
    flat = np.column_stack([path[:, :2], np.zeros(len(path))])
    seen = np.column_stack([fixes, np.zeros(len(fixes))])
    carried = batch.compose(alignment(flat[: len(fixes)], seen), flat)[:, :2]
    residual = fixes - carried[: len(fixes)]
    between = np.column_stack([np.interp(stamps[len(fixes) :], fix_times, r) for r in residual.T])
    return carried[len(fixes) :] + between


def interpolate_covariances(times: object, covariances: object, at: object) -> np.ndarray:
    """Pose covariances ``(M, 3, 3)`` at the times ``at`` ``(M,)`` s (within ``times``),
    entry by entry on the straight line between the two around each (what ``interpolate``'s
    poses are given when a covariance goes with them)."""
    times, at = np.asarray(times, dtype=float), np.asarray(at, dtype=float)
    flat = np.asarray(covariances, dtype=float).reshape(len(times), 9)
    columns = [np.interp(at, times, flat[:, k]) for k in range(9)]
    return np.stack(columns, axis=-1).reshape(-1, 3, 3)


@dataclass(frozen=True, eq=False)
class Consistency:
    """``consistency``'s result: ``nees`` ``(T+1,)`` (NaN where the covariance is not positive
    definite, e.g. a start known exactly), ``anees`` (the mean NEES over the ``used`` poses
    divided by ``dof``), ``inside_50`` and ``inside_95`` (shares of the used poses), ``dof``
    (3: pose; 2: positions only) and ``used``."""

    nees: np.ndarray
    anees: float
    inside_50: float
    inside_95: float
    dof: int
    used: int


def consistency(
    estimate: object,
    covariances: object,
    truth: object,
    positions_only: bool | None = None,
    aligned: bool = False,
) -> Consistency:
    """How honest the covariances ``(T+1, 3, 3)`` (over ``x, y, theta``) of ``estimate``
    ``(T+1, 3)`` are against ``truth`` ``(T+1, 3)``: see the module. ``positions_only``
    (default: when the truth has no headings, NaN, as GPS) compares x and y alone.
    ``aligned``: the estimate first moved onto the truth by ``alignment``'s rigid motion, its
    covariances turned with it (for an estimate in a frame of its own, odometry against GPS)."""
    poses = np.array(estimate, dtype=float)
    reference = np.array(truth, dtype=float)
    if positions_only is None:
        positions_only = bool(np.isnan(reference[..., 2]).any()) if reference.ndim == 2 else False
    if positions_only:  # the headings take no part
        poses[..., 2] = reference[..., 2] = 0.0
    estimate, truth = _check(poses, reference)
    matrices = np.asarray(covariances, dtype=float)
    if matrices.shape != (len(estimate), 3, 3):
        raise ValueError(
            f"covariances must have shape ({len(estimate)}, 3, 3), got {matrices.shape}"
        )
    if not np.all(np.isfinite(matrices)):
        row = int(np.argmin(np.all(np.isfinite(matrices), axis=(1, 2))))
        raise ValueError(f"covariances must be finite; covariance {row} is not")
    if aligned:
        motion = alignment(estimate, truth)
        estimate = np.asarray(batch.compose(motion, estimate))
        c, s = math.cos(motion[2]), math.sin(motion[2])
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        matrices = turn @ matrices @ turn.T
        if positions_only:
            estimate[:, 2] = 0.0
    axes = [0, 1] if positions_only else [0, 1, 2]
    error = (truth - estimate)[:, axes]
    if not positions_only:
        error[:, 2] = batch.wrap_angle(error[:, 2])
    block = matrices[:, axes][:, :, axes]
    block = 0.5 * (block + np.swapaxes(block, 1, 2))
    scale = np.maximum(np.abs(block).max(axis=(1, 2)), np.finfo(float).tiny)
    smallest = np.linalg.eigvalsh(block).min(axis=1)
    if np.any(smallest < -1e-9 * scale):
        # Not a covariance at all: skipped as "known exactly", it would pass for honest.
        row = int(np.argmax(smallest < -1e-9 * scale))
        raise ValueError(
            f"covariance {row} is not positive semi-definite (an eigenvalue of "
            f"{smallest[row]:.3g}): not a covariance"
        )
    usable = smallest > 1e-12 * scale
    if not usable.any():
        raise ValueError(
            "no pose has a positive definite covariance: the estimate carries none (zeros?)"
        )
    nees = np.full(len(estimate), np.nan)
    solved = np.linalg.solve(block[usable], error[usable][..., None])[..., 0]
    with np.errstate(over="ignore", invalid="ignore"):
        nees[usable] = np.einsum("ni,ni->n", error[usable], solved)
    if not np.all(np.isfinite(nees[usable])):
        row = int(np.flatnonzero(usable)[np.argmin(np.isfinite(nees[usable]))])
        raise ValueError(
            f"pose {row}: its error ({np.abs(error[row]).max():.3g} off) against its covariance "
            "overflows the NEES past float64's range; are the estimate and the truth in one "
            "frame and one unit?"
        )
    dof = len(axes)
    used = nees[usable]
    return Consistency(
        nees,
        float(used.mean() / dof),
        float(np.mean(used <= chi2_quantile(0.5, dof))),
        float(np.mean(used <= chi2_quantile(0.95, dof))),
        dof,
        int(usable.sum()),
    )


@dataclass(frozen=True, eq=False)
class PathErrors:
    """``cross_track``, ``along_track`` (m) and ``heading`` (rad), each ``(..., T+1)``;
    ``position``: the distance to the reference position of the same time (m)."""

    cross_track: np.ndarray
    along_track: np.ndarray
    heading: np.ndarray
    position: np.ndarray

    def summary(self) -> dict[str, float]:
        """Mean and maximum of the position error and of the absolute cross-track error (m),
        and the maximum absolute along-track (m) and heading (rad) errors, over everything."""
        cross = np.abs(self.cross_track)
        return {
            "mean_position": float(self.position.mean()),
            "max_position": float(self.position.max()),
            "mean_cross_track": float(cross.mean()),
            "max_cross_track": float(cross.max()),
            "max_along_track": float(np.abs(self.along_track).max()),
            "max_heading": float(np.abs(self.heading).max()),
        }


def path_errors(
    plan_times: object,
    plan_poses: object,
    times: object,
    poses: object,
    reference: object,
    window: float = 2.0,
) -> PathErrors:
    """Errors of ``poses`` ``(..., T+1, 3)`` at ``times`` ``(T+1,)`` against a densely sampled
    path, its states' ``plan_times`` ``(M,)`` and ``plan_poses`` ``(M, 3)``, and against the
    ``reference`` poses ``(T+1, 3)`` of the same times. The nearest state is sought among
    those within ``window`` s of each time; the cross-track error is measured across that
    state's heading."""
    path_t = np.asarray(plan_times, dtype=float)
    path = np.asarray(plan_poses, dtype=float)
    t = np.asarray(times, dtype=float)
    robots = np.asarray(poses, dtype=float)
    reference = np.asarray(reference, dtype=float)
    if path.ndim != 2 or path.shape[1] != 3 or path_t.shape != (len(path),) or len(path) < 2:
        raise ValueError(f"the plan must be (M,) times and (M, 3) poses, got {path.shape}")
    if robots.shape[-2:] != (len(t), 3) or reference.shape != (len(t), 3):
        raise ValueError(
            f"poses must be (..., {len(t)}, 3) and reference ({len(t)}, 3) for {len(t)} times, "
            f"got {robots.shape} and {reference.shape}"
        )
    dx, dy = robots[..., 0] - reference[:, 0], robots[..., 1] - reference[:, 1]
    along = np.cos(reference[:, 2]) * dx + np.sin(reference[:, 2]) * dy
    heading = batch.wrap_angle(robots[..., 2] - reference[:, 2])
    cross = np.empty(robots.shape[:-1])
    starts = np.searchsorted(path_t, t - window)
    ends = np.searchsorted(path_t, t + window, side="right")
    for k in range(len(t)):
        lo, hi = min(starts[k], len(path) - 1), max(ends[k], starts[k] + 1)
        near = path[lo:hi]
        gx = robots[..., k, 0, None] - near[:, 0]
        gy = robots[..., k, 1, None] - near[:, 1]
        index = np.argmin(gx * gx + gy * gy, axis=-1)
        theta = near[index, 2]
        picked_x = np.take_along_axis(gx, index[..., None], axis=-1)[..., 0]
        picked_y = np.take_along_axis(gy, index[..., None], axis=-1)[..., 0]
        cross[..., k] = -np.sin(theta) * picked_x + np.cos(theta) * picked_y
    return PathErrors(cross, along, heading, np.hypot(dx, dy))
