"""The noise model of odometry, identified from runs with a reference, and the covariance it
predicts along a run.

The model of the odometry's error has three parts:

- ``k`` (m): each wheel's travel in each step has a variance ``k |travel|``, as ``Odometry``
  propagates it (``WheelNoise.symmetric(k)``);
- ``radius_sigma``, ``track_sigma`` (relative): the run's geometry differs from the robot's by a
  Gaussian draw of these relative standard deviations, each wheel radius and the track, as
  ``monte_carlo``'s ``geometry_sigma``: an error that stays for the whole run;
- ``reference_sigma`` (m), ``reference_heading_sigma`` (rad): the reference's own noise.

Identification (``identify``). Each run is cut into ``windows`` stretches of equal travelled
distance (the odometry's). In each, the odometry's motion (from the wheels alone, starting at
rest) is compared with the reference's motion, both in the frame of the window's start:
``e = reference motion - odometry motion`` (x, y along and across, heading wrapped). Over a
window the error is small and linear in the terms, whatever happened before, and:

- the random walk's part of the windows of a run is independent from window to window, with
  ``Odometry``'s covariance over the window (``k`` times that for ``k`` = 1 m);
- the geometry's part is one draw per run, through each window's Jacobians: correlated across
  the windows of a run;
- the reference's part comes from its noise at both ends of the window: shared by neighbours.

So a run's stacked window errors are Gaussian with a covariance linear in the five variances
``theta = (k, radius_sigma^2, track_sigma^2, reference_sigma^2,
reference_heading_sigma^2)``, runs independent. Fisher scoring on the likelihood, kept
non-negative, gives theta and its covariance (the inverse information, runs as the units).
A term that the runs cannot identify, by itself or apart from the others, is refused by name.

Held out (``cross_validate``): the whole procedure scored on groups of runs it did not see,
each group in turn calibrated and identified on the others.

Prediction (``covariances``): the pose covariance along a run that the model implies, as the
error against that reference: ``Odometry``'s with ``k``, the geometry's through the unscented
transform of its three relative errors (over a long run with much turning a track error turns
the path far, beyond a linear Jacobian's reach), and the reference's noise.
``draw_reference`` draws a reference as the model says it arises, to score the model on
errors it made itself: what the real errors should look like if the model were right.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diffdrive import batch
from diffdrive._validate import finite, rng_of, whole
from diffdrive.calibration.offline import calibrate, checked_runs, run_names
from diffdrive.estimation.odometry import Odometry
from diffdrive.estimation.standing import GyroFit, allan_deviation, identify_gyro
from diffdrive.integrate import Method
from diffdrive.model import DiffDrive
from diffdrive.montecarlo import noisy_angles
from diffdrive.sensor_noise import draw_geometry
from diffdrive.simulation import dead_reckon
from diffdrive.types import Pose

__all__ = [
    "TERMS",
    "GyroFit",
    "HeldOut",
    "NoiseModel",
    "allan_deviation",
    "covariances",
    "cross_validate",
    "draw_reference",
    "identify",
    "identify_gyro",
    "identify_what_it_can",
    "score",
]

TERMS = ("k", "radius_sigma", "track_sigma", "reference_sigma", "reference_heading_sigma")
_STEP = 1e-6  # relative: the geometry's finite differences


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """``identify``'s result: the five terms (see the module; 0 for a term not fitted), the
    covariance ``(5, 5)`` of ``theta`` (``k`` m and the four variances), the ``runs`` it came
    from and the ``terms`` fitted."""

    k: float
    radius_sigma: float
    track_sigma: float
    reference_sigma: float
    reference_heading_sigma: float
    covariance: np.ndarray
    runs: int
    terms: tuple[str, ...]

    def __post_init__(self) -> None:
        # A negative or infinite term would be squared or rooted into covariances that look
        # valid, or NaN ones, far from here.
        for name in TERMS:
            if not finite(f"noise model {name}", getattr(self, name)) >= 0.0:
                raise ValueError(f"noise model {name} must be >= 0, got {getattr(self, name)!r}")

    @property
    def theta(self) -> np.ndarray:
        """``(k, radius_sigma^2, track_sigma^2, reference_sigma^2,
        reference_heading_sigma^2)``."""
        return np.array(
            [
                self.k,
                self.radius_sigma**2,
                self.track_sigma**2,
                self.reference_sigma**2,
                self.reference_heading_sigma**2,
            ]
        )

    def standard_errors(self) -> dict[str, float]:
        """The standard error of each fitted term in its own unit (k in m, the sigmas
        relative, m or rad; a sigma's from its variance's by the delta method)."""
        errors = {}
        theta, spread = self.theta, np.sqrt(np.maximum(np.diag(self.covariance), 0.0))
        for index, name in enumerate(TERMS):
            if name not in self.terms:
                continue
            if index == 0:
                errors[name] = float(spread[0])
            else:
                sigma = np.sqrt(theta[index])
                errors[name] = float(spread[index] / (2 * sigma)) if sigma > 0 else float("inf")
        return errors


def _bounds(poses: np.ndarray, count: int) -> np.ndarray:
    """``count + 1`` pose indices cutting the run into windows of equal travelled distance."""
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))])
    wanted = travelled[-1] * np.arange(1, count + 1) / count
    inner = np.clip(np.searchsorted(travelled, wanted), 1, len(poses) - 1)
    return np.unique(np.concatenate([[0], inner]))


def _relative(poses: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The motion from pose index ``a`` to ``b`` in the frame at ``a`` ``(W, 3)``."""
    return batch.relative_to(poses[b], poses[a])


def _window_terms(robot, increments, truth, count, method):
    """A run's window errors ``(3W,)`` and the five matrices ``(5, 3W, 3W)`` theta weighs."""
    start = truth[0]
    poses = dead_reckon(robot, increments, start, method)
    cut = _bounds(poses, count)
    a, b = cut[:-1], cut[1:]
    windows = len(a)
    moved = _relative(poses, a, b)
    seen = _relative(truth, a, b)
    error = seen - moved
    error[:, 2] = batch.wrap_angle(error[:, 2])
    walk = np.zeros((3 * windows, 3 * windows))
    for w in range(windows):
        odometry = Odometry(robot, method, Pose(), wheel_noise=1.0)
        rows = increments[a[w] : b[w]]
        odometry.update_arrays("increments", rows[:, 0], rows[:, 1])
        walk[3 * w : 3 * w + 3, 3 * w : 3 * w + 3] = odometry.covariance
    base = np.array([robot.left_wheel_radius, robot.right_wheel_radius, robot.track_width])
    jacobians = []
    for index in range(3):
        step = np.zeros(3)
        step[index] = _STEP
        other = robot.with_geometry(*(base * (1.0 + step)))
        shifted = dead_reckon(other, increments, start, method)
        jacobians.append(((_relative(shifted, a, b) - moved) / _STEP).ravel())
    radius = np.outer(jacobians[0], jacobians[0]) + np.outer(jacobians[1], jacobians[1])
    track = np.outer(jacobians[2], jacobians[2])
    # The reference's noise at both ends of each window, through the relative motion:
    # d(seen)/d(reference pose at a) and at b, linearised at the reference.
    ends = np.zeros((2, 3 * windows, 3 * (windows + 1)))  # (position, heading) parts
    for w in range(windows):
        theta = truth[a[w], 2]
        c, s = np.cos(theta), np.sin(theta)
        rotation = np.array([[c, s], [-s, c]])  # world to the window's frame
        gap = truth[b[w], :2] - truth[a[w], :2]
        turned = np.array([-s * gap[0] + c * gap[1], -c * gap[0] - s * gap[1]])
        at_a, at_b = 3 * w, 3 * (w + 1)
        rows = slice(3 * w, 3 * w + 2)
        ends[0, rows, at_a : at_a + 2] = -rotation
        ends[0, rows, at_b : at_b + 2] = rotation
        ends[1, rows, at_a + 2] = turned
        ends[1, 3 * w + 2, at_a + 2] = -1.0
        ends[1, 3 * w + 2, at_b + 2] = 1.0
    reference = [part @ part.T for part in ends]
    return error.ravel(), np.array([walk, radius, track, *reference])


def identify(
    robot: DiffDrive,
    runs,
    *,
    terms: tuple[str, ...] = TERMS,
    windows: int = 8,
    method: Method = "exact",
    iterations: int = 200,
    fixed: dict[str, float] | None = None,
) -> NoiseModel:
    """The noise model of ``robot``'s odometry from ``runs``, each a ``Run`` with ground truth
    or ``(increments (T, 2) rad, truth (T+1, 3))``, the truth as reference, each cut into
    ``windows``; ``terms`` chooses what is fitted, ``fixed`` holds others at known values
    (e.g. the reference's, ``{"reference_sigma": 0.001}`` for motion capture; in their own
    units, m or rad), and the rest are 0. ``ValueError`` names a term the runs cannot
    identify."""
    unknown = [term for term in terms if term not in TERMS]
    if unknown or not terms:
        raise ValueError(f"terms must be some of {', '.join(TERMS)}, got {terms!r}")
    held = dict(fixed or {})
    for name, value in held.items():
        if name not in TERMS or name in terms:
            raise ValueError(
                f"fixed terms must be some of {', '.join(TERMS)} not fitted, got {name!r}"
            )
        if not finite(f"fixed {name}", value) >= 0.0:
            raise ValueError(f"fixed {name} must be >= 0, got {value!r}")
    windows = whole("windows", windows, 1)
    runs = list(runs)
    if not runs:
        raise ValueError("identify needs at least one run")
    checked = checked_runs(runs, run_names(runs, None))
    per_run = {"radius_sigma", "track_sigma"} & set(terms)
    if per_run and len(checked) < 2:
        raise ValueError(
            f"{' and '.join(sorted(per_run))} vary from run to run: identifying them needs 2 "
            f"runs or more, got {len(checked)}"
        )
    fitted = np.array([term in terms for term in TERMS])
    data = [_window_terms(robot, i, t, windows, method) for i, t in checked]
    start = _start(data, fitted)
    for name, value in held.items():  # k is a variance's scale; the sigmas enter squared
        start[TERMS.index(name)] = value if name == "k" else value * value
    theta = _fit(data, start, fitted, iterations)
    information = _fisher(data, theta, fitted)
    _refuse_the_unidentified(information, fitted)
    covariance = np.zeros((5, 5))
    active = np.ix_(fitted, fitted)
    covariance[active] = np.linalg.pinv(information[active])
    return NoiseModel(
        float(theta[0]),
        float(np.sqrt(theta[1])),
        float(np.sqrt(theta[2])),
        float(np.sqrt(theta[3])),
        float(np.sqrt(theta[4])),
        covariance,
        len(checked),
        tuple(term for term in TERMS if term in terms),
    )


def identify_what_it_can(robot: DiffDrive, runs, **options) -> tuple[NoiseModel, tuple[str, ...]]:
    """``identify`` with every term the runs can identify: the terms it refuses are left
    out one at a time (and returned) until the rest are identified."""
    runs = list(runs)
    held = options.get("fixed") or {}
    terms: list[str] = [t for t in options.pop("terms", TERMS) if t not in held]
    left_out: list[str] = []
    while True:
        try:
            return identify(robot, runs, terms=tuple(terms), **options), tuple(left_out)
        except ValueError as refused:
            term = next((t for t in terms if t in str(refused)), None)
            if term is None or len(terms) == 1:
                raise
            terms.remove(term)
            left_out.append(term)


def _refuse_the_unidentified(information: np.ndarray, fitted: np.ndarray) -> None:
    """``ValueError`` naming a fitted term the runs carry no information on, or one they
    cannot tell from the others (the information, scaled to unit diagonal, nearly singular
    along it)."""
    for index in np.flatnonzero(fitted):
        if not information[index, index] > 0.0:
            raise ValueError(
                f"the runs cannot identify {TERMS[index]}: they do not excite it (a track error "
                "needs turning); leave it out of terms"
            )
    active = np.flatnonzero(fitted)
    block = information[np.ix_(active, active)]
    scale = np.sqrt(np.diag(block))
    values, vectors = np.linalg.eigh(block / np.outer(scale, scale))
    if values[0] < 1e-6:
        worst = TERMS[active[int(np.argmax(np.abs(vectors[:, 0])))]]
        raise ValueError(
            f"the runs cannot tell {worst} from the other terms (their errors look alike on "
            "these paths); leave one of them out of terms"
        )


def _sigma(parts: np.ndarray, theta: np.ndarray) -> np.ndarray:
    sigma = np.tensordot(theta, parts, axes=1)
    return sigma + np.eye(len(sigma)) * 1e-18 * max(1.0, float(np.abs(sigma).max()))


def _fisher(data, theta, fitted) -> np.ndarray:
    information = np.zeros((5, 5))
    for _, parts in data:
        inverse = np.linalg.inv(_sigma(parts, theta))
        weighted = np.einsum("ij,tjk->tik", inverse, parts)
        information += 0.5 * np.einsum("aij,bji->ab", weighted, weighted)
    information[~fitted, :] = 0.0
    information[:, ~fitted] = 0.0
    return information


def _likelihood_and_gradient(data, theta, fitted) -> tuple[float, np.ndarray]:
    total, gradient = 0.0, np.zeros(5)
    for error, parts in data:
        sigma = _sigma(parts, theta)
        sign, logdet = np.linalg.slogdet(sigma)
        if sign <= 0:
            return -np.inf, gradient
        inverse = np.linalg.inv(sigma)
        whitened = inverse @ error
        total -= 0.5 * (logdet + error @ whitened)
        gradient += 0.5 * (
            np.einsum("i,tij,j->t", whitened, parts, whitened)
            - np.einsum("ij,tji->t", inverse, parts)
        )
    gradient[~fitted] = 0.0
    return total, gradient


def _start(data, fitted) -> np.ndarray:
    """Moment matching: each fitted term's scale from its own share alone, divided among
    them (the others 0)."""
    theta = np.zeros(5)
    for index in np.flatnonzero(fitted):
        numerator = sum(float(e @ parts[index] @ e) for e, parts in data)
        denominator = sum(float(np.sum(parts[index] * parts[index])) for _, parts in data)
        theta[index] = max(numerator / denominator, 0.0) if denominator > 0 else 0.0
    theta[fitted] = np.maximum(theta[fitted], 1e-12) / max(1, int(fitted.sum()))
    return theta


def _fit(data, theta, fitted, iterations) -> np.ndarray:
    """Fisher scoring on theta, kept non-negative, each step halved until the likelihood
    rises."""
    active = np.ix_(fitted, fitted)
    best, gradient = _likelihood_and_gradient(data, theta, fitted)
    for _ in range(iterations):
        information = _fisher(data, theta, fitted)
        step = np.zeros(5)
        step[fitted] = np.linalg.lstsq(information[active], gradient[fitted], rcond=None)[0]
        scale = 1.0
        while scale > 1e-6:
            trial = np.maximum(theta + scale * step, 0.0)
            value, trial_gradient = _likelihood_and_gradient(data, trial, fitted)
            if value >= best:
                break
            scale *= 0.5
        else:
            break
        change = np.abs(trial - theta).max() / max(float(np.abs(theta).max()), 1e-300)
        theta, best, gradient = trial, value, trial_gradient
        if change < 1e-10:
            break
    return theta


def covariances(
    robot: DiffDrive,
    increments: object,
    start: object,
    model: NoiseModel,
    method: Method = "exact",
) -> tuple[np.ndarray, np.ndarray]:
    """The dead-reckoned poses ``(T+1, 3)`` of a run from ``start`` and the covariance
    ``(T+1, 3, 3)`` of their error against the reference ``model`` describes."""
    increments = np.asarray(increments, dtype=float)
    start = np.asarray(start, dtype=float)
    poses = dead_reckon(robot, increments, start, method)
    odometry = Odometry(robot, method, Pose(*start), wheel_noise=model.k)
    _, walk = odometry.update_arrays(
        "increments", increments[:, 0], increments[:, 1], covariance=True
    )
    assert walk is not None
    predicted = np.concatenate([np.zeros((1, 3, 3)), walk])
    # The geometry's spread by the unscented transform: sigma points at +-sqrt(3) sigma along
    # each of the three relative errors (kappa = 0), weights 1/6 each, the mean's 0.
    sigmas = np.array([model.radius_sigma, model.radius_sigma, model.track_sigma])
    base = np.array([robot.left_wheel_radius, robot.right_wheel_radius, robot.track_width])
    for index in np.flatnonzero(sigmas):
        for sign in (1.0, -1.0):
            step = np.zeros(3)
            step[index] = sign * np.sqrt(3.0) * sigmas[index]
            other = robot.with_geometry(*(base * (1.0 + step)))
            spread = dead_reckon(other, increments, start, method) - poses
            predicted += np.einsum("ti,tj->tij", spread, spread) / 6.0
    reference = np.diag(
        [model.reference_sigma**2, model.reference_sigma**2, model.reference_heading_sigma**2]
    )
    return poses, predicted + reference


def draw_reference(
    robot: DiffDrive,
    increments: object,
    start: object,
    model: NoiseModel,
    rng: np.random.Generator | int | None,
    method: Method = "exact",
) -> np.ndarray:
    """One reference ``(T+1, 3)`` for a run with wheel-angle ``increments`` ``(T, 2)`` rad
    from ``start``, drawn from ``rng`` (a NumPy generator, or a seed) as ``model`` says it
    arises: the run's geometry drawn once, each
    wheel's travel in each step with variance ``k |travel|``, the reference's own noise at each
    pose. ``reference - covariances(...)[0]`` is then an error the model's covariance should
    cover: the check that the model could have made the errors it is scored on."""
    increments = np.asarray(increments, dtype=float)
    start = np.asarray(start, dtype=float)
    rng = rng if isinstance(rng, np.random.Generator) else rng_of(rng)
    base = np.array([robot.left_wheel_radius, robot.right_wheel_radius, robot.track_width])
    sigmas = np.array([model.radius_sigma, model.radius_sigma, model.track_sigma])
    geometry = draw_geometry(base, sigmas, 1, rng)[0]
    wheels = noisy_angles(increments, geometry[:2], model.k, rng)
    poses = dead_reckon(robot.with_geometry(*geometry), wheels, start, method)
    floor = np.array([model.reference_sigma] * 2 + [model.reference_heading_sigma])
    return poses + floor * rng.standard_normal(poses.shape)


@dataclass(frozen=True, eq=False)
class HeldOut:
    """One group's score in ``cross_validate``: the ``model`` fitted without it (and the
    ``left_out`` terms its runs could not identify), and the consistency of its predicted
    covariance on the group's runs (``evaluation.Consistency``, all poses but the starts)."""

    model: NoiseModel
    left_out: tuple[str, ...]
    consistency: object


def cross_validate(nominal: DiffDrive, groups: dict, *, calibrate_with=None) -> dict:
    """Each group of runs (``{name: [(increments, truth), ...]}``, e.g. an experiment's) scored
    by a noise model that never saw it: the geometry calibrated (``calibrate_with(nominal,
    runs)``, default least squares) and the model identified on the other groups, then the
    consistency of the covariance it predicts on the group's runs. ``{name: HeldOut}``."""
    if len(groups) < 2:
        raise ValueError(f"cross_validate needs 2 groups of runs or more, got {len(groups)}")
    fit = calibrate_with or (lambda robot, runs: calibrate(robot, runs, "least_squares").robot)
    scores = {}
    for name, runs in groups.items():
        others = [run for other, rs in groups.items() if other != name for run in rs]
        robot = fit(nominal, others).equivalent  # the calibrated model's drive
        model, left_out = identify_what_it_can(robot, others)
        scores[name] = HeldOut(model, left_out, score(robot, runs, model))
    return scores


def score(robot: DiffDrive, runs, model: NoiseModel, method: Method = "exact"):
    """How honest ``model``'s predicted covariance is on ``runs`` (as ``identify`` takes
    them): ``evaluation.consistency`` of each run's dead reckoning from its first reference
    pose against its reference, pooled over the runs, every pose but the starts (known
    exactly)."""
    from diffdrive.evaluation import consistency

    estimates, predicted, truths = [], [], []
    for increments, truth in checked_runs(list(runs), run_names(runs, None)):
        poses, covariance = covariances(robot, increments, truth[0], model, method)
        estimates.append(poses[1:])
        predicted.append(covariance[1:])
        truths.append(truth[1:])
    return consistency(np.concatenate(estimates), np.concatenate(predicted), np.concatenate(truths))
