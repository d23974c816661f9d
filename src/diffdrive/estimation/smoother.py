"""A whole log through ``PoseEstimator``, then a fixed-interval smoother.

``estimate_trajectory`` runs the log forward (wheel increments, a ``Gyro`` with its own
stamps, absolute measurements applied at their stamps) and, with ``smooth``, back again:
the Rauch-Tung-Striebel smoother (Rauch, Tung and Striebel, AIAA Journal 3(8), 1965) on the
filter's linearisation, the state before each interval moved by the gain ``C`` times the
smoothed correction after it (``diffdrive.estimation.filter.Step``). Every estimate then uses
every measurement, before and after it.

With a gyro, the whole log also finds slip episodes the per-interval test misses
(``diffdrive.estimation.episodes``) and runs forward again with them flagged as slipping.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from diffdrive._validate import increasing, settings_of
from diffdrive.backends.settings import LogArrays, PassArrays
from diffdrive.encoders import wheel_quantum
from diffdrive.estimation import filter as ekf
from diffdrive.estimation.episodes import steady_episodes
from diffdrive.estimation.fixes import IDENTIFIED_GATE, identify_fixes
from diffdrive.estimation.fusion import PoseEstimator, body_covariances, body_poses
from diffdrive.estimation.imu import Gyro
from diffdrive.estimation.measurements import MEASUREMENT_KINDS, Measurement
from diffdrive.estimation.settings import EstimatorSettings, Gate, SensorCalibration, Window
from diffdrive.estimation.standing import identify_standing
from diffdrive.estimation.twists import interval_twists
from diffdrive.estimation.wheel_turns import identify_wheel_turns
from diffdrive.model import Robot
from diffdrive.sensor_noise import WheelNoise

# measurements as the cores take them: stamps, kinds, values, covariances, lever arms
_Packed = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]

__all__ = ["Estimate", "estimate_trajectory"]


@dataclass(frozen=True, eq=False)
class Estimate:
    """``estimate_trajectory``'s result at the wheel stamps ``times`` ``(N,)``: the body's
    ``poses`` ``(N, 3)`` and ``covariances`` ``(N, 3, 3)``, the filter's ``states`` ``(N, 8)``
    (``x, y, theta, bias, turn_scale, distance_scale, offset_x, offset_y`` of the reference
    point: ``diffdrive.estimation.filter``) and ``state_covariances`` ``(N, 8, 8)``; per row the
    ``slip`` flag and ``slip_score`` of the interval ending there; the ``measurements`` in stamp
    order with ``accepted`` ``(M,)``, ``scores`` ``(M,)`` (the squared Mahalanobis distance in
    the forward pass) and ``log_dets`` ``(M,)`` (the log determinant of each innovation's
    covariance; see ``log_likelihood``); ``smoothed`` says which pass it is;
    ``twists`` ``(N, 3)`` ``[vx, vy, omega]`` and ``twist_covariances`` ``(N, 3, 3)``: the body
    twist over the interval ending at each row (row 0: the first interval's) and its
    covariance, from the wheels and the heading source with the estimated bias or turn scale
    (``diffdrive.estimation.twists``); with ``records``, the smoother's record of every step
    (``filter.SmootherRecords``), else None; ``settings``: what the gyro's noise and bias
    were, and the fixes' with ``WholeLog(fixes="identified")``, and where from (given, or
    identified from the log's standing stretches and from the fixes themselves); ``used``: the
    ``EstimatorSettings`` the pass ran with, what the log identified filled in, and the
    ``window`` as given (the pass's own keeps the whole log): a streaming ``PoseEstimator``
    starts from it with a bounded history."""

    times: np.ndarray
    poses: np.ndarray
    covariances: np.ndarray
    states: np.ndarray
    state_covariances: np.ndarray
    slip: np.ndarray
    slip_score: np.ndarray
    measurements: tuple[Measurement, ...]
    accepted: np.ndarray
    scores: np.ndarray
    smoothed: bool
    heading: str
    twists: np.ndarray
    twist_covariances: np.ndarray
    records: ekf.SmootherRecords | None = None
    settings: tuple[str, ...] = ()
    log_dets: np.ndarray | None = None
    used: EstimatorSettings | None = None

    @property
    def rejected(self) -> int:
        """How many measurements the gate refused."""
        return int(np.count_nonzero(~self.accepted))

    @property
    def log_likelihood(self) -> float:
        """The Gaussian log likelihood of the measurements' innovations in the forward pass,
        each against the covariance the filter predicted for it (the ones the gate refused
        count too, with the innovation they had): how well the noise settings explain the
        measurements, for comparing settings on one log."""
        if self.log_dets is None or not len(self.measurements):
            return 0.0
        sizes = np.array([len(m.value) for m in self.measurements])
        terms = self.scores + self.log_dets + sizes * np.log(2.0 * np.pi)
        return float(-0.5 * np.sum(terms[np.isfinite(terms)]))


def checked_log(
    times: object, increments: object, gyro: Gyro | None, commanded: object
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """A whole log's ``times`` ``(N,)``, ``increments`` ``(N-1, 2)``, the ``gyro``'s turn over
    each interval ``(N-1,)`` (None without one) and ``commanded`` ``(N-1, 2)`` (or None), as
    float arrays; ``ValueError`` or ``TypeError`` naming what is wrong."""
    times = np.asarray(times, dtype=float)
    increments = np.asarray(increments, dtype=float)
    if times.ndim != 1 or len(times) < 2:
        raise ValueError(f"times must be (N,) s with N >= 2, got shape {times.shape}")
    increasing("times", times)
    if increments.shape != (len(times) - 1, 2):
        raise ValueError(
            f"increments must be (N-1, 2) for {len(times)} times, got {increments.shape}"
        )
    if gyro is not None and not isinstance(gyro, Gyro):
        raise TypeError(f"gyro must be a Gyro (Gyro, Gyro.from_imu), got {type(gyro).__name__}")
    turned = None if gyro is None else np.diff(gyro.angles(times))
    wanted = None if commanded is None else np.asarray(commanded, dtype=float)
    if wanted is not None and wanted.shape != increments.shape:
        raise ValueError(f"commanded must be {increments.shape}, got {wanted.shape}")
    return times, increments, turned, wanted


def estimate_trajectory(
    robot: Robot,
    times: object,
    increments: object,
    *,
    gyro: Gyro | None = None,
    measurements: Iterable[Measurement] = (),
    commanded: object = None,
    settings: EstimatorSettings | None = None,
    initial_pose: object = None,
    initial_covariance: object = None,
    smooth: bool = True,
) -> Estimate:
    """A whole log: wheel-angle ``increments`` ``(N-1, 2)`` rad between ``times`` ``(N,)`` s,
    the ``gyro`` (needed unless the heading is ``"wheels"``), absolute ``measurements``
    stamped inside ``[times[0], times[-1]]``, and ``commanded`` wheel velocities ``(N-1, 2)``
    rad/s if known. ``settings``: an ``EstimatorSettings`` (default ``EstimatorSettings()``),
    the whole log's part being ``settings.whole_log`` (its ``window`` is the streaming
    estimator's: a whole log keeps all of itself and waits for nothing). With ``smooth``,
    the smoothed estimate; else the filter's.

    Read from the log where ``settings`` leaves them None: the gyro's noise and bias, from
    its standing stretches (``standing.identify_standing``); with ``whole_log.fixes``
    ``"identified"``, what the ``"position"`` measurements (a GPS receiver's) are worth, from
    the fixes themselves (``diffdrive.estimation.fixes``): their white noise replaces their
    covariance, and unless given, the offset state wanders at the identified rate
    (``fix_offset``), the wheels' distance scale (``distance_scale``) and the start (in the
    fixes' frame: ``initial_pose``, ``initial_covariance``) are the dead reckoning's fit onto
    them, and the gate is ``1 - 1e-9`` with outliers inflated (a receiver's jumps are
    heavier-tailed than a Gaussian); it needs ``fixes.LEAST_FIXES`` fixes or more.
    ``Estimate.settings`` says what was used."""
    settings = settings_of(settings, EstimatorSettings)
    whole = settings.whole_log
    if settings.heading != "wheels" and gyro is None:
        raise ValueError(f"heading {settings.heading!r} needs a gyro")
    # The sensors' calibration is applied here, once: the estimator then runs without it.
    sensors = settings.sensors
    settings = settings.replace(sensors=SensorCalibration())
    times, increments, turned, wanted = calibrated_log(times, increments, gyro, commanded, sensors)
    given = list(measurements)
    for m in given:
        if not isinstance(m, Measurement):
            raise TypeError(
                f"measurements must be Measurements (Measurement.make, measurements_of), got "
                f"{type(m).__name__}"
            )
    given = [sensors.placed(m) for m in given]
    ordered = sorted(given, key=lambda m: m.order)
    moved = f" (moved by {-sensors.offset:g} s: SensorCalibration.offset)" if sensors.offset else ""
    for m in ordered:
        if not times[0] <= m.t <= times[-1]:
            raise ValueError(
                f"{m.kind} measurement at t = {m.t!r} s{moved} lies outside the log "
                f"[{times[0]:g}, {times[-1]:g}] s"
            )
    if whole.records and not smooth:
        raise ValueError("records are the smoother's, made on its pass back: give smooth=True")
    window = settings.window  # the streaming estimator's, given back in ``used``
    settings = settings.replace(window=Window(math.inf, 0.0))  # the whole log, no waiting
    settings, lines = _gyro_settings(times, increments, turned, gyro, settings)
    spread = np.zeros(len(increments))  # how far the gyro's samples leave each turn open
    if gyro is not None:
        spread = _on_wheels(gyro, sensors).interpolation_variances(times)
    settings, wheel_lines = _wheel_settings(robot, (times, increments, turned, spread), settings)
    lines += wheel_lines
    if sensors != SensorCalibration():
        lines += (_sensor_line(sensors),)
    _check_log(times, increments, turned, settings.encoders.max_wheel_speed)
    start: dict = {"initial_pose": initial_pose, "initial_covariance": initial_covariance}
    gyro_turns = np.full(len(increments), np.nan) if turned is None else turned
    if whole.fixes == "identified":
        ordered, settings, identified = _identified_fixes(
            robot, (times, increments, gyro_turns, spread), ordered, start, settings
        )
        lines += identified
    estimator = PoseEstimator(robot, settings, initial_time=float(times[0]), **start)
    missed = _commands_missed(estimator, times, increments, wanted)
    log = _Log(times, increments, gyro_turns, spread, missed, _packed(ordered))
    episodes = whole.slip_episodes and turned is not None
    records = whole.records
    run = _run(estimator, log, smooth and not episodes, None, records and not episodes)
    forced = None
    # Again with the episodes' wheel turns left out, and once more if what they had pulled
    # into the estimate (the bias, in a fused heading) moved the episodes found.
    for _ in range(2 if episodes else 0):
        found = _episodes(estimator.config, log, run)
        if forced is None and not np.any(found & ~run.out.slips[1:]):
            break
        if forced is not None and np.array_equal(found, forced):
            break
        forced = found
        run = _run(estimator, log, False, forced)
    if smooth and episodes:  # the smoother over the last forward pass
        run = _run(estimator, log, True, forced, records)
    twists, twist_covariances = _twists(robot, estimator.config, log, run)
    return Estimate(
        times,
        body_poses(run.out.states, robot),
        body_covariances(run.out.states, run.out.covariances, robot),
        run.out.states,
        run.out.covariances,
        run.out.slips,
        run.out.scores,
        tuple(ordered),
        run.out.accepted,
        run.out.distances,
        smooth,
        settings.heading,
        twists,
        twist_covariances,
        run.records,
        lines,
        run.out.log_dets,
        settings.replace(window=window, sensors=sensors),
    )


def _sensor_line(sensors: SensorCalibration) -> str:
    """What the settings' ``SensorCalibration`` moved, in words."""
    parts = [
        f"the gyro's clock {sensors.gyro_offset:g} s and scale {sensors.gyro_scale:g}",
        f"the measurements' clock {sensors.offset:g} s",
        f"a pose sensor's yaw {sensors.yaw:g} rad",
    ]
    if sensors.lever_arm is not None:
        parts.append(f"the lever arm ({sensors.lever_arm[0]:g}, {sensors.lever_arm[1]:g}) m")
    return "sensors, as given (SensorCalibration): " + ", ".join(parts)


def calibrated_log(
    times: object,
    increments: object,
    gyro: Gyro | None,
    commanded: object,
    sensors: SensorCalibration,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """``checked_log`` with the gyro moved onto the wheels' clock and scale by ``sensors``;
    a wheel log the moved gyro no longer covers is refused, naming the offset."""
    if gyro is None or not sensors.gyro_calibrated:
        return checked_log(times, increments, gyro, commanded)
    moved = _on_wheels(gyro, sensors)
    try:
        return checked_log(times, increments, moved, commanded)
    except ValueError as refused:
        if "the gyro only" not in str(refused):
            raise
        raise ValueError(
            f"{refused}, its stamps moved by {-sensors.gyro_offset:g} s onto the wheels' clock "
            "(SensorCalibration.gyro_offset): keep the wheel log inside that span"
        ) from None


def _on_wheels(gyro: Gyro, sensors: SensorCalibration) -> Gyro:
    """``gyro`` on the wheels' clock and scale (``SensorCalibration``'s gyro terms)."""
    if not sensors.gyro_calibrated:
        return gyro
    return gyro.calibrated(sensors.gyro_offset, sensors.gyro_scale)


def _identified_fixes(
    robot: Robot, wheels: tuple, ordered: list, start: dict, settings: EstimatorSettings
) -> tuple[list[Measurement], EstimatorSettings, tuple[str, ...]]:
    """The measurements with the fixes' identified white noise, ``start`` filled and
    ``settings`` completed from ``fixes.identify_fixes`` where not given, and the lines that
    say what was used. ``wheels``: the log's times, increments, gyro turns and their
    variances beyond the random walk's."""
    times, increments, turned, spread = wheels
    positions = [m for m in ordered if m.kind == "position"]
    # The dead reckoning the fixes are fitted onto: the same estimator without them.
    reckoner = PoseEstimator(robot, settings.replace(gate=None), initial_time=float(times[0]))
    empty = _packed([])
    still = np.zeros(len(increments), dtype=bool)
    dead = _run(reckoner, _Log(times, increments, turned, spread, still, empty), False, None)
    # The fixes' own covariance is not quoted: it may be a placeholder (fixes without one).
    fit = identify_fixes(
        times,
        body_poses(dead.out.states, robot),
        [m.t for m in positions],
        [m.value for m in positions],
    )
    lines = list(fit.report)
    found = fit.settings(settings)
    for name in ("fix_offset", "distance_scale", "initial_pose", "initial_covariance", "gate"):
        place = start if name.startswith("initial") else vars(settings)
        if place[name] is not None:
            lines.append(f"{name}: as given")
    start["initial_pose"] = (
        tuple(fit.start.tolist()) if start["initial_pose"] is None else start["initial_pose"]
    )
    if start["initial_covariance"] is None:
        start["initial_covariance"] = fit.start_covariance
    settings = found
    if settings.gating == Gate(IDENTIFIED_GATE, "inflate"):
        lines.append(
            f"gate 1 - {1 - IDENTIFIED_GATE:.0e}, past it inflated, not refused: a receiver's "
            "jumps are heavier-tailed than a Gaussian"
        )
    white = np.eye(2) * fit.white**2
    made = [
        dataclasses.replace(m, covariance=white) if m.kind == "position" else m for m in ordered
    ]
    return made, settings, tuple(lines)


def _gyro_settings(
    times, increments, turned, gyro, settings: EstimatorSettings
) -> tuple[EstimatorSettings, tuple[str, ...]]:
    """``settings`` with the gyro's noise and bias from the log's standing stretches where
    they were not given (``standing.identify_standing``); the lines that say what was used and
    where from."""
    if gyro is None:  # with the wheels' heading the gyro still tests for slip
        return settings, ()
    noise_given, bias_given = settings.gyro_noise is not None, settings.bias is not None
    if noise_given and bias_given:
        return settings, ("gyro noise and bias: as given",)
    fit = identify_standing(times, increments, turned, samples=(gyro.times, gyro.rates))
    if fit is None:
        return settings, (
            "no standing stretch of 0.5 s in the log (the wheels never stand still): the gyro "
            f"noise {'as given' if noise_given else 'is the default'} ({settings.gyro}), the "
            f"bias {'as given' if bias_given else 'starts at 0 rad/s'}",
        )
    report = list(fit.report)
    if noise_given:
        report = [report[0], "gyro noise: as given"]
    if bias_given:
        report[0] = "gyro bias: as given"
    return fit.settings(settings), tuple(report)


def _wheel_settings(
    robot: Robot, log: tuple, settings: EstimatorSettings
) -> tuple[EstimatorSettings, tuple[str, ...]]:
    """``settings`` with the encoders' counts from the step of the wheel angles where they
    were not given (``encoders.wheel_quantum``: the floor of the wheels' noise against a
    gyro) and the wheels' noise where it was not (``_wheels_against_gyro``); the lines that
    say what was used and where from. ``log``: the times, increments, the gyro's turns
    (None: no gyro) and their interpolation variances."""
    increments, turned = log[1], log[2]
    lines: tuple[str, ...] = ()
    encoders = settings.encoders
    step = None
    if turned is not None and encoders.ticks_per_revolution is None:
        step = wheel_quantum(increments)
    if step is not None:
        counts = 2.0 * math.pi / step
        settings = settings.replace(
            encoders=dataclasses.replace(encoders, ticks_per_revolution=counts)
        )
        lines = (
            f"wheel angles: whole steps of {step:.4g} rad ({counts:.6g} counts per "
            "revolution), each increment's rounding a floor of the wheels' noise against the "
            "gyro (Encoders.ticks_per_revolution to give it)",
        )
    if settings.wheel_noise is not None:
        return settings, lines
    noise, said = _wheels_against_gyro(robot, log, settings)
    return settings.replace(wheel_noise=noise), lines + said


def _wheels_against_gyro(
    robot: Robot, log: tuple, settings: EstimatorSettings
) -> tuple[WheelNoise, tuple[str, ...]]:
    """The wheels' noise from their turn against the gyro's (``identify_wheel_turns``), and
    the lines that say so; ``sensor_noise.DEFAULT`` where there is no gyro, too little
    driving, or a turn that differs from the gyro's by a scale, saying which."""
    times, increments, turned, spread = log

    def default(why: str) -> str:
        return (
            f"wheel noise: k = {settings.wheels.left:.3g} m on both wheels, the default ({why}; "
            "EstimatorSettings.wheel_noise to give it)"
        )

    if turned is None:
        return settings.wheels, (default("no gyro to tell it"),)
    arw = settings.gyro.angle_random_walk
    fit = identify_wheel_turns(robot, times, increments, turned, arw, spread)
    if fit is None:
        return settings.wheels, (default("too little driving to tell it"),)
    if fit.scaled:
        scaled = (
            f"the wheels turn {100 * fit.mismatch:+.1f} % (+- {100 * fit.mismatch_error:.1f}) "
            "against the gyro: a scale, not their noise (a track or radii not the robot's, or "
            "a skid-steer's turns; diffdrive calibrate-gyro finds the track)"
        )
        return settings.wheels, (scaled, default("their turn scaled against the gyro's"))
    if settings.encoders.wheel_floor == 0.0 and fit.noise.left < fit.k_error:
        # without counts nothing else keeps the wheels' turn from reading as exact
        held = (
            f"wheel noise: k held at its standard error, {fit.k_error:.2g} m: the fit is no "
            "more, and without the counts' rounding as a floor, 0 would read the wheels as exact"
        )
        return WheelNoise.symmetric(fit.k_error), (fit.report, held)
    return fit.noise, (fit.report,)


@dataclass(frozen=True)
class _Log:
    """A whole log as the cores take it: ``times`` ``(N,)``, ``increments`` ``(N-1, 2)``, the
    gyro's turns ``(N-1,)`` (NaN: none) and their variances beyond the random walk's
    (``Gyro.interpolation_variances``; 0: none), the intervals the commands flag ``(N-1,)`` and the
    measurements as arrays (``_packed``)."""

    times: np.ndarray
    increments: np.ndarray
    turned: np.ndarray
    gyro_variance: np.ndarray
    commanded: np.ndarray
    measurements: _Packed


@dataclass(frozen=True)
class _Run:
    """One pass of a core over a ``_Log`` (see ``EstimatorCore._run_log``): what it filled,
    ``covariances`` as ``(n, 8, 8)`` and the flags as booleans, and the smoother's
    ``records`` as ``SmootherRecords`` (None unless kept)."""

    out: PassArrays
    records: ekf.SmootherRecords | None


def _run(
    estimator: PoseEstimator,
    log: _Log,
    smooth: bool,
    forced: np.ndarray | None,
    records: bool = False,
) -> _Run:
    """A pass forward (and with ``smooth``, back) over ``log``, the intervals ``forced``
    ``(N-1,)`` flagged as slipping besides those the commands flag; with ``smooth`` and
    ``records``, the smoother's record of every step kept."""
    n, m = len(log.times), len(log.measurements[0])
    flagged = log.commanded if forced is None else log.commanded | forced
    states, covariances = np.empty((n, ekf.N)), np.empty((n, ekf.N * ekf.N))
    slips, scores, accepted = np.empty(n), np.empty(n), np.empty(m)
    distances, log_dets = np.empty(m), np.empty(m)
    steps = ekf.record_steps(log.times, log.measurements[0]) if smooth and records else None
    rows = None if steps is None else np.empty((int(steps.sum()), ekf.RECORD_WIDTH))
    # the cores read contiguous float64 (a caller's times may be a strided view)
    arrays = LogArrays(
        np.ascontiguousarray(log.times, dtype=float),
        np.ascontiguousarray(log.increments[:, 0], dtype=float),
        np.ascontiguousarray(log.increments[:, 1], dtype=float),
        np.ascontiguousarray(log.turned, dtype=float),
        np.ascontiguousarray(log.gyro_variance, dtype=float),
        flagged.astype(float),
        *log.measurements,
    )
    out = PassArrays(states, covariances, slips, scores, accepted, distances, log_dets, rows)
    failed = estimator._run_log(arrays, out, smooth)
    if failed == -2:
        raise ValueError(
            f"a measurement at the log's start ({log.times[0]:g} s) would overflow the state; "
            "refused"
        )
    if failed >= 0:
        where = f"interval {failed} ({log.times[failed]:g} to {log.times[failed + 1]:g} s)"
        raise ValueError(f"{where}: the update would overflow the state; refused")
    return _Run(
        out._replace(
            covariances=covariances.reshape(n, ekf.N, ekf.N),
            slips=slips.astype(bool),
            accepted=accepted.astype(bool),
        ),
        None
        if rows is None or steps is None
        else ekf.SmootherRecords.from_rows(np.repeat(np.arange(1, n), steps), rows),
    )


def _packed(ordered: list[Measurement]) -> _Packed:
    """The measurements (in ``Measurement.order``) as the cores' arrays: stamps ``(M,)``,
    kinds ``(M,)``, values ``(M, 3)``, covariances ``(M, 9)`` (the ``k x k`` first, row by
    row) and lever arms ``(M, 2)``."""
    m = len(ordered)
    stamps, kinds = np.empty(m), np.empty(m)
    values, covariances, arms = np.zeros((m, 3)), np.zeros((m, 9)), np.zeros((m, 2))
    for j, measurement in enumerate(ordered):
        k = len(measurement.value)
        stamps[j], kinds[j] = measurement.t, MEASUREMENT_KINDS.index(measurement.kind)
        values[j, :k] = measurement.value
        covariances[j, : k * k] = measurement.covariance.ravel()
        arms[j] = measurement.lever_arm
    return stamps, kinds, values, covariances, arms


def _check_log(times, increments, turned, max_wheel_speed) -> None:
    """What ``Odometry`` and ``PoseEstimator`` refuse in a reading, refused for the whole log
    before it runs, naming the first bad interval."""
    dt = np.diff(times)
    with np.errstate(over="ignore", invalid="ignore"):
        speed = np.abs(increments).max(axis=1) / dt
    limit = np.inf if max_wheel_speed is None else float(max_wheel_speed)
    problems = (
        (~np.all(np.isfinite(increments), axis=1), "the wheel increments must be finite"),
        (~np.isfinite(speed), "a wheel turns faster than the largest float"),
        (speed > limit, f"a wheel turns over max_wheel_speed {limit!r} rad/s"),
        (
            np.zeros(len(dt), dtype=bool) if turned is None else ~np.isfinite(turned),
            "the gyro's turn must be finite",
        ),
    )
    for bad, what in problems:
        if np.any(bad):
            k = int(np.argmax(bad))
            where = f"interval {k} ({times[k]:g} to {times[k + 1]:g} s)"
            rates = increments[k] / dt[k]
            raise ValueError(
                f"{where}: {what}: wheel increments {increments[k].tolist()} rad "
                f"({rates.tolist()} rad/s)"
            )


def _commands_missed(estimator: PoseEstimator, times, increments, wanted) -> np.ndarray:
    """The intervals whose wheels missed their commanded velocities ``wanted`` ``(N-1, 2)``
    rad/s beyond ``COMMAND_THRESHOLD`` (chi-square, two degrees of freedom, at the
    estimator's ``command_sigma``); none if ``wanted`` is None."""
    if wanted is None:
        return np.zeros(len(increments), dtype=bool)
    miss = increments / np.diff(times)[:, None] - wanted
    sigma = estimator.config.command_sigma
    sigma2 = sigma * sigma
    return (miss * miss).sum(axis=1) / sigma2 > ekf.COMMAND_THRESHOLD


def _twists(robot: Robot, c: ekf.Config, log: _Log, run: _Run):
    """The body twist over each interval and its covariance (``interval_twists``): the
    wheels' turn times the estimated turn scale, or the gyro's turn less the estimated bias,
    each interval's wheel noise inflated as the filter inflated it."""
    states, covariances = run.out.states, run.out.covariances
    inflation = np.where(run.out.slips[1:], c.slip_inflation, 1.0)
    if c.heading == "wheels":
        return interval_twists(
            robot,
            log.times,
            log.increments,
            c.k,
            turn_scale=states[1:, ekf.SCALE],
            turn_scale_variances=covariances[1:, ekf.SCALE, ekf.SCALE],
            noise_scale=inflation,
            wheel_floor=c.wheel_floor,
        )
    dt = np.diff(log.times)
    return interval_twists(
        robot,
        log.times,
        log.increments,
        c.k,
        turns=log.turned - states[1:, ekf.BIAS] * dt,
        turn_variances=c.arw2 * dt
        + log.gyro_variance
        + dt * dt * covariances[1:, ekf.BIAS, ekf.BIAS],
        noise_scale=inflation,
        wheel_floor=c.wheel_floor,
    )


def _episodes(c: ekf.Config, log: _Log, run: _Run) -> np.ndarray:
    """``steady_episodes`` over a forward pass's intervals, each from its start state (the
    filter's at the end of the interval before)."""
    r_l, r_r, track, _ = c.drive
    dl, dr, dt = log.increments[:, 0], log.increments[:, 1], np.diff(log.times)
    starts, start_covariances = run.out.states[:-1], run.out.covariances[:-1]
    innovation, variance, by_left, by_right = ekf.slip_innovation(
        c, starts, start_covariances, dl, dr, log.turned, log.gyro_variance, dt
    )
    scale = starts[:, ekf.SCALE]
    wheel_noise = np.column_stack(
        [
            c.k[0] * np.abs(r_l * dl) + c.wheel_floor * r_l * r_l,
            c.k[1] * np.abs(r_r * dr) + c.wheel_floor * r_r * r_r,
        ]
    )
    deviation = np.sqrt(variance)
    shared = wheel_noise * (scale * scale / (track * track * variance))[:, None]
    return steady_episodes(
        innovation / deviation,
        np.column_stack([by_left, by_right]) / deviation[:, None],
        run.out.slips[1:],
        dt / deviation,
        shared,
    )
