"""Odometry calibration: the wheel radii and track width that make odometry match ground truth.

``calibrate(nominal_robot, runs, method)`` with ``runs`` a list of ``diffdrive.io.Run`` with
ground truth, or of ``(increments, truth)`` pairs: wheel-angle increments ``(T, 2)`` ``[left,
right]`` in rad and ground-truth poses ``(T+1, 3)`` at the same instants. Methods:

- ``"umbmark"`` (Borenstein and Feng 1996): clockwise and counter-clockwise square runs of
  side ``square_side``. From the mean final x error (ground truth minus odometry, in the start
  frame) of each direction, ``alpha = (x_cw + x_ccw) / (-4 L)`` gives the track width,
  ``b = b_0 (pi/2) / (pi/2 - alpha)``, and ``beta = (x_cw - x_ccw) / (-4 L)`` the diameter
  ratio ``E_d = (R + b_0/2) / (R - b_0/2)`` with ``R = (L/2) / sin(beta/2)``; the mean diameter
  is kept. Which runs are clockwise is read from the ground truth's net turn. Every run must
  be a closed square of side ``square_side`` by its ground truth (one net turn, four sides'
  length, a square's extent, back near its start); any other run is refused by name. The
  parameters' covariance comes from the scatter of the runs' final errors (the standard error
  of each direction's mean, propagated through the formulas), so it needs two runs or more in
  each direction; with one, the result has no covariance and says why.
- ``"least_squares"``: the odometry of every run (the chosen integration method, from each
  run's first ground-truth pose) against every ground-truth pose, with a robust loss, by
  ``scipy.optimize.least_squares``. The parameters' covariance comes from the Jacobian at the
  solution. When the runs cannot tell a parameter apart (only straight lines cannot fix the
  track width), the scaled Jacobian's condition number says so and ``calibrate`` raises
  ``CalibrationError`` instead of returning a number.
A ``SkidSteer`` robot is calibrated the same way, its ICR spread (the effective track, about
the same midpoint) in the place of the track width and its ``-icr_x`` in the place of the axle
offset (any model, through its ``with_geometry``).

- ``"increments"``: each step's motion instead of the whole path: the reference's distance
  and turn over every step (through the SE(2) logarithm of consecutive poses) against the
  wheels', ``s = (r_l dphi_l + r_r dphi_r) / 2`` and ``dtheta = (r_r dphi_r - r_l dphi_l) /
  track``, by least squares (the turn weighted by half the nominal track, so that both are
  metres). Errors do not accumulate along the run, so a stretch where the reference and the
  wheels disagree (slip, a reference that jumps) costs only its own steps; the reference must
  be sampled densely (a step's turn well under pi). This is the fit of a logged odometry, such
  as a ROS ``/odom`` topic, as a reference. With ``window`` steps at a time (the steps' moves
  composed over the window, against the reference's relative pose over it) the encoders'
  timing and rounding and the reference's jitter, which enter the wheels' side too, weigh
  less against the motion: on the OptiOdom experiments (20 Hz, motion capture) a window of 20
  cut the worst in-sample position error of the runs from 16.5-577 mm to 12.3-217.5 mm.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from diffdrive import batch
from diffdrive._optional import optional
from diffdrive._progress import progress_bar
from diffdrive._validate import whole
from diffdrive.integrate import Method, check_method
from diffdrive.io.run import Run
from diffdrive.model import Robot, check_robot, geometry_of
from diffdrive.simulation import dead_reckon, integrate_increments

__all__ = [
    "CALIBRATION_METHODS",
    "DEFAULT_EXTRA",
    "EXTRAS",
    "PARAMETERS",
    "CalibrationError",
    "CalibrationMethod",
    "CalibrationResult",
    "Increments",
    "LeastSquares",
    "MethodOptions",
    "UMBmark",
    "calibrate",
    "checked_runs",
    "run_names",
]

CalibrationMethod = Literal["umbmark", "least_squares", "minimax", "increments"]
"""The offline calibration methods' names."""
CALIBRATION_METHODS: tuple[CalibrationMethod, ...] = (
    "umbmark",
    "least_squares",
    "minimax",
    "increments",
)
"""Every ``CalibrationMethod``: UMBmark's square runs, least squares and minimax over the runs' end
poses, and least squares over every increment."""
PARAMETERS = ("left_wheel_radius", "right_wheel_radius", "track_width")
"""The geometry every method fits: both wheel radii and the track width (m)."""
EXTRAS = ("axle_offset", "heading_offset")
"""The optional parameters of least squares and minimax: how far the reference point lies ahead of
the axle (m), and a constant heading between the reference's body and the robot (rad)."""
DEFAULT_EXTRA: tuple[str, ...] = ()
"""The extras fitted when none are asked for (in the library and on the command line): none. The
heading offset belongs to the reference, not the robot file, and an axle offset helps only runs
that turn while driving."""
# A motion-capture body is set up within a few degrees of the robot's heading.
PLAUSIBLE_HEADING_OFFSET = math.radians(10.0)
_EXTRA_BOUNDS = {"axle_offset": (-0.5, 0.5), "heading_offset": (-0.5, 0.5)}
# Past this condition number of the scaled Jacobian, a parameter is not identified.
_CONDITION_LIMIT = 1e6


class CalibrationError(ValueError):
    """The runs cannot determine the parameters (or are not what the method needs)."""


@dataclass(frozen=True)
class UMBmark:
    """The ``umbmark`` method's options: ``square_side``, the side of the squares run, m."""

    square_side: float | None = None


@dataclass(frozen=True)
class LeastSquares:
    """The options of ``least_squares`` and ``minimax`` (which starts from least squares).

    ``extra`` adds parameters: ``"axle_offset"`` (the tracked point is not on the axle; a
    ``SkidSteer``'s ``-icr_x``) and ``"heading_offset"`` (a constant heading between the
    reference's body and the robot); ``loss`` and ``loss_scale`` (m) are scipy's robust loss;
    ``heading_weight`` (m per rad) weighs the heading errors against the position errors;
    ``prior_sigma`` (relative, e.g. 0.02) pulls the fit toward the nominal geometry: a
    Gaussian prior of that relative standard deviation on each geometry parameter, as
    residuals ``loss_scale * (p / p_nominal - 1) / prior_sigma``, so that a few runs cannot
    push the parameters far.
    """

    extra: tuple[str, ...] = DEFAULT_EXTRA
    loss: str = "soft_l1"
    loss_scale: float = 0.01
    heading_weight: float = 1.0
    prior_sigma: float | None = None


@dataclass(frozen=True)
class Increments:
    """The ``increments`` method's options: ``window``, how many steps one residual spans (a
    run's last window may be shorter)."""

    window: int = 1


MethodOptions = UMBmark | LeastSquares | Increments
"""A method's options: ``UMBmark``, ``LeastSquares`` (least squares, minimax) or ``Increments``."""
# Each method's options, and its defaults.
_OPTIONS: dict[str, type] = {
    "umbmark": UMBmark,
    "least_squares": LeastSquares,
    "minimax": LeastSquares,
    "increments": Increments,
}


def _options_for(method: str, options: MethodOptions | None) -> MethodOptions:
    """``options`` checked against ``method`` (None: the method's defaults); ``ValueError``
    names the option that belongs to another method."""
    if method not in _OPTIONS:
        raise ValueError(f"method must be one of {', '.join(CALIBRATION_METHODS)}, got {method!r}")
    if options is None:
        return _OPTIONS[method]()
    if isinstance(options, _OPTIONS[method]):
        return options
    if isinstance(options, Increments):
        raise ValueError(
            f"window is for the increments method only; got {options.window} with {method}"
        )
    if isinstance(options, UMBmark):
        raise ValueError(f"square_side is for the umbmark method only; got it with {method}")
    if isinstance(options, LeastSquares):
        raise ValueError("extra parameters are for least_squares and minimax")
    raise TypeError(f"options must be UMBmark, LeastSquares or Increments, got {options!r}")


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """A calibrated ``robot`` and how well it is known.

    ``covariance`` is 3x3 over ``PARAMETERS`` (m^2), or None when the runs give none (then
    ``uncertainty_note`` says why); ``residuals`` are the fit's position errors at the
    solution, m, one array per run (for UMBmark, the final errors of each run);
    ``condition`` is the condition number of the scaled Jacobian (least squares), or None;
    ``heading_offset`` (rad) the fitted constant between the reference's heading and the
    robot's (0 unless fitted); a fitted axle offset is the robot's own.
    """

    robot: Robot
    method: str
    covariance: np.ndarray | None
    residuals: list[np.ndarray] = field(repr=False)
    condition: float | None = None
    uncertainty_note: str = ""
    heading_offset: float = 0.0

    @property
    def standard_errors(self) -> np.ndarray | None:
        """One standard deviation of each parameter, m; None without a covariance."""
        return None if self.covariance is None else np.sqrt(np.diag(self.covariance))

    @property
    def implausible(self) -> list[str]:
        """What the fitted extra parameters say that no robot of this size would: an axle
        offset of more than the track (the tracked point outside the robot), a heading
        offset of more than ``PLAUSIBLE_HEADING_OFFSET`` (a reference frame turned that far
        from the robot's is more likely a fit that absorbed something else)."""
        found = []
        drive = self.robot.equivalent
        if abs(drive.axle_offset) > drive.track_width:
            found.append(
                f"axle offset {drive.axle_offset:.3f} m is more than the track "
                f"({drive.track_width:.3f} m): the tracked point would lie outside the robot"
            )
        if abs(self.heading_offset) > PLAUSIBLE_HEADING_OFFSET:
            found.append(
                f"heading offset {math.degrees(self.heading_offset):.1f} deg: a reference "
                f"turned more than {math.degrees(PLAUSIBLE_HEADING_OFFSET):.0f} deg from the "
                "robot is more likely a fit that absorbed a slip or a bad stretch"
            )
        return found


def _robot_with(nominal: Robot, parameters: np.ndarray, axle_offset: float | None = None):
    """``nominal`` with new wheel radii and track (its model's ``with_geometry``), and the
    equivalent drive's ``axle_offset`` if given."""
    left, right, track = (float(p) for p in parameters)
    return nominal.with_geometry(left, right, track, axle_offset)


def run_names(runs: Sequence, names: Sequence[str] | None) -> list[str]:
    """``names``, or each run's source (a ``Run``) or ``run k`` (a pair)."""
    if names is not None:
        return list(names)
    return [run.source if isinstance(run, Run) else f"run {k}" for k, run in enumerate(runs)]


def checked_runs(runs: Sequence, names: list[str]) -> list[tuple[np.ndarray, np.ndarray]]:
    """``runs`` as checked ``(increments, truth)`` pairs; ``CalibrationError`` names the run."""
    if not runs:
        raise CalibrationError("calibrate needs at least one run")
    if len(names) != len(runs):
        raise ValueError(f"names must name each of the {len(runs)} runs, got {len(names)}")
    checked = []
    for k, run in zip(names, runs, strict=True):
        if isinstance(run, Run):
            if run.truth is None:
                raise CalibrationError(f"{k}: the run has no ground truth to calibrate against")
            increments, truth = run.increments(), run.truth
        else:
            try:
                increments, truth = run
            except (TypeError, ValueError):
                kind = type(run).__name__
                raise TypeError(f"{k}: a run is a Run or (increments, truth), got {kind}") from None
        increments, truth = np.asarray(increments, float), np.asarray(truth, float)
        if increments.ndim != 2 or increments.shape[1] != 2:
            raise CalibrationError(f"{k}: increments must be (T, 2), got {increments.shape}")
        if truth.shape != (len(increments) + 1, 3):
            raise CalibrationError(
                f"{k}: ground truth must be (T+1, 3) = {(len(increments) + 1, 3)}, got "
                f"{truth.shape}"
            )
        if not (np.all(np.isfinite(increments)) and np.all(np.isfinite(truth))):
            raise CalibrationError(f"{k}: increments and ground truth must be finite")
        checked.append((increments, truth))
    return checked


def calibrate(
    nominal_robot: Robot,
    runs: Sequence[Run | tuple[np.ndarray, np.ndarray]],
    method: CalibrationMethod = "least_squares",
    options: MethodOptions | None = None,
    *,
    integration: Method = "exact",
    fixed: tuple[str, ...] = (),
    names: list[str] | None = None,
    progress: bool = False,
) -> CalibrationResult:
    """Calibrate ``nominal_robot``'s wheel radii and track width on ``runs``; see the module.

    ``options`` are the method's own (``UMBmark``, ``LeastSquares`` for least squares and
    minimax, ``Increments``; None: its defaults). ``integration`` is the odometry's method
    (default exact, as everywhere; the OptiOdom reproduction names rk2, the authors' method).
    ``fixed`` names parameters held at their nominal values (``"track_width"``, say, when the
    runs cannot identify it). ``names`` name the runs in messages (default: a ``Run``'s
    source, else ``run 0``, ``run 1``, ...; a ``Run`` of ticks needs its own ticks per
    revolution); ``progress`` shows a progress bar of the fit's evaluations on standard error.
    On the OptiOdom runs held out one at a time, the axle offset lowers the errors and the
    heading offset's gain is the reference's, not the robot file's (see
    docs/guides/calibration.md); a per-run start-pose offset raised them and a time offset
    changed nothing, so neither is offered.

    Before fitting, the runs must excite every free parameter: they must drive (the wheel
    radii), turn (the track width) and turn both ways (a difference between the wheels apart
    from the track width); ``CalibrationError`` names what is missing and which runs would
    supply it. Past that, the fit's condition number decides.
    """
    check_robot(nominal_robot, "nominal_robot")
    check_method(integration)
    options = _options_for(method, options)
    if isinstance(options, Increments):
        window = whole("window", options.window, smallest=1)
    if isinstance(options, LeastSquares):
        extra = _check_extra(options.extra)
        prior = _checked_prior(options.prior_sigma)
    names = run_names(runs, names)
    checked = checked_runs(runs, names)
    free = _free(fixed)
    if isinstance(options, UMBmark):
        side = options.square_side
        if side is None or not side > 0:
            raise CalibrationError(f"umbmark needs square_side > 0 (m), got {side!r}")
        return _umbmark(nominal_robot, checked, names, float(side), integration)
    _check_excitation(nominal_robot, checked, free)
    if isinstance(options, Increments):
        parameters, covariance, condition = _fit_increments(nominal_robot, checked, free, window)
        robot = _robot_with(nominal_robot, parameters)
        residuals = _position_errors(robot, checked, integration)
        return CalibrationResult(robot, method, covariance, residuals, condition)
    parameters, covariance, condition, found = _fit_least_squares(
        nominal_robot,
        checked,
        integration,
        options.loss,
        options.loss_scale,
        options.heading_weight,
        free,
        progress,
        extra,
        prior,
    )
    offset = found.get("heading_offset", 0.0)
    axle = found.get("axle_offset")
    if method == "minimax":
        parameters = _minimax(nominal_robot, checked, integration, parameters, axle, offset)
    robot = _robot_with(nominal_robot, parameters, axle)
    residuals = _position_errors(robot, checked, integration, offset)
    return CalibrationResult(robot, method, covariance, residuals, condition, heading_offset=offset)


def _check_square(name: str, truth: np.ndarray, side: float) -> None:
    """Refuse a run whose ground truth is not a closed square of ``side`` m."""
    local = batch.relative_to(truth, truth[0])
    length = float(np.sum(np.hypot(*np.diff(truth[:, :2], axis=0).T)))
    turn = abs(truth[-1, 2] - truth[0, 2])
    extent = np.ptp(local[:, :2], axis=0)
    gap = float(np.hypot(*local[-1, :2]))
    problems = []
    if abs(turn - 2 * math.pi) > math.pi / 4:
        problems.append(f"it turns {math.degrees(turn):.0f} deg in all, not 360")
    if abs(length - 4 * side) > 0.15 * 4 * side:
        problems.append(f"it is {length:.3g} m long, not about {4 * side:g} m")
    if np.any(np.abs(extent - side) > 0.25 * side):
        problems.append(f"it spans {extent[0]:.3g} x {extent[1]:.3g} m, not {side:g} x {side:g}")
    if gap > 0.25 * side:
        problems.append(f"it ends {gap:.3g} m from its start")
    if problems:
        raise CalibrationError(
            f"umbmark needs closed squares of side {side:g} m; {name} is not one: "
            + "; ".join(problems)
        )


def _umbmark_parameters(nominal: Robot, x_cw: float, x_ccw: float, side: float) -> np.ndarray:
    """Borenstein and Feng's corrections from the mean final x errors of each direction."""
    alpha = (x_cw + x_ccw) / (-4.0 * side)
    beta = (x_cw - x_ccw) / (-4.0 * side)
    track = nominal.track_width * (math.pi / 2) / (math.pi / 2 - alpha)
    ratio = 1.0  # right diameter over left
    if beta != 0.0:
        radius = (side / 2) / math.sin(beta / 2)
        ratio = (radius + nominal.track_width / 2) / (radius - nominal.track_width / 2)
    mean = 0.5 * (nominal.left_wheel_radius + nominal.right_wheel_radius)
    return np.array([mean * 2 / (ratio + 1), mean * 2 / (1 / ratio + 1), track])


def _umbmark(nominal: Robot, runs, names, side: float, integration: Method):
    errors: dict[str, list[np.ndarray]] = {"cw": [], "ccw": []}
    residuals = []
    for name, (increments, truth) in zip(names, runs, strict=True):
        _check_square(name, truth, side)
        poses = dead_reckon(nominal, increments, truth[0], integration)
        # In the start frame: ground truth minus odometry, as Borenstein and Feng measure it.
        error = (
            batch.relative_to(truth[-1], truth[0])[:2] - batch.relative_to(poses[-1], truth[0])[:2]
        )
        turn = truth[-1, 2] - truth[0, 2]
        errors["cw" if turn < 0 else "ccw"].append(error)
        residuals.append(error)
    if not errors["cw"] or not errors["ccw"]:
        raise CalibrationError(
            "umbmark needs clockwise and counter-clockwise runs; the ground truth turns "
            f"{len(errors['cw'])} clockwise and {len(errors['ccw'])} counter-clockwise"
        )
    x = {way: np.array(found)[:, 0] for way, found in errors.items()}
    parameters = _umbmark_parameters(nominal, x["cw"].mean(), x["ccw"].mean(), side)
    robot = _robot_with(nominal, parameters)
    if min(len(x["cw"]), len(x["ccw"])) < 2:
        note = (
            f"umbmark gives no uncertainty from {len(x['cw'])} clockwise and "
            f"{len(x['ccw'])} counter-clockwise runs: it needs 2 or more in each direction"
        )
        return CalibrationResult(robot, "umbmark", None, residuals, uncertainty_note=note)
    # The standard error of each direction's mean, through the formulas' Jacobian.
    variances = np.array([x[way].var(ddof=1) / len(x[way]) for way in ("cw", "ccw")])
    means, step = np.array([x["cw"].mean(), x["ccw"].mean()]), 1e-6 * side

    def at(cw_and_ccw: np.ndarray) -> np.ndarray:
        return _umbmark_parameters(nominal, cw_and_ccw[0], cw_and_ccw[1], side)

    jacobian = np.column_stack(
        [(at(means + d) - at(means - d)) / (2 * step) for d in step * np.eye(2)]
    )
    covariance = jacobian @ np.diag(variances) @ jacobian.T
    return CalibrationResult(robot, "umbmark", covariance, residuals)


def _fit_least_squares(
    nominal: Robot,
    runs,
    integration: Method,
    loss: str,
    scale: float,
    heading_weight: float,
    free: np.ndarray,
    progress: bool = False,
    extra: tuple[str, ...] = (),
    prior: float | None = None,
):
    """scipy's robust least squares over every ground-truth pose of every run (and the prior's
    residuals): ``(parameters, covariance, condition, {extra parameter: value})``."""
    start = _parameters(nominal)
    bar = progress_bar(progress, desc=f"fitting {len(runs)} runs", unit=" evaluations")

    def residuals(relative: np.ndarray, extras: np.ndarray) -> np.ndarray:
        if bar is not None:
            bar.update()
        found = dict(zip(extra, extras.tolist(), strict=True))
        robot = _robot_with(nominal, start * relative, found.get("axle_offset"))
        offset = found.get("heading_offset", 0.0)
        pieces = []
        for increments, truth in runs:
            begin = truth[0] + np.array([0.0, 0.0, offset])
            error = dead_reckon(robot, increments, begin, integration)[1:] - truth[1:]
            error[:, 2] = heading_weight * batch.wrap_angle(error[:, 2] - offset)
            pieces.append(error.ravel())
        if prior is not None:
            pieces.append(_quadratic_under(loss, scale, scale * (relative[free] - 1.0) / prior))
        return np.concatenate(pieces)

    offset = nominal.equivalent.axle_offset  # a SkidSteer's -icr_x
    initial = [offset if name == "axle_offset" else 0.0 for name in extra]
    try:
        return _solve(nominal, residuals, free, extra, initial, loss=loss, f_scale=scale)
    finally:
        if bar is not None:
            bar.close()


def _solve(nominal, residuals, free: np.ndarray, extra=(), initial=(), **options):
    """Least squares over the ``free`` parameters, relative to the nominal ones (so that all
    are of order 1), and the ``extra`` ones from ``initial``: ``(parameters, covariance (zero
    for fixed ones), condition, {extra: value})``."""
    least_squares = optional("scipy.optimize", "calibration", "calibration").least_squares

    start = _parameters(nominal)
    count = int(free.sum())
    lower, upper = (list(np.asarray(b)[free]) for b in _bounds(nominal))
    lower += [_EXTRA_BOUNDS[name][0] for name in extra]
    upper += [_EXTRA_BOUNDS[name][1] for name in extra]

    def reduced(x: np.ndarray) -> np.ndarray:
        relative = np.ones(3)
        relative[free] = x[:count]
        return residuals(relative, x[count:])

    fit = least_squares(
        reduced,
        np.array([1.0] * count + list(initial)),
        x_scale=1e-3,
        bounds=(lower, upper),
        method="trf",
        **options,
    )
    condition = _check_condition(fit.jac, free, extra)
    dof = max(1, fit.fun.size - len(fit.x))
    variance = float(np.sum(fit.fun**2) / dof)
    full = variance * np.linalg.inv(fit.jac.T @ fit.jac)
    covariance = np.zeros((3, 3))
    covariance[np.ix_(free, free)] = full[:count, :count] * np.outer(start[free], start[free])
    relative = np.ones(3)
    relative[free] = fit.x[:count]
    return (
        start * relative,
        covariance,
        condition,
        dict(zip(extra, fit.x[count:].tolist(), strict=True)),
    )


def _fit_increments(nominal: Robot, runs, free: np.ndarray, window: int):
    """Least squares of every window's distance and turn (see the module)."""
    parts = [_windows(increments, truth, window) for increments, truth in runs]
    wheels = np.concatenate([blocks for blocks, _ in parts])
    motion = np.concatenate([batch.log(batch.relative_to(t[1:], t[:-1])) for _, t in parts])
    start = _parameters(nominal)
    weight = 0.5 * nominal.track_width

    def residuals(relative: np.ndarray, _extras: np.ndarray) -> np.ndarray:
        twists = batch.to_twist(_robot_with(nominal, start * relative), wheels)
        # Each window's steps composed, so that a turn that changes within it is followed.
        moved = batch.log(integrate_increments(twists)[:, -1])
        return np.concatenate([motion[:, 0] - moved[:, 0], weight * (motion[:, 2] - moved[:, 2])])

    return _solve(nominal, residuals, free)[:3]


def _windows(increments: np.ndarray, truth: np.ndarray, window: int):
    """Wheel increments ``(T, 2)`` as windows ``(W, window, 2)`` of steps (the last one
    filled out with steps of no motion), and the ground truth at the windows' ends (its first
    pose too)."""
    count = -(-len(increments) // window)
    blocks = np.zeros((count * window, 2))
    blocks[: len(increments)] = increments
    ends = np.minimum(np.arange(count + 1) * window, len(increments))
    return blocks.reshape(count, window, 2), truth[ends]


def _check_condition(jacobian: np.ndarray, free: np.ndarray, extra=()) -> float:
    """The scaled Jacobian's condition number; ``CalibrationError`` past the limit."""
    singular = np.linalg.svd(jacobian, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else math.inf
    if condition > _CONDITION_LIMIT:
        _, _, vt = np.linalg.svd(jacobian)
        names = [name for name, is_free in zip(PARAMETERS, free, strict=True) if is_free]
        names += list(extra)
        weakest = names[int(np.argmax(np.abs(vt[-1])))]
        raise CalibrationError(
            f"the runs cannot identify the parameters: the fit's condition number is "
            f"{condition:.3g} (limit {_CONDITION_LIMIT:g}); the least determined is {weakest}. "
            f"{_ADVICE[weakest]}, or fix it at its nominal value (fixed=('{weakest}',); --fix "
            f"{weakest})."
        )
    return condition


# What kind of run identifies each parameter.
_ADVICE = {
    "left_wheel_radius": "Add runs that drive, and turn both ways",
    "right_wheel_radius": "Add runs that drive, and turn both ways",
    "track_width": "Turn in place in both directions to identify the track width",
    "axle_offset": "Turn while driving (arcs, both ways) to identify the axle offset",
    "heading_offset": "Drive straight for a while to identify the heading offset",
}
# Below these the runs do not excite a parameter: the distance driven (m), the turning (rad),
# and the smaller direction's share of the turning.
_LEAST_DISTANCE, _LEAST_TURN, _LEAST_OTHER_WAY = 0.5, 0.5, 0.1
_TURN_WINDOW = 20


def _quadratic_under(loss: str, scale: float, residuals: np.ndarray) -> np.ndarray:
    """Residuals whose robust ``loss`` (scale ``scale``) is the plain square of
    ``residuals``: a Gaussian prior must not be down-weighted as an outlier would be."""
    if loss == "linear":
        return residuals
    if loss == "soft_l1":  # rho(z) = 2 (sqrt(1 + z) - 1), z = (r / scale)^2: invert rho
        cost = residuals**2 / (2.0 * scale**2)
        return np.sign(residuals) * scale * np.sqrt((1.0 + cost) ** 2 - 1.0)
    raise ValueError(f"prior_sigma works with the linear and soft_l1 losses, not {loss!r}")


def _checked_prior(prior_sigma) -> float | None:
    """``prior_sigma`` as a float > 0, or None."""
    if prior_sigma is None:
        return None
    if (
        isinstance(prior_sigma, str | bool)
        or not float(prior_sigma) > 0
        or not math.isfinite(float(prior_sigma))
    ):
        raise ValueError(f"prior_sigma must be a finite number > 0, got {prior_sigma!r}")
    return float(prior_sigma)


def _check_extra(extra) -> tuple[str, ...]:
    """``extra`` as a tuple of known names."""
    extra = (extra,) if isinstance(extra, str) else tuple(extra)
    unknown = [name for name in extra if name not in EXTRAS]
    if unknown:
        raise ValueError(
            f"extra names {unknown[0]!r}; the extra parameters are {', '.join(EXTRAS)}"
        )
    return extra


def _free(fixed) -> np.ndarray:
    """The mask of the parameters not ``fixed``."""
    fixed = (fixed,) if isinstance(fixed, str) else tuple(fixed)
    unknown = [name for name in fixed if name not in PARAMETERS]
    if unknown:
        raise ValueError(f"fixed names {unknown[0]!r}; the parameters are {', '.join(PARAMETERS)}")
    free = np.array([name not in fixed for name in PARAMETERS])
    if not free.any():
        raise ValueError("every parameter is fixed: nothing to calibrate")
    return free


def _check_excitation(nominal, runs, free: np.ndarray) -> None:
    """Refuse runs that do not drive, turn, or turn both ways, as the free parameters need.

    Judged from the wheels with the nominal geometry, the turns summed over windows of
    ``_TURN_WINDOW`` steps, and of each run only the windows that turn at least a tenth as
    much as its sharpest: a square's steering corrections on its straight sides do not count
    as turning the other way.
    """
    increments = np.concatenate([increments for increments, _ in runs])
    motion = batch.to_twist(nominal, increments)  # per step: distance and turn
    distance = float(np.sum(np.abs(motion[:, 0])))
    turns = np.concatenate(
        [_significant(_window_sums(batch.to_twist(nominal, inc)[:, 2])) for inc, _ in runs]
    )
    left, right = float(np.sum(np.clip(turns, 0, None))), float(np.sum(np.clip(-turns, 0, None)))
    radii = bool(free[0] or free[1])
    if radii and distance < _LEAST_DISTANCE:
        raise CalibrationError(
            f"the runs drive {distance:.3g} m in all: too little to identify the wheel radii; "
            f"add runs that drive {_LEAST_DISTANCE:g} m or more"
        )
    if free[2] and left + right < _LEAST_TURN:
        raise CalibrationError(
            f"the runs turn {left + right:.3g} rad in all: too little to identify the "
            "track_width; turn in place in both directions to identify the track width (or "
            "fix it: fixed=('track_width',); --fix track_width)"
        )
    if free[2] and radii and min(left, right) < _LEAST_OTHER_WAY * max(left, right):
        way = "left (counter-clockwise)" if left > right else "right (clockwise)"
        raise CalibrationError(
            f"the runs turn only {way}: a difference between the wheels cannot be told from "
            "the track_width; add runs that turn the other way too, or fix one "
            "(fixed=('track_width',); --fix track_width)"
        )


def _significant(turns: np.ndarray) -> np.ndarray:
    """The turns at least a tenth of the largest (in magnitude)."""
    if not len(turns):
        return turns
    return turns[np.abs(turns) >= 0.1 * np.abs(turns).max()]


def _window_sums(values: np.ndarray) -> np.ndarray:
    """Sums of consecutive windows of ``_TURN_WINDOW`` values (the last may be shorter)."""
    edges = np.arange(0, len(values), _TURN_WINDOW)
    return np.add.reduceat(values, edges) if len(values) else values


def _bounds(nominal: Robot) -> tuple[list[float], list[float]]:
    """The parameters' range relative to the nominal ones: radii within 50 %; the track as
    its model allows (``TRACK_RANGE``: a skid-steer robot's ICR spread up to 3 times)."""
    low, high = nominal.TRACK_RANGE
    return [0.5, 0.5, low], [1.5, 1.5, high]


def _parameters(robot: Robot) -> np.ndarray:
    return np.array(geometry_of(robot)[:3])


def _position_errors(robot, runs, integration: Method, heading_offset: float = 0.0):
    """Each run's position error (m) at each ground-truth pose."""
    shift = np.array([0.0, 0.0, heading_offset])
    return [
        np.hypot(
            *(dead_reckon(robot, increments, truth[0] + shift, integration)[:, :2] - truth[:, :2]).T
        )
        for increments, truth in runs
    ]


def _minimax(nominal, runs, integration: Method, parameters: np.ndarray, axle=None, offset=0.0):
    """The parameters, from ``parameters``, that minimise the largest position error (the
    extra parameters stay as least squares found them)."""
    minimize = optional("scipy.optimize", "calibration", "minimax calibration").minimize

    def largest(relative: np.ndarray) -> float:
        robot = _robot_with(nominal, parameters * relative, axle)
        errors = _position_errors(robot, runs, integration, offset)
        return max(float(error.max()) for error in errors)

    # Within 2 % of the least-squares answer: the largest error alone can be flat along a
    # parameter (the track width, on runs that turn only in place), and it must not drift.
    simplex = 1.0 + 2e-3 * np.vstack([np.zeros(3), np.eye(3)])
    fit = minimize(
        largest,
        np.ones(3),
        method="Nelder-Mead",
        bounds=[(0.98, 1.02)] * 3,
        options={"xatol": 1e-7, "fatol": 1e-7, "initial_simplex": simplex},
    )
    return parameters * fit.x
