"""Calibration against an absolute reference that is not ground truth: a camera's or a
localiser's poses, or a GPS receiver's positions, each with its noise, its own stamps and its
own rate, and a gyro where there is one.

Estimated jointly (``PARAMETERS``, in ``UNITS``): the left and right wheel radii and the
track; the sensor's mount on the robot (``lever_x``, ``lever_y``; ``yaw`` for poses) and its
clock ``offset`` (a reading taken at ``t`` on the wheels' clock is stamped ``t + offset``);
the gyro's ``gyro_scale`` and ``gyro_bias`` (it reads ``(1 + scale) omega + bias``, as
``sensors.GyroModel``) and ``gyro_offset`` (its clock against the wheels', likewise); for
positions, the ``heading`` of the reference's frame in the odometry's.

Why a batch least squares over the motion between readings, and not the parameters as the
estimator's states: the motion between two readings depends on the parameters and on the
noise over that stretch alone, whatever the odometry got wrong before; a lever arm and a clock
offset are not states the estimator's motion model has, and a filter would carry the same
information through a linearisation at every step. Between readings ``k`` and ``k+1``:

- poses: the sensor moved ``S_k^-1 S_k+1`` (its readings) where the wheels say it moved
  ``E^-1 O_k E`` (``O_k`` the odometry's motion between the two instants, interpolated at the
  stamps less the offset; ``E`` the mount);
- positions: the antenna moved ``g_k+1 - g_k`` where the wheels' travel, turned by the gyro's
  heading (the wheels' own without a gyro) and carrying the lever arm, says it moved;
- with a gyro, the wheels' turn against the gyro's over the same stretches of the wheels'
  clock: each sensor is timed against the wheels.

Each stretch's residual is Gaussian with a covariance known in closed form: the wheels' noise
over the stretch (``Odometry``'s, seen from the sensor), the gyro's angle random walk, and the
reference's noise at both ends, which neighbouring stretches share, so it is block banded
(the wheels' turn noise that a stretch's two comparisons share is left out: beside the
reference's it is small). For positions the heading that turns the wheels' travel is
integrated from the start, and its random walk is added: the covariance is then dense. The
generalised least squares over it (Gauss-Newton, central-difference Jacobians) gives the
parameters and their covariance, inflated by the residuals' chi-square per degree of freedom
where the noise stated was too small. Without a gyro the positions' heading is the wheels'
own, whose drift the covariance leaves out.

What the drive made observable: the information matrix, scaled to unit diagonal, is
examined. A direction it barely sees is a combination the log cannot tell apart (named, with
its largest parts); a parameter whose standard error passes ``LIMITS`` is not determined.
Either is refused by name, with the drive that would supply it, and nothing is reported. A log
with too few readings, a reference that never moves, clocks that do not overlap: refused
before any fit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from diffdrive import batch
from diffdrive._validate import finite, settings_of, whole
from diffdrive.calibration._reference_model import (
    NOISES,
    PARAMETERS,
    RELATIVE,
    DivergedError,
    Log,
    antenna_positions,
    fit,
)
from diffdrive.calibration._reference_noise import UNDETERMINED, IdentifiedNoise, identify
from diffdrive.estimation.imu import Gyro
from diffdrive.estimation.settings import EstimatorSettings, Prior
from diffdrive.integrate import Method, check_method
from diffdrive.model import DiffDrive, geometry_of
from diffdrive.sensor_noise import DEFAULT, GyroNoise, WheelNoise

__all__ = [
    "LIMITS",
    "NOISES",
    "PARAMETERS",
    "UNITS",
    "ReferenceCalibration",
    "ReferenceSettings",
    "UndeterminedError",
    "calibrate_to_reference",
    "estimable",
]

UNITS = ("m", "m", "m", "m", "m", "rad", "s", "", "rad/s", "s", "rad")
# The standard error past which a parameter is not determined by the log (radii and track
# relative to their value).
LIMITS = {
    "left_radius": 0.05,
    "right_radius": 0.05,
    "track": 0.05,
    "lever_x": 0.5,
    "lever_y": 0.5,
    "yaw": 0.2,
    "offset": 0.2,
    "gyro_scale": 0.05,
    "gyro_bias": 0.01,
    "gyro_offset": 0.2,
    "heading": 0.5,
}
# What drive shows each parameter.
DRIVES = {
    "left_radius": "drive some distance and turn (one wheel apart from the other)",
    "right_radius": "drive some distance and turn (one wheel apart from the other)",
    "track": "turn",
    "lever_x": "turn, in place or on arcs",
    "lever_y": "turn, in place or on arcs",
    "yaw": "drive straight as well as turn",
    "offset": "change speed and turn rate",
    "gyro_scale": "turn a good deal, both ways",
    "gyro_bias": "drive for longer, or stand still",
    "gyro_offset": "change the turn rate",
    "heading": "drive some distance",
}
LEAST_READINGS = 20
# The chi-square per degree of freedom past which the noise identified does not describe a log.
MISFIT = 1.5
# s kept off each end of the wheels' span (and of the gyro's): room for a clock offset.
CLOCK_MARGIN = 1.0
_FLAT = 1e-9  # a direction of the scaled information below this is not seen at all


@dataclass(frozen=True, eq=False)
class ReferenceCalibration:
    """``calibrate_to_reference``'s result: the calibrated ``robot``, the ``estimated``
    parameter names, all ``values`` ``(11,)`` over ``PARAMETERS`` (those not estimated at
    what was given), the ``covariance`` ``(E, E)`` of the estimated ones (inflated where
    ``chi2`` > 1) and the ``information`` ``(E, E)`` under the noise stated, ``chi2`` (the
    residuals' chi-square per degree of freedom under that noise), the ``readings`` used and
    the ``report``'s lines."""

    robot: DiffDrive
    estimated: tuple[str, ...]
    values: np.ndarray
    covariance: np.ndarray
    information: np.ndarray
    chi2: float
    readings: int
    report: tuple[str, ...]
    noise: IdentifiedNoise | None = None

    def value(self, name: str) -> float:
        """One parameter's value, in its unit (``UNITS``)."""
        return float(self.values[PARAMETERS.index(name)])

    def standard_errors(self) -> dict[str, float]:
        """Each estimated parameter's standard error, in its unit."""
        spread = np.sqrt(np.diag(self.covariance))
        return {name: float(error) for name, error in zip(self.estimated, spread, strict=True)}

    @property
    def correlation(self) -> np.ndarray:
        """The estimated parameters' correlation matrix ``(E, E)``."""
        spread = np.sqrt(np.diag(self.covariance))
        return self.covariance / np.outer(spread, spread)

    def estimator_settings(
        self, robot: DiffDrive, given: EstimatorSettings | None = None
    ) -> EstimatorSettings:
        """``given`` (default ``EstimatorSettings()``) started from this calibration, for an
        estimator that runs with ``robot`` (``self.robot``, or the geometry it was started
        from): the wheels' ``distance_scale`` and ``turn_scale``, the calibrated geometry's
        against ``robot``'s (1 for ``self.robot``), each a ``Prior`` whose spread is its
        standard error; the gyro's ``bias``; and ``sensors``, a ``SensorCalibration`` of the
        gyro's clock and scale and the reference sensor's clock, lever arm and yaw. What the
        calibration did not estimate is left as ``given`` has it; the GPS frame's ``heading``
        belongs to the start, not the settings (an ``initial_pose``). ``ValueError`` where
        ``robot``'s wheels differ left from right otherwise than the calibration's by more
        than two standard errors: scales carry no such difference (run with ``self.robot``)."""
        given = settings_of(given, EstimatorSettings)
        full = np.zeros((len(PARAMETERS), len(PARAMETERS)))
        at = [PARAMETERS.index(name) for name in self.estimated]
        full[np.ix_(at, at)] = self.covariance
        left, right, track = self.values[:3]
        ours = geometry_of(robot)[:3]

        def spread(gradient: dict[str, float]) -> float:
            g = np.zeros(len(PARAMETERS))
            for name, value in gradient.items():
                g[PARAMETERS.index(name)] = value
            return float(np.sqrt(g @ full @ g))

        ratio = (right / left) / (ours[1] / ours[0])
        error = spread({"left_radius": -ratio / left, "right_radius": ratio / right})
        if abs(ratio - 1.0) > 2.0 * error:
            raise ValueError(
                f"the calibrated wheels differ right from left by {ratio - 1.0:+.3%} against "
                f"the robot's (+- {error:.2%}), which the estimator's scales cannot carry: run "
                "it with the calibration's robot"
            )
        mean = ours[0] + ours[1]
        distance = (left + right) / mean
        turn = ((left + right) / track) / (mean / ours[2])
        by_radius = turn / (left + right)
        changes: dict[str, object] = {
            "distance_scale": Prior(
                distance, spread({"left_radius": 1.0 / mean, "right_radius": 1.0 / mean})
            ),
            "turn_scale": Prior(
                turn,
                spread(
                    {"left_radius": by_radius, "right_radius": by_radius, "track": -turn / track}
                ),
            ),
        }
        estimated = set(self.estimated)
        scale = self.value("gyro_scale") if "gyro_scale" in estimated else 0.0
        if "gyro_bias" in estimated:
            changes["bias"] = self.value("gyro_bias") / (1.0 + scale)  # on the wheels' scale
        # SensorCalibration's fields are the parameters' own names.
        found: dict[str, Any] = {
            name: self.value(name) for name in ("gyro_offset", "offset", "yaw") if name in estimated
        }
        if "gyro_scale" in estimated:
            found["gyro_scale"] = scale
        if {"lever_x", "lever_y"} & estimated:
            found["lever_arm"] = (self.value("lever_x"), self.value("lever_y"))
        changes["sensors"] = dataclasses.replace(given.sensors, **found)
        return given.replace(**changes)


def _checked(times, increments, stamps, reference, sigma, gyro, least=LEAST_READINGS) -> tuple:
    """The arrays as floats, the wheels within the gyro's span and the readings within the
    wheels', ``CLOCK_MARGIN`` off each end, at least ``least`` of them; ``ValueError`` for
    what no fit can use."""
    times = np.asarray(times, dtype=float)
    increments = np.asarray(increments, dtype=float)
    stamps = np.asarray(stamps, dtype=float)
    readings = np.asarray(reference, dtype=float)
    if increments.ndim != 2 or increments.shape[1] != 2 or len(times) != len(increments) + 1:
        raise ValueError(
            f"increments must be (T, 2) rad with times (T+1,) s, got {increments.shape} and "
            f"{times.shape}"
        )
    if gyro is not None:
        kept = (times >= gyro.times[0] + CLOCK_MARGIN) & (times <= gyro.times[-1] - CLOCK_MARGIN)
        if np.count_nonzero(kept) < 2:
            raise ValueError(
                f"the clocks do not overlap: the gyro's stamps span [{gyro.times[0]:g}, "
                f"{gyro.times[-1]:g}] s and the wheels' [{times[0]:g}, {times[-1]:g}] s; are "
                "they on the same clock, in the same unit?"
            )
        first, last = np.flatnonzero(kept)[[0, -1]]
        times, increments = times[first : last + 1], increments[first:last]
    if readings.ndim == 2 and readings.shape[1] == 3 and np.all(np.isnan(readings[:, 2])):
        readings = readings[:, :2]  # a position sensor's, headings NaN
    if readings.ndim != 2 or readings.shape[1] not in (2, 3) or len(stamps) != len(readings):
        raise ValueError(
            "the reference must be (K, 3) poses or (K, 2) positions with stamps (K,), got "
            f"{readings.shape} and {stamps.shape}"
        )
    for name, values in (("times", times), ("stamps", stamps)):
        if not np.all(np.isfinite(values)) or np.any(np.diff(values) <= 0):
            raise ValueError(f"{name} must be finite and increasing")
    if not np.all(np.isfinite(increments)) or not np.all(np.isfinite(readings)):
        raise ValueError("the increments and the reference's readings must be finite")
    if not np.any((stamps >= times[0]) & (stamps <= times[-1])):
        raise ValueError(
            f"the clocks do not overlap: the reference's stamps span [{stamps[0]:g}, "
            f"{stamps[-1]:g}] s and the wheels' [{times[0]:g}, {times[-1]:g}] s; are they on "
            "the same clock, in the same unit?"
        )
    inside = (stamps >= times[0] + CLOCK_MARGIN) & (stamps <= times[-1] - CLOCK_MARGIN)
    if np.count_nonzero(inside) < least:
        raise ValueError(
            f"too short a log: {np.count_nonzero(inside)} reference readings inside the wheels' "
            f"span ({CLOCK_MARGIN:g} s off its ends, room for the clocks' offsets), at least "
            f"{least} needed: record a longer drive"
        )
    stamps, readings = stamps[inside], readings[inside]
    if readings.shape[1] == 3:
        readings = np.column_stack([readings[:, :2], np.unwrap(readings[:, 2])])
    sigma = np.atleast_1d(np.asarray(sigma, dtype=float))
    wanted = 3 if readings.shape[1] == 3 else 1
    if sigma.shape != (wanted,) or not np.all(np.isfinite(sigma)) or not np.all(sigma > 0):
        what = "(x m, y m, theta rad)" if wanted == 3 else "one position noise (m)"
        raise ValueError(f"sigma must be {what}, each > 0, got {sigma!r}")
    sigma = sigma if wanted == 3 else np.array([sigma[0], sigma[0], 0.0])
    spread = float(np.hypot(np.ptp(readings[:, 0]), np.ptp(readings[:, 1])))
    turned = float(np.ptp(readings[:, 2])) if wanted == 3 else 0.0
    if spread < 10 * sigma[0] and turned < 10 * sigma[2]:
        turns = f" and turn through {turned:.3g} rad" if wanted == 3 else ""
        noise = f" and {sigma[2]:.3g} rad" if wanted == 3 else ""
        raise ValueError(
            f"the reference hardly moves: its readings span {spread:.3g} m{turns}, against "
            f"their noise of {sigma[0]:.3g} m{noise}; drive some distance"
        )
    return times, increments, stamps, readings, sigma, spread


class UndeterminedError(ValueError):
    """A calibration refused because the log did not determine ``parameters`` (the message
    says why and what drive would); leaving them out of ``estimate`` may let the rest go. Where
    the noise was identified, ``noise`` is what was found (``IdentifiedNoise``): a good start
    for the next try's figures."""

    def __init__(
        self, message: str, parameters: tuple[str, ...], noise: IdentifiedNoise | None = None
    ) -> None:
        super().__init__(message)
        self.parameters = parameters
        self.noise = noise


def estimable(poses: bool, gyro: bool) -> tuple[str, ...]:
    """What a reference of poses (else positions), with or without a gyro, can calibrate
    (``calibrate_to_reference``'s default ``estimate``)."""
    names = ["left_radius", "right_radius", "track", "lever_x", "lever_y"]
    names += ["yaw", "offset"] if poses else ["offset"]
    if gyro:
        names += ["gyro_scale", "gyro_bias", "gyro_offset"]
    if not poses:
        names.append("heading")
    return tuple(names)


@dataclass(frozen=True)
class ReferenceSettings:
    """How ``calibrate_to_reference`` fits: the parameters it ``estimate``s (names of
    ``PARAMETERS``; None, the default: all the reference can show, see the module), the
    ``initial`` values of the others (the robot's geometry, 0 elsewhere, by default), the
    odometry's integration ``method``, at most ``iterations`` Gauss-Newton steps, and
    ``identify_noise``: True, or some of ``NOISES``, finds the wheels', the gyro's and the
    reference's noise from the log itself (``_reference_noise``), the figures given its start
    and the others held (False, the default: as given)."""

    estimate: tuple[str, ...] | None = None
    initial: dict[str, float] | None = None
    method: Method = "exact"
    iterations: int = 30
    identify_noise: bool | tuple[str, ...] = False

    def __post_init__(self) -> None:
        if self.estimate is not None:
            if isinstance(self.estimate, str) or not all(
                isinstance(name, str) for name in self.estimate
            ):
                raise TypeError(
                    f"ReferenceSettings.estimate must be names of PARAMETERS, got {self.estimate!r}"
                )
            object.__setattr__(self, "estimate", tuple(self.estimate))
        for name, value in (self.initial or {}).items():
            if name not in PARAMETERS:
                raise ValueError(
                    f"ReferenceSettings.initial names {name!r}, not one of {', '.join(PARAMETERS)}"
                )
            finite(f"ReferenceSettings.initial {name}", value)
        check_method(self.method)
        object.__setattr__(
            self, "iterations", whole("ReferenceSettings.iterations", self.iterations, 1)
        )
        _noise_terms(self.identify_noise)


def calibrate_to_reference(
    robot: DiffDrive,
    times: object,
    increments: object,
    stamps: object,
    reference: object,
    *,
    sigma: object,
    gyro: Gyro | list[Gyro] | None = None,
    gyro_noise: GyroNoise | None = None,
    wheel_noise: object = DEFAULT,
    settings: ReferenceSettings | None = None,
) -> ReferenceCalibration:
    """``robot`` calibrated against a reference: wheel-angle ``increments`` ``(T, 2)`` rad over
    ``times`` ``(T+1,)`` s; the reference's readings stamped ``stamps`` ``(K,)`` s on its own
    clock, poses ``(K, 3)`` (its sensor's ``x, y, theta``) with noise ``sigma`` (m, m, rad),
    or positions ``(K, 2)`` (or headings NaN) with noise ``sigma`` (m); a ``gyro`` (on its own
    clock) with ``gyro_noise``'s angle random walk; the wheels' ``wheel_noise``. ``settings``:
    what is fitted and how (``ReferenceSettings``; by default every parameter the reference can
    show, from the robot's geometry, the noise as given). ``ValueError`` for a log no fit can
    use, and ``UndeterminedError`` (a ``ValueError``) for parameters the drive did not
    determine, naming them and the drive that would. Several runs of poses calibrate together:
    ``times``, ``increments``, ``stamps``, ``reference`` (and ``gyro``) as lists, one item a
    run, the parameters shared. With ``settings.identify_noise``, the result's ``noise``."""
    settings = settings_of(settings, ReferenceSettings)
    estimate, initial, method = settings.estimate, settings.initial, settings.method
    iterations, identify_noise = settings.iterations, settings.identify_noise
    runs = _runs_of(times, increments, stamps, reference, gyro)
    # Several runs need a stretch each and the readings of one log between them.
    least = LEAST_READINGS if len(runs) == 1 else 2
    checked = [_checked(t, i, k, r, sigma, g, least) for t, i, k, r, g in runs]
    if sum(len(c[2]) for c in checked) < LEAST_READINGS:
        raise ValueError(
            f"too short a log: {sum(len(c[2]) for c in checked)} reference readings inside "
            f"the runs' spans ({CLOCK_MARGIN:g} s off their ends), at least {LEAST_READINGS} "
            "needed: record longer drives"
        )
    poses = checked[0][3].shape[1] == 3
    if len({c[3].shape[1] for c in checked}) > 1 or (len(runs) > 1 and not poses):
        raise ValueError(
            "several runs are calibrated together against poses only: GPS positions need "
            "each run's own frame heading; calibrate one log at a time"
        )
    gyros = [run[4] for run in runs]
    if len({g is None for g in gyros}) > 1:
        raise ValueError("give every run a gyro, or none")
    with_gyro = gyros[0] is not None
    for number, (run, gyro_of_run) in enumerate(zip(checked, gyros, strict=True), 1):
        if gyro_of_run is not None:
            _refuse_a_gyro_against_the_wheels(robot, run[0], run[1], gyro_of_run, number, len(runs))
    allowed = estimable(poses, with_gyro)
    estimate = allowed if estimate is None else tuple(estimate)
    refused = [name for name in estimate if name not in allowed]
    if refused or not estimate:
        raise ValueError(
            f"estimate must name some of {', '.join(allowed)} for this reference"
            f"{' and gyro' if with_gyro else ''}, got {estimate!r}"
        )
    if with_gyro and gyro_noise is None:
        raise ValueError("a gyro needs its noise: gyro_noise=GyroNoise(angle_random_walk=...)")
    wheels = WheelNoise.coerce(wheel_noise)
    arw = 0.0 if gyro_noise is None else gyro_noise.angle_random_walk
    logs = [
        Log(robot, t, i, k, r, noise, wheels, g, arw, method)
        for (t, i, k, r, noise, _), g in zip(checked, gyros, strict=True)
    ]
    spread = max(c[5] for c in checked)
    readings = np.concatenate([c[3] for c in checked])
    values = np.zeros(len(PARAMETERS))
    values[:3] = geometry_of(robot)[:3]
    for name, value in (initial or {}).items():
        values[PARAMETERS.index(name)] = float(value)
    if not poses and "heading" not in (initial or {}):
        values[PARAMETERS.index("heading")] = _heading_of(logs[0], values)
    fitted = np.array([name in estimate for name in PARAMETERS])
    noise = None
    terms = _noise_terms(identify_noise)
    try:
        if terms:
            logs, result, noise = identify(logs, values, fitted, iterations, terms)
        else:
            result = fit(logs, values, fitted, iterations)
    except DivergedError as diverged:
        if not initial:
            raise
        given = ", ".join(f"{name} {float(value):g}" for name, value in initial.items())
        raise DivergedError(
            f"the calibration did not converge from the initial values given ({given}): "
            f"{diverged.went}. Start nearer the robot's own (m, rad, s)",
            diverged.went,
        ) from None
    if len(logs) > 1:
        _refuse_a_run_that_fits_none(logs, values, fitted, iterations, result)
    values, covariance, information = result.values, result.covariance, result.information
    for name in ("offset", "gyro_offset"):
        if abs(values[PARAMETERS.index(name)]) > CLOCK_MARGIN:
            raise ValueError(
                f"{name} came out at {values[PARAMETERS.index(name)]:.3g} s, past the "
                f"{CLOCK_MARGIN:g} s the log's ends leave for it: are the clocks that far apart? "
                "Give initial={...} near it"
            )
    names = tuple(name for name in PARAMETERS if name in estimate)
    moved = f"the reference's readings span {spread:.3g} m"
    if poses:
        turned = max(float(np.ptp(c[3][:, 2])) for c in checked)
        moved += f" and turn through {turned:.3g} rad"
    try:
        report = _refuse_the_undetermined(names, values, covariance, information, moved)
    except UndeterminedError as undetermined:
        raise UndeterminedError(str(undetermined), undetermined.parameters, noise) from None
    if noise is not None:
        report += _noise_lines(noise)
        if result.chi2 > MISFIT:
            # REML settled, yet the fit's residuals are larger than the terms say: errors of
            # a shape no term has (a receiver's slow wander, slip that follows the turns).
            report += (
                f"the residuals' chi-square per degree of freedom is {result.chi2:.2f} under the "
                "noise identified: its terms do not describe this log's errors well (the "
                "standard errors are inflated by it); read the figures with care",
            )
    return ReferenceCalibration(
        robot.with_geometry(*values[:3]),
        names,
        values,
        covariance,
        information,
        result.chi2,
        len(readings),
        report,
        noise,
    )


_NOISE_NAMES = {
    "wheels": ("the wheels' k", "m", ".2g"),
    "gyro": ("the gyro's angle random walk", "rad/s/sqrt(Hz)", ".2g"),
    "reference": ("the reference's position noise", "m", ".3g"),
    "reference_heading": ("the reference's heading noise", "rad", ".3g"),
}


# The gyro's turn per the wheels' (nominal geometry) outside which it is not this robot's
# gyro as read: reversed (below 0), no turn seen (a wrong axis), or degrees for radians (57).
GYRO_SLOPE = (0.05, 20.0)


def _refuse_a_gyro_against_the_wheels(robot, times, increments, gyro, run: int, runs: int):
    """``ValueError`` where the gyro's turn over the run is not the wheels' (nominal
    geometry) within ``GYRO_SLOPE``: a fit from there goes anywhere (a clock offset of tens
    of seconds, say) and its refusal would name the wrong cause."""
    wheel_turn = np.concatenate([[0.0], np.cumsum(batch.to_twist(robot, increments)[:, 2])])
    inside = (times >= gyro.times[0]) & (times <= gyro.times[-1])
    if np.count_nonzero(inside) < 2 or np.ptp(wheel_turn[inside]) < 1.0:
        return  # too little turn to tell (the fit's own refusals speak there)
    gyro_turn = gyro.angles(times[inside])
    wheel = wheel_turn[inside] - wheel_turn[inside][0]
    wheel, gyro_turn = wheel - wheel.mean(), gyro_turn - gyro_turn.mean()
    # The bias drifts the gyro's angle: fit it as a ramp beside the turn.
    ramp = times[inside] - times[inside].mean()
    (slope, _), *_ = np.linalg.lstsq(np.column_stack([wheel, ramp]), gyro_turn, rcond=None)
    if GYRO_SLOPE[0] <= slope <= GYRO_SLOPE[1]:
        return
    which = f"run {run} of {runs}: " if runs > 1 else ""
    cause = (
        "it turns the other way: its z axis points down or its sign is reversed (a mounting "
        "turned over, --imu-mount 3.1415927 0 0)"
        if slope < 0
        else "it sees almost none of the turn: the wrong axis (the IMU's mounting)"
        if slope < GYRO_SLOPE[0]
        else "degrees per second read as radians?"
    )
    raise ValueError(
        f"{which}the gyro turns {slope:.3g} times as far as the wheels say the robot did "
        f"(nominal geometry): {cause}"
    )


def _refuse_a_run_that_fits_none(logs, values, fitted, iterations: int, result) -> None:
    """``ValueError`` naming a run that, fitted alone, still misfits (chi-square per degree of
    freedom past ``MISFIT`` and 10 times the best run's alone): a reference of another drive,
    or a clock or unit of its own. Looked at only where the runs together misfit; it would
    otherwise show as parameters the drive left undetermined, or pull the others' fit."""
    if result.chi2 <= MISFIT:
        return
    alone = []
    for log in logs:
        try:
            alone.append(fit([log], values, fitted, iterations).chi2)
        except ValueError:  # diverged alone: as misfit as a run can be
            alone.append(np.inf)
    worst, best = int(np.argmax(alone)), min(alone)
    if alone[worst] > MISFIT and alone[worst] > 10 * best:
        misfit = (
            "its fit alone diverges"
            if np.isinf(alone[worst])
            else f"its residuals' chi-square per degree of freedom alone is {alone[worst]:.3g}"
        )
        raise ValueError(
            f"run {worst + 1} of {len(logs)} does not fit, even alone: {misfit}, the best "
            f"run's {best:.3g} (together {result.chi2:.3g}). Is its reference from another "
            "drive, or on a clock or in units of its own? Calibrate without it"
        )


def _noise_terms(identify_noise: object) -> tuple[str, ...]:
    """The noise terms to identify: all for True, none for False or an empty sequence, or
    those named."""
    if isinstance(identify_noise, bool):
        return NOISES if identify_noise else ()
    terms = tuple(identify_noise) if isinstance(identify_noise, list | tuple) else (None,)
    if any(term not in NOISES for term in terms):
        raise ValueError(
            f"identify_noise must be True, False or some of {', '.join(NOISES)}, got "
            f"{identify_noise!r}"
        )
    return terms


def _noise_lines(noise: IdentifiedNoise) -> tuple[str, ...]:
    """The report's lines for the noise identified: each term, and whether the log set it."""
    lines = []
    for name, value in noise.values.items():
        what, unit, form = _NOISE_NAMES[name]
        found = f"{what} {value:{form}} +- {noise.standard_errors[name]:.2g} {unit}"
        if name in noise.undetermined:
            found += (
                f": not determined by this log (its variance to no better than "
                f"{100 * UNDETERMINED:.0f} %), only weighs the fit"
            )
        lines.append(found + ("" if name in noise.undetermined else ", identified from the log"))
    return tuple(lines)


def _runs_of(times, increments, stamps, reference, gyro) -> list[tuple[Any, ...]]:
    """One log, or several as lists one item a run: ``(times, increments, stamps,
    reference, gyro)`` each."""
    if not isinstance(times, list | tuple):
        return [(times, increments, stamps, reference, gyro)]
    if not times:
        raise ValueError("calibrate_to_reference needs a log, got an empty list of runs")
    gyros = gyro if isinstance(gyro, list | tuple) else [gyro] * len(times)
    try:
        return list(zip(times, increments, stamps, reference, gyros, strict=True))
    except (TypeError, ValueError):
        raise ValueError(
            "several runs: times, increments, stamps and reference (and a gyro's list) must be "
            "lists of one length, an item a run"
        ) from None


def _heading_of(log: Log, values: np.ndarray) -> float:
    """The reference frame's heading in the odometry's that best lays the predicted antenna
    path onto the readings (a rotation by complex least squares)."""
    antenna = antenna_positions(log, values)
    predicted = antenna[:, 0] + 1j * antenna[:, 1]
    seen = log.readings[:, 0] + 1j * log.readings[:, 1]
    predicted, seen = predicted - predicted.mean(), seen - seen.mean()
    return float(np.angle(np.sum(np.conj(predicted) * seen)))


def _refuse_the_undetermined(names, values, covariance, information, moved) -> tuple[str, ...]:
    """``ValueError`` naming a combination the drive did not show, or a parameter whose
    standard error passes its limit; else the report's lines."""
    scale = np.sqrt(np.maximum(np.diag(information), 1e-300))
    eigenvalues, vectors = np.linalg.eigh(information / np.outer(scale, scale))
    weights = vectors[:, 0]  # the combination the log sees least
    parts = [names[i] for i in np.argsort(-np.abs(weights)) if abs(weights[i]) > 0.3]
    drives = "; ".join(f"{DRIVES[name]} ({name})" for name in parts)
    if eigenvalues[0] < _FLAT * max(1.0, eigenvalues[-1]):
        raise UndeterminedError(
            f"this log cannot tell {' from '.join(parts)} apart ({moved}): they move its "
            f"readings alike. To determine them: {drives}; or leave them out of estimate",
            tuple(parts),
        )
    errors = np.sqrt(np.diag(covariance))
    lines, undetermined, loose = [], [], []
    for name, error in zip(names, errors, strict=True):
        index = PARAMETERS.index(name)
        value, unit = values[index], UNITS[index]
        relative = name in RELATIVE
        size = error / value if relative else error
        if size > LIMITS[name]:
            shown = "of its value" if relative else unit
            undetermined.append(f"{name} (standard error {size:.3g} {shown}): {DRIVES[name]}")
            loose.append(name)
        elif relative:
            lines.append(f"{name} {value:.6g} m, known to {100 * size:.2g} %")
        else:
            shown = f" {unit}" if unit else ""
            lines.append(f"{name} {value:.4g}{shown} +- {error:.2g}{shown}")
    if undetermined:
        raise UndeterminedError(
            f"this log does not determine {'; '.join(undetermined)} ({moved}). The "
            f"combination it sees least is of {', '.join(parts)}: to determine it, {drives}; "
            "or leave them out of estimate",
            tuple(loose),
        )
    return tuple(lines)
