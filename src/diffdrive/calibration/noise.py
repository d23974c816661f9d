"""The noise model of odometry, identified from runs with a reference, and the covariance it
predicts along a run.

The model of the odometry's error has three parts:

- ``k_left``, ``k_right`` (m): each wheel's travel in each step has a variance ``k |travel|``,
  as ``Odometry`` propagates it (``WheelNoise(k_left, k_right)``);
- ``geometry`` ``(3, 3)``: the relative covariance of the geometry's error (left radius, right
  radius, track) from one group of runs to the next (an experiment, a session, a day): a random
  constant that every run of a group shares. The full matrix, because the radii move together
  (a floor, a load, a tyre pressure) and a track calibrated on one kind of path differs from
  another's;
- ``reference_sigma`` (m), ``reference_heading_sigma`` (rad): the reference's own noise.

Identification (``identify``). Each run is cut into ``windows`` stretches of equal travelled
distance (the odometry's). In each, the odometry's motion (from the wheels alone, starting at
rest) is compared with the reference's motion, both in the frame of the window's start:
``e = reference motion - odometry motion`` (x, y along and across, heading wrapped). Over a
window the error is small and linear in the terms, whatever happened before, and:

- the wheels' part is independent from window to window, with ``Odometry``'s covariance over
  the window for each wheel's ``k`` = 1 m;
- the geometry's part is one draw a group, through each window's Jacobians: correlated across
  the windows of every run of the group;
- the reference's part comes from its noise at both ends of the window: shared by neighbours.

So a group's stacked window errors are Gaussian with a covariance linear in ten parameters
(``_noise_fit.PARAMETERS``: the two ``k``, the geometry's six entries, the reference's two
variances), groups independent. Fisher scoring on the likelihood, the geometry kept positive
semi-definite, gives them and their covariance (the inverse information). A term that the
runs cannot identify, by itself or apart from the others, is refused by name. A reference of
stated accuracy (motion capture: ``MOTION_CAPTURE``) is held at it (``fixed``): fitted, its
terms would take the odometry's own errors.

Held out (``cross_validate_noise``): the whole procedure scored on groups of runs it did not see,
each group (or each group's whole session) in turn calibrated and identified on the others.

Prediction (``covariances``): the pose covariance along a run that the model implies, as the
error against that reference: ``Odometry``'s with each wheel's ``k``, the geometry's through
the unscented transform along the principal axes of ``geometry`` (over a long run with much
turning a track error turns the path far, beyond a linear Jacobian's reach), and the
reference's noise. ``draw_reference`` draws a reference as the model says it arises, to score
the model on errors it made itself: what the real errors should look like if it were right.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from diffdrive._validate import finite, rng_of, whole
from diffdrive.calibration import _noise_fit
from diffdrive.calibration.offline import calibrate, checked_runs, run_names
from diffdrive.estimation.odometry import Odometry
from diffdrive.estimation.standing import GyroFit, allan_deviation, identify_gyro
from diffdrive.integrate import Method
from diffdrive.model import DiffDrive, Robot
from diffdrive.montecarlo import noisy_angles
from diffdrive.sensor_noise import NONE, WheelNoise
from diffdrive.simulation import dead_reckon
from diffdrive.types import Pose

__all__ = [
    "MOTION_CAPTURE",
    "TERMS",
    "GyroFit",
    "HeldOut",
    "NoiseModel",
    "allan_deviation",
    "covariances",
    "cross_validate_noise",
    "draw_reference",
    "identify",
    "identify_gyro",
    "identify_what_it_can",
    "identify_wheel_noise",
    "score",
]

TERMS = (
    "k_left",
    "k_right",
    "radius_sigma",
    "track_sigma",
    "reference_sigma",
    "reference_heading_sigma",
)
"""The noise model's terms by name: each wheel's ``k`` (m), the relative spread of the radii and of
the track, and the reference's position (m) and heading (rad) noise."""
MOTION_CAPTURE = (0.001, math.radians(0.1))
"""A motion-capture reference's accuracy ``(m, rad)``: 1 mm and 0.1 degree, above the room's
sub-millimetre (OptiOdom's ground truth jitters at the millimetre)."""
# Which term owns each of _noise_fit.PARAMETERS (a pair of the geometry is fitted when both of
# its terms are), and how a refusal names it.
_OWNER = (
    ("k_left",),
    ("k_right",),
    ("radius_sigma",),
    ("radius_sigma",),
    ("track_sigma",),
    ("radius_sigma",),
    ("radius_sigma", "track_sigma"),
    ("radius_sigma", "track_sigma"),
    ("reference_sigma",),
    ("reference_heading_sigma",),
)
_LABEL = (
    "k_left",
    "k_right",
    "radius_sigma (left)",
    "radius_sigma (right)",
    "track_sigma",
    "radius_sigma (the radii's correlation)",
    "track_sigma (its correlation with the left radius)",
    "track_sigma (its correlation with the right radius)",
    "reference_sigma",
    "reference_heading_sigma",
)


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """``identify``'s result (see the module): the wheels' ``wheel_noise`` (a ``WheelNoise``;
    a number ``k`` (m) or a pair is read as one), the ``geometry``'s relative covariance
    ``(3, 3)`` over (left radius, right radius, track) from group to group, the reference's
    ``reference_sigma`` (m) and ``reference_heading_sigma`` (rad); the ``covariance``
    ``(10, 10)`` of ``_noise_fit.PARAMETERS``, the ``runs`` and ``groups`` it came from and the
    ``terms`` fitted. ``NoiseModel.symmetric`` builds one by hand."""

    wheel_noise: WheelNoise = NONE
    geometry: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    reference_sigma: float = 0.0
    reference_heading_sigma: float = 0.0
    covariance: np.ndarray = field(default_factory=lambda: np.zeros((10, 10)))
    runs: int = 0
    groups: int = 0
    terms: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        # A negative or infinite term would be squared or rooted into covariances that look
        # valid, or NaN ones, far from here.
        wheels = WheelNoise.coerce(self.wheel_noise, "noise model wheel_noise")
        object.__setattr__(self, "wheel_noise", wheels)
        for name in ("reference_sigma", "reference_heading_sigma"):
            if not finite(f"noise model {name}", getattr(self, name)) >= 0.0:
                raise ValueError(f"noise model {name} must be >= 0, got {getattr(self, name)!r}")
        geometry = np.asarray(self.geometry, dtype=float)
        if geometry.shape != (3, 3) or not np.all(np.isfinite(geometry)):
            raise ValueError(
                f"noise model geometry must be a finite (3, 3) matrix, got {geometry!r}"
            )
        if not np.allclose(geometry, geometry.T, rtol=0.0, atol=1e-15):
            raise ValueError("noise model geometry must be symmetric (a covariance)")
        if np.linalg.eigvalsh(geometry)[0] < -1e-12 * max(1.0, float(np.abs(geometry).max())):
            raise ValueError(
                "noise model geometry must be positive semi-definite (a covariance), got "
                f"eigenvalues {np.linalg.eigvalsh(geometry)!r}"
            )
        object.__setattr__(self, "geometry", geometry)

    @classmethod
    def symmetric(
        cls,
        k: float,
        radius_sigma: float = 0.0,
        track_sigma: float = 0.0,
        reference_sigma: float = 0.0,
        reference_heading_sigma: float = 0.0,
    ) -> NoiseModel:
        """A model by hand: both wheels' ``k`` (m), each radius and the track drawn
        independently with these relative standard deviations, the reference's noise."""
        for name, value in (("k", k), ("radius_sigma", radius_sigma), ("track_sigma", track_sigma)):
            if not finite(f"noise model {name}", value) >= 0.0:
                raise ValueError(f"noise model {name} must be >= 0, got {value!r}")
        geometry = np.diag([radius_sigma**2, radius_sigma**2, track_sigma**2])
        return cls(WheelNoise.symmetric(k), geometry, reference_sigma, reference_heading_sigma)

    @property
    def k_left(self) -> float:
        """The left wheel's ``k`` (m): ``wheel_noise.left``, by the name of its term."""
        return self.wheel_noise.left

    @property
    def k_right(self) -> float:
        """The right wheel's ``k`` (m): ``wheel_noise.right``, by the name of its term."""
        return self.wheel_noise.right

    @property
    def k(self) -> float:
        """The wheels' mean ``k`` (m): what a speed's or a turn's variance takes from both."""
        return 0.5 * (self.k_left + self.k_right)

    @property
    def sigmas(self) -> np.ndarray:
        """The relative standard deviations ``(3,)`` of the left radius, right radius, track."""
        return np.sqrt(np.diag(self.geometry))

    @property
    def radius_sigma(self) -> float:
        """The radii's root-mean-square relative standard deviation."""
        return float(np.sqrt(0.5 * (self.geometry[0, 0] + self.geometry[1, 1])))

    @property
    def track_sigma(self) -> float:
        """The track's relative standard deviation."""
        return float(self.sigmas[2])

    @property
    def correlation(self) -> np.ndarray:
        """The geometry's correlation matrix ``(3, 3)`` (0 off the diagonal where a sigma is)."""
        sigmas = self.sigmas
        scale = np.where(sigmas > 0, sigmas, 1.0)
        out = self.geometry / np.outer(scale, scale)
        np.fill_diagonal(out, 1.0)
        return out

    @property
    def theta(self) -> np.ndarray:
        """``_noise_fit.PARAMETERS``: the two ``k``, the geometry's six entries, the
        reference's two variances ``(10,)``."""
        g = self.geometry
        return np.array(
            [
                self.k_left,
                self.k_right,
                *(g[row, column] for row, column in _noise_fit.GEOMETRY),
                self.reference_sigma**2,
                self.reference_heading_sigma**2,
            ]
        )

    def standard_errors(self) -> dict[str, float]:
        """The standard error of each fitted term in its own unit (``k`` in m, the sigmas
        relative, m or rad, a sigma's from its variance's by the delta method): ``k_left``,
        ``k_right``, ``radius_left_sigma``, ``radius_right_sigma``, ``track_sigma``,
        ``reference_sigma``, ``reference_heading_sigma`` as fitted."""
        theta, spread = self.theta, np.sqrt(np.maximum(np.diag(self.covariance), 0.0))
        names = {
            0: "k_left",
            1: "k_right",
            2: "radius_left_sigma",
            3: "radius_right_sigma",
            4: "track_sigma",
            8: "reference_sigma",
            9: "reference_heading_sigma",
        }
        errors = {}
        for index, name in names.items():
            if not set(_OWNER[index]) <= set(self.terms):
                continue
            if index < 2:
                errors[name] = float(spread[index])
            else:
                sigma = np.sqrt(theta[index])
                errors[name] = float(spread[index] / (2 * sigma)) if sigma > 0 else float("inf")
        return errors

    def unseen(self) -> NoiseModel:
        """The model for a group its calibration did not see: its geometry a new draw about
        a mean calibrated on ``groups`` draws, whose own error adds ``geometry / groups``
        (1 group or none: unchanged)."""
        if self.groups < 2:
            return self
        return replace(self, geometry=self.geometry * (1.0 + 1.0 / self.groups))

    def draw_geometry(self, rng: np.random.Generator) -> np.ndarray:
        """One group's relative geometry error ``(3,)`` (left radius, right radius, track)."""
        values, vectors = np.linalg.eigh(self.geometry)
        return vectors @ (np.sqrt(np.maximum(values, 0.0)) * rng.standard_normal(3))


def _groups_of(runs) -> list[list]:
    """The runs as groups: a mapping's values, or each run of a sequence its own group."""
    if isinstance(runs, Mapping):
        groups = [list(group) for group in runs.values()]
        empty = [name for name, group in zip(runs, groups, strict=True) if not group]
        if empty:
            raise ValueError(f"group {empty[0]!r} has no runs")
        return groups
    return [[run] for run in runs]


def _fitted(terms: tuple[str, ...]) -> np.ndarray:
    return np.array([set(owner) <= set(terms) for owner in _OWNER])


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
    """The noise model of ``robot``'s odometry from ``runs``: a sequence of runs, each a
    ``Run`` with ground truth or ``(increments (T, 2) rad, truth (T+1, 3))``, the truth as
    reference, each run its own draw of the geometry; or a mapping ``{group: runs}`` whose
    runs share one (an experiment's, a session's). Each run is cut into ``windows``;
    ``terms`` chooses what is fitted, ``fixed`` holds others at known values in their own
    units (m or rad; the reference's stated accuracy, ``{"reference_sigma": 0.001, ...}``,
    ``MOTION_CAPTURE`` for motion capture), and the rest are 0. ``ValueError`` names a term
    the runs cannot identify."""
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
    groups = _groups_of(runs)
    if not groups:
        raise ValueError("identify needs at least one run")
    every = [run for group in groups for run in group]
    flat = checked_runs(every, run_names(every, None))
    per_group = {"radius_sigma", "track_sigma"} & set(terms)
    if per_group and len(groups) < 2:
        raise ValueError(
            f"{' and '.join(sorted(per_group))} vary from group to group (run to run where "
            f"the runs are not grouped): identifying them needs 2 or more, got {len(groups)}"
        )
    fitted = _fitted(terms)
    data, at = [], 0
    for group in groups:
        data.append(_noise_fit.group_terms(robot, flat[at : at + len(group)], windows, method))
        at += len(group)
    theta = _noise_fit.start(data, fitted)
    theta = _held(theta, held)
    theta = _noise_fit.fit(data, theta, fitted, iterations)
    information = _noise_fit.fisher(data, theta, fitted)
    _refuse_the_unidentified(information, fitted)
    covariance = np.zeros((10, 10))
    active = np.ix_(fitted, fitted)
    covariance[active] = np.linalg.pinv(information[active])
    if per_group:
        # The windows' errors are taken about a geometry calibrated on these same groups, so
        # their draws scatter about their own mean: (n - 1) / n of the spread (Bessel).
        scale = np.ones(10)
        scale[2:8] = len(groups) / (len(groups) - 1)
        theta = theta * scale
        covariance = covariance * np.outer(scale, scale)
    return NoiseModel(
        WheelNoise(float(theta[0]), float(theta[1])),
        _noise_fit.geometry_covariance(theta),
        float(np.sqrt(theta[8])),
        float(np.sqrt(theta[9])),
        covariance,
        len(flat),
        len(groups),
        tuple(term for term in TERMS if term in terms),
    )


def _held(theta: np.ndarray, held: dict[str, float]) -> np.ndarray:
    """theta with the ``fixed`` terms at their values: each k as it is, the sigmas squared
    (the radii and the track independent)."""
    where = {
        "k_left": (0,),
        "k_right": (1,),
        "radius_sigma": (2, 3),
        "track_sigma": (4,),
        "reference_sigma": (8,),
        "reference_heading_sigma": (9,),
    }
    out = theta.copy()
    for name, value in held.items():
        out[list(where[name])] = value if name.startswith("k_") else value * value
    return out


def identify_wheel_noise(
    robot: Robot, increments: np.ndarray, truth: np.ndarray
) -> tuple[WheelNoise | None, str]:
    """Each wheel's ``k`` (m) from one log's wheel-angle ``increments`` ``(N-1, 2)`` rad
    against its motion-capture ground truth ``(N, 3)`` (``identify`` of the two wheel terms,
    the reference held at ``MOTION_CAPTURE``), and a line saying where it came from; None and
    the reason where the log cannot identify them (a refusal, or a wheel at 0 m: its errors are
    then not the wheels' random walk)."""
    metres, radians = MOTION_CAPTURE
    fixed = {"reference_sigma": metres, "reference_heading_sigma": radians}
    try:
        found = identify(robot.equivalent, [(increments, truth)], terms=TERMS[:2], fixed=fixed)
    except ValueError as refused:
        return None, f"the ground truth could not identify them ({refused})"
    if found.k_left == 0.0 or found.k_right == 0.0:
        return None, (
            "identified on the ground truth, a wheel came out at 0 m (its errors are not the "
            "wheels' random walk)"
        )
    errors = found.standard_errors()
    return found.wheel_noise, (
        f"identified on the log's ground truth, +-{errors['k_left']:.2g} and "
        f"+-{errors['k_right']:.2g} m, the reference held at motion capture's "
        f"{1000 * metres:g} mm and {math.degrees(radians):g} deg"
    )


def identify_what_it_can(robot: DiffDrive, runs, **options) -> tuple[NoiseModel, tuple[str, ...]]:
    """``identify`` with every term the runs can identify: the terms it refuses are left
    out one at a time (and returned) until the rest are identified."""
    runs = runs if isinstance(runs, Mapping) else list(runs)
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
                f"the runs cannot identify {_LABEL[index]}: they do not excite it (a track "
                "error needs turning, one wheel's noise a turn that tells it from the other's); "
                "leave it out of terms"
            )
    active = np.flatnonzero(fitted)
    block = information[np.ix_(active, active)]
    scale = np.sqrt(np.diag(block))
    values, vectors = np.linalg.eigh(block / np.outer(scale, scale))
    if values[0] < 1e-6:
        worst = _LABEL[active[int(np.argmax(np.abs(vectors[:, 0])))]]
        raise ValueError(
            f"the runs cannot tell {worst} from the other terms (their errors look alike on "
            "these paths); leave one of them out of terms"
        )


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
    wheels = model.wheel_noise
    odometry = Odometry(robot, method, Pose(*start), wheel_noise=wheels)
    _, walk = odometry.update_arrays(
        "increments", increments[:, 0], increments[:, 1], covariance=True
    )
    assert walk is not None
    predicted = np.concatenate([np.zeros((1, 3, 3)), walk])
    # The geometry's spread by the unscented transform: sigma points at +-sqrt(3) along each
    # principal axis of its covariance (kappa = 0), weights 1/6 each, the mean's 0.
    values, vectors = np.linalg.eigh(model.geometry)
    base = np.array([robot.left_wheel_radius, robot.right_wheel_radius, robot.track_width])
    for index in np.flatnonzero(values > 0.0):
        axis = np.sqrt(3.0 * values[index]) * vectors[:, index]
        for sign in (1.0, -1.0):
            other = robot.with_geometry(*(base * (1.0 + sign * axis)))
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
    *,
    geometry: object = None,
) -> np.ndarray:
    """One reference ``(T+1, 3)`` for a run with wheel-angle ``increments`` ``(T, 2)`` rad
    from ``start``, drawn from ``rng`` (a NumPy generator, or a seed) as ``model`` says it
    arises: the group's relative geometry error ``geometry`` ``(3,)`` (drawn here when not
    given: ``model.draw_geometry``; give one draw to every run of a group), each wheel's
    travel in each step with variance ``k |travel|``, the reference's own noise at each pose.
    ``reference - covariances(...)[0]`` is then an error the model's covariance should cover:
    the check that the model could have made the errors it is scored on."""
    increments = np.asarray(increments, dtype=float)
    start = np.asarray(start, dtype=float)
    rng = rng if isinstance(rng, np.random.Generator) else rng_of(rng)
    base = np.array([robot.left_wheel_radius, robot.right_wheel_radius, robot.track_width])
    error = model.draw_geometry(rng) if geometry is None else np.asarray(geometry, dtype=float)
    if error.shape != (3,) or not np.all(np.isfinite(error)):
        raise ValueError(f"geometry must be a finite relative error (3,), got {geometry!r}")
    drawn = base * (1.0 + error)
    if np.any(drawn <= 0):
        raise ValueError("the geometry drawn has a radius or track <= 0: its spread is too wide")
    k = np.array([model.k_left, model.k_right])
    wheels = noisy_angles(increments, drawn[:2], k, rng)
    poses = dead_reckon(robot.with_geometry(*drawn), wheels, start, method)
    floor = np.array([model.reference_sigma] * 2 + [model.reference_heading_sigma])
    return poses + floor * rng.standard_normal(poses.shape)


@dataclass(frozen=True, eq=False)
class HeldOut:
    """One group's score in ``cross_validate_noise``: the ``robot`` calibrated and the ``model``
    fitted without it (and the ``left_out`` terms its training runs could not identify), the
    groups it was trained on, and the consistency of its predicted covariance on the group's
    runs (``evaluation.Consistency``, all poses but the starts)."""

    robot: DiffDrive
    model: NoiseModel
    left_out: tuple[str, ...]
    trained_on: tuple[str, ...]
    consistency: object


def cross_validate_noise(
    nominal: DiffDrive,
    groups: dict,
    *,
    sessions: dict | None = None,
    fixed: dict[str, float] | None = None,
    calibrate_with=None,
) -> dict:
    """Each group of runs (``{name: [(increments, truth), ...]}``, e.g. an experiment's) scored
    by a noise model that never saw it: the geometry calibrated (``calibrate_with(nominal,
    runs)``, default least squares) on the other groups pooled and the model identified on
    them, each a draw of the geometry, ``fixed`` holding the reference's stated accuracy;
    then the consistency of the covariance it predicts (``NoiseModel.unseen``: a group it
    never saw) on the group's runs. With
    ``sessions`` (``{name: session}`` for every group), every group of the held-out group's
    session is held out with it: by session. ``{name: HeldOut}``."""
    if len(groups) < 2:
        raise ValueError(f"cross_validate_noise needs 2 groups of runs or more, got {len(groups)}")
    if sessions is not None:
        missing = [name for name in groups if name not in sessions]
        if missing:
            raise ValueError(f"sessions gives no session for group {missing[0]!r}")
    fit = calibrate_with or (lambda robot, runs: calibrate(robot, runs, "least_squares").robot)
    scores = {}
    for name, runs in groups.items():
        if sessions is None:
            others = {other: rs for other, rs in groups.items() if other != name}
        else:
            others = {o: rs for o, rs in groups.items() if sessions[o] != sessions[name]}
        if len(others) < 2:
            raise ValueError(
                f"holding out {name!r} (session {sessions[name]!r}) leaves {len(others)} "
                "group to train on: the geometry's spread needs 2 or more"
                if sessions is not None
                else f"holding out {name!r} leaves 1 group to train on: the geometry's "
                "spread needs 2 or more"
            )
        pooled = [run for rs in others.values() for run in rs]
        robot = fit(nominal, pooled).equivalent  # the calibrated model's drive
        model, left_out = identify_what_it_can(robot, others, fixed=fixed)
        model = model.unseen()
        scores[name] = HeldOut(robot, model, left_out, tuple(others), score(robot, runs, model))
    return scores


def score(robot: DiffDrive, runs, model: NoiseModel, method: Method = "exact"):
    """How honest ``model``'s predicted covariance is on ``runs`` (a sequence, as
    ``identify`` takes them): ``evaluation.consistency`` of each run's dead reckoning from its
    first reference pose against its reference, pooled over the runs, every pose but the
    starts (known exactly)."""
    from diffdrive.evaluation import consistency

    estimates, predicted, truths = [], [], []
    for increments, truth in checked_runs(list(runs), run_names(runs, None)):
        poses, covariance = covariances(robot, increments, truth[0], model, method)
        estimates.append(poses[1:])
        predicted.append(covariance[1:])
        truths.append(truth[1:])
    return consistency(np.concatenate(estimates), np.concatenate(predicted), np.concatenate(truths))
