"""What position fixes (a GPS receiver's) are worth, identified from the fixes themselves.

A receiver's error is mostly not white: its fixes wander (multipath, the satellites moving)
and jump, and the variance it reports covers the whole error. ``identify_fixes`` splits it the
way ``estimate_trajectory``'s fix offset state takes it (``diffdrive.estimation.filter``):

- the dead reckoning is fitted onto the fixes by a rotation, a scale and a shift (least squares
  in the complex plane); the scale is the wheels' distance scale, the rotation and shift give
  the start in the fixes' frame. The standard errors of the scale and the rotation are the
  least-squares fit's under the residuals' own model (below; the sandwich form): the
  residuals are correlated in time, and the formula for white ones would be overconfident;
- what the fit leaves, the fixes' residuals in time, has the variogram of a random walk (the
  offset's wander, ``q`` m^2/s) seen through white noise (``w^2`` m^2): ``w^2 + q tau / 2`` per
  axis at lag ``tau``. The variogram at the first ``LAGS`` lags is Cressie and Hawkins's robust
  estimate (Mathematical Geology 12(2), 1980), which a receiver's jumps do not inflate as they
  do a mean of squares, and the line through it gives ``w^2`` and ``q``.

The dead reckoning's own drift lands in the wander too: the offset then carries what the
wheels and gyro got wrong between fixes as well, which is what a smoother needs of it.

Fixes far apart cannot tell white noise from wander: their first lag already spans more time
than a receiver's white noise shows apart from its wander in (``SPAN``), and a wander that
bends back (a receiver's multipath, the dead reckoning's own errors over tens of seconds)
reads there as white noise. On the Husky, one fix every 10 s gives a line through 0.69 m of
white noise where the receiver's whole stream shows 0.001 m, and the smoother that believes it
places the fixes left out 30 % worse than one that does not. So where fewer than two lags fall
within ``SPAN`` the white noise is held at a stated prior, ``WHITE_PRIOR`` (a receiver's fixes
come out of its own filter and are smooth from one to the next: centimetres to a decimetre),
and the wander is the line through that intercept. Were the fixes' noise white after all, the
smoother passes close to each fix rather than averaging them: as good as interpolating them,
not better. As few as ``LEAST_FIXES`` fixes are taken: the fit of four numbers leaves a
residual, and the wander is what the lags there show.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive._validate import floats, increasing
from diffdrive.estimation.measurements import Measurement, measurements_of
from diffdrive.estimation.settings import EstimatorSettings, FixOffset, Gate, Prior

__all__ = ["FixFit", "identify_fixes"]

# The fewest fixes to identify anything from: a fit of 4 numbers leaves a residual from 3.
LEAST_FIXES = 3
# The variogram's lags: from one fix to LAGS fixes or SPAN seconds, whichever is more (fixes
# at 100 Hz five apart span too little time to show a wander), LAG_COUNT of them at most.
LAGS, SPAN, LAG_COUNT = 5, 2.5, 8
# The white noise's floor, m: a fix is never taken as exact.
WHITE_FLOOR = 1e-3
# The white noise held where the fixes are too far apart to show it (see the module), m.
WHITE_PRIOR = 0.1
# The wander's floor, m/sqrt(s): the offset state stays on.
WANDER_FLOOR = 1e-4
# The gate for identified fixes (a probability): wide, with outliers inflated.
IDENTIFIED_GATE = 1.0 - 1e-9


@dataclass(frozen=True)
class FixFit:
    """``identify_fixes``'s result: the fixes' ``white`` noise (m, each axis), the offset's
    ``wander`` (m/sqrt(s)), the wheels' ``fitted_scale`` and its ``scale_error`` (standard
    error), the ``distance_scale`` to use (the fitted one, or 1 where the fit cannot tell it
    from 1 within two standard errors), the ``start`` pose ``(3,)`` (the body origin at the
    log's start, in the fixes' frame) and its ``start_covariance`` ``(3, 3)``, how many
    ``fixes`` it used, and ``report``: what each is and where from."""

    white: float
    wander: float
    fitted_scale: float
    scale_error: float
    distance_scale: float
    start: np.ndarray
    start_covariance: np.ndarray
    fixes: int
    report: tuple[str, ...]

    def settings(self, given: EstimatorSettings) -> EstimatorSettings:
        """``given`` with what it leaves None taken from the fit: the offset's wander
        (``fix_offset``), the distance scale (``distance_scale``, not estimated) and the gate:
        wide (``IDENTIFIED_GATE``), a fix past it inflated, not refused (a receiver's jumps are
        heavier-tailed than a Gaussian). The start is ``start`` and ``start_covariance``."""
        found = {
            "fix_offset": FixOffset(rate=self.wander),
            "distance_scale": Prior(self.distance_scale),
            "gate": Gate(IDENTIFIED_GATE, "inflate"),
        }
        return given.replace(
            **{name: value for name, value in found.items() if getattr(given, name) is None}
        )

    def measurements(
        self, fix_times: object, fixes: object, lever_arm: object = None
    ) -> list[Measurement]:
        """Position ``Measurement``s of ``fixes`` ``(M, 2)`` m at ``fix_times`` ``(M,)`` s with
        the white noise found (the receiver's fixes, or a share of them)."""
        return measurements_of("position", fix_times, fixes, self.white, lever_arm)


def _checked(times, poses, fix_times, fixes) -> tuple[np.ndarray, ...]:
    """The four arrays of ``identify_fixes``, or a ``ValueError`` naming the one that is
    wrong: its shape, a stamp out of order, a value that is no finite number."""
    times, poses = floats("times", times), floats("poses", poses)
    fix_times, fixes = floats("fix_times", fix_times), floats("fixes", fixes)
    if times.ndim != 1 or poses.shape != (len(times), 3) or len(times) < 2:
        raise ValueError(
            f"times (N,) and poses (N, 3) with N >= 2 must match, got {times.shape} and "
            f"{poses.shape}"
        )
    if fix_times.ndim != 1 or fixes.shape != (len(fix_times), 2):
        raise ValueError(
            f"fix_times (M,) and fixes (M, 2) m must match, got {fix_times.shape} and {fixes.shape}"
        )
    increasing("times", times)
    increasing("fix_times", fix_times)
    for name, values in (("poses", poses), ("fixes", fixes)):
        if not np.all(np.isfinite(values)):
            row = int(np.argmin(np.all(np.isfinite(values), axis=1)))
            raise ValueError(f"{name} must be finite: row {row} is {values[row].tolist()}")
    return times, poses, fix_times, fixes


def identify_fixes(
    times: object,
    poses: object,
    fix_times: object,
    fixes: object,
    reported: float | None = None,
) -> FixFit:
    """The fixes' noise, the offset's wander, the distance scale and the start, from dead
    reckoning ``poses`` ``(N, 3)`` at ``times`` ``(N,)`` s (the body's, in any frame) and
    ``fixes`` ``(M, 2)`` m at ``fix_times`` ``(M,)`` s (increasing, inside the log);
    ``reported`` (m): the receiver's own figure, quoted in the report. ``ValueError`` naming
    what is missing: fewer than ``LEAST_FIXES`` fixes, or dead reckoning that hardly moves
    while they were taken (no rotation or scale to fit)."""
    times, poses, fix_times, fixes = _checked(times, poses, fix_times, fixes)
    if len(fix_times) < LEAST_FIXES:
        raise ValueError(
            f"{len(fix_times)} position fixes: at least {LEAST_FIXES} are needed to fit the dead "
            "reckoning onto them and see what is left (give the fixes' covariance, a FixOffset, "
            "and WholeLog(fixes='given'))"
        )
    along = np.column_stack([np.interp(fix_times, times, poses[:, i]) for i in (0, 1)])
    z, seen = along @ (1.0, 1j), fixes @ (1.0, 1j)
    turn, shift, moved = _similarity(z, seen)
    if not moved > 1e-2 * len(z):  # under 10 cm from the mean, on average
        raise ValueError(
            "the dead reckoning hardly moves while the fixes were taken (under 0.1 m from its "
            "mean): no heading or scale can be fitted onto them; drive a few metres, or give "
            "initial_pose, a FixOffset and WholeLog(fixes='given')"
        )
    reckoned = math.sqrt(moved / len(z))  # RMS distance from the mean, m
    spread = float(np.sqrt(np.mean(np.abs(seen - seen.mean()) ** 2)))
    if not spread > 0.1 * reckoned:
        raise ValueError(
            f"the fixes hardly move ({spread:.3g} m RMS from their mean) while the dead "
            f"reckoning moves {reckoned:.3g} m: a receiver that never moved (no fix, or a held "
            "one?); no heading or scale can be fitted onto them"
        )
    residuals = seen - (turn * z + shift)
    flat = np.column_stack([residuals.real, residuals.imag])
    spacing = float(np.median(np.diff(fix_times)))
    reach = max(LAGS, round(SPAN / spacing) if spacing > 0.0 else LAGS)
    short = np.unique(np.round(np.geomspace(1, reach, LAG_COUNT)).astype(int))
    # See the module: two lags within SPAN to tell white noise from wander, and fixes enough.
    told = 2.0 * spacing <= SPAN and np.count_nonzero(short <= len(fix_times) // 2) >= 2
    held = None if told else WHITE_PRIOR
    white, wander = _variogram_line(fix_times, flat, short, held)
    # The fit's errors see the whole log: the wander over lags up to a quarter of it too.
    longest = max(len(fix_times) // 4, 2)
    lags = np.unique(np.geomspace(1, longest, 10).astype(int))
    slow = _variogram_line(fix_times, flat, lags, held)[1]
    fitted, rotation = abs(turn), float(np.angle(turn))
    scale_error, heading_sigma = _fit_errors(fix_times, z, turn, white, max(wander, slow))
    # A scale the fit cannot tell from 1 (within two standard errors) is left at 1.
    scale = fitted if abs(fitted - 1.0) > 2.0 * scale_error else 1.0
    # the start: the fit at the log's start, moved by the residual the first fix leaves
    first = turn * (poses[0, 0] + 1j * poses[0, 1]) + shift + residuals[0]
    start = np.array([first.real, first.imag, poses[0, 2] + rotation])
    covariance = np.diag([white * white, white * white, heading_sigma * heading_sigma])
    quoted = "" if reported is None else f" (the receiver reports {reported:.3g} m)"
    shown = min(int(short[-1]), len(fix_times) // 2)
    source = (
        f"the robust variogram of the {len(fixes)} fixes' residuals from the dead reckoning "
        f"fitted onto them, at lags of 1 to {shown} fixes ({shown * spacing:.3g} s)"
    )
    if held is not None:
        source = (
            f"the white noise held at its prior: {len(fixes)} fixes {spacing:.3g} s apart "
            f"cannot tell it from the wander (that takes two lags within {SPAN:g} s); the "
            f"wander from {source}"
        )
    report = (
        f"fixes: white noise {white:.3g} m each axis{quoted}, their offset wandering "
        f"{wander:.3g} m/sqrt(s): {source}",
        f"distance scale {scale:.4f}: "
        + (
            f"the dead reckoning's scale fitted onto the fixes, +- {scale_error:.4f}"
            if scale != 1.0
            else f"the fit's {fitted:.4f} +- {scale_error:.4f} is not told from 1"
        )
        + " (its error: the fit's, under the white noise found and the wander at lags up to "
        "a quarter of the log)",
        f"start ({start[0]:.3f} m, {start[1]:.3f} m, {start[2]:.4f} rad) in the fixes' frame, "
        f"heading to {heading_sigma:.2g} rad: the same fit",
    )
    return FixFit(white, wander, fitted, scale_error, scale, start, covariance, len(fixes), report)


def _similarity(z: np.ndarray, seen: np.ndarray) -> tuple[complex, complex, float]:
    """The rotation-and-scale ``turn`` and ``shift`` that best carry points ``z`` onto
    ``seen`` (complex), and how far ``z`` spreads (sum of squares about its mean, m^2)."""
    spread = z - z.mean()
    moved = float(np.vdot(spread, spread).real)
    turn = complex(np.vdot(spread, seen - seen.mean()) / moved) if moved > 0.0 else 1.0 + 0j
    return turn, complex(seen.mean() - turn * z.mean()), moved


def _fit_errors(
    stamps: np.ndarray, z: np.ndarray, turn: complex, white: float, wander: float
) -> tuple[float, float]:
    """The standard errors of the fit's scale and rotation (rad) when the residuals, each axis,
    have covariance ``K = white^2 I + wander^2 min(s_i, s_j)`` (``s``: time since the first
    fix): ``A^-1 X^T K X A^-1`` with ``A = X^T X`` over the fit's four numbers (the turn's
    real and imaginary parts, the shift's). ``u^T min(s_i, s_j) v`` is the sum over ``k`` of
    ``(s_k - s_(k-1))`` times the sums of ``u`` and ``v`` from ``k`` on: O(M)."""
    x, y, ones, zeros = z.real, z.imag, np.ones(len(z)), np.zeros(len(z))
    design = (  # each axis's rows of X: the fix's x, then its y
        np.column_stack([x, -y, ones, zeros]),
        np.column_stack([y, x, zeros, ones]),
    )
    steps = np.diff(stamps, prepend=stamps[0])
    information, spread = np.zeros((4, 4)), np.zeros((4, 4))
    for X in design:
        information += X.T @ X
        tails = np.cumsum(X[::-1], axis=0)[::-1]  # the sums of each column from k on
        spread += white * white * (X.T @ X) + wander * wander * (tails.T * steps) @ tails
    inverse = np.linalg.inv(information)
    covariance = inverse @ spread @ inverse
    a = np.array([turn.real, turn.imag])
    size = abs(turn)
    by_scale, by_angle = a / size, np.array([-a[1], a[0]]) / (size * size)
    block = covariance[:2, :2]
    return float(np.sqrt(by_scale @ block @ by_scale)), float(np.sqrt(by_angle @ block @ by_angle))


def _variogram_line(
    stamps: np.ndarray, residuals: np.ndarray, lags: np.ndarray, white: float | None = None
) -> tuple[float, float]:
    """The white noise (m) and random walk (m/sqrt(s)) of residuals ``(M, 2)`` at ``stamps``
    ``(M,)``: the line ``w^2 + q tau / 2`` through their robust semivariogram (each axis,
    averaged) at ``lags`` (in fixes; those past half the fixes left out), by least squares
    (see the module); ``white`` (m): the intercept held there, only the slope fitted."""
    taus, values = [], []
    for lag in lags[lags <= len(stamps) // 2]:
        steps = residuals[lag:] - residuals[:-lag]
        n = len(steps)
        robust = np.mean(np.sqrt(np.abs(steps)), axis=0) ** 4 / (0.457 + 0.494 / n) / 2.0
        taus.append(float(np.mean(stamps[lag:] - stamps[:-lag])))
        values.append(float(np.mean(robust)))
    tau, value = np.array(taus), np.array(values)
    if white is not None:
        half_rate = float(tau @ (value - white * white) / (tau @ tau))
        return white, max(math.sqrt(max(2.0 * half_rate, 0.0)), WANDER_FLOOR)
    design = np.column_stack([np.ones(len(taus)), tau])
    (white2, half_rate), *_ = np.linalg.lstsq(design, value, rcond=None)
    found = max(math.sqrt(max(float(white2), 0.0)), WHITE_FLOOR)
    return found, max(math.sqrt(max(2.0 * float(half_rate), 0.0)), WANDER_FLOOR)
