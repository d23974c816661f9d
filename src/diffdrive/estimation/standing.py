"""The gyro's noise from where the robot stands still: the Allan deviation of a standing
stretch (``allan_deviation``, ``identify_gyro``), and the settings a whole log's standing
stretches give an estimator (``identify_standing``).

A log's standing stretches are its intervals in which neither wheel turned. Over them the gyro
reads its bias plus its noise, so:

- the bias (rad/s) is the gyro's mean rate over them (``stationary_bias``'s);
- the angle random walk (rad/s/sqrt(Hz)) comes from the Allan deviation of the longest stretch
  (the gyro's own samples in it where given) when it holds 100 samples or more, evenly spaced,
  and the rate random walk and the bias instability with it (a rate random walk of 0 where the
  deviation does not rise: the bias held still over the stretch, and the estimator is told
  so); otherwise from the rates' spread, ``std(rate) sqrt(dt)`` (white rate noise of density N
  has a variance ``N^2 / dt`` in samples of ``dt`` s), the rate random walk then kept at
  ``DEFAULT_GYRO``'s and said so;
- the bias prior (rad/s, what an estimator starts the bias's variance from) is the standard
  error of that mean, ``N / sqrt(T)`` over ``T`` s standing: how well the stretches pin it,
  which is
  far tighter than a datasheet's spread of biases and lets the fused heading leave the bias
  alone where the wheels' turn disagrees with the gyro for reasons of their own (a skid-steer's
  manoeuvre-dependent slip).

``identify_standing`` says what it used and where from (``StandingFit.report``), and None when
the wheels never stand still for ``least`` s: the caller then says which default it used.
``estimate_trajectory`` calls it on the whole log; a streaming ``PoseEstimator`` starts from
a stated warm-up (``warm_up``, then ``PoseEstimator(robot, fit.settings())``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive._stats import nonnegative_least_squares
from diffdrive.estimation.settings import EstimatorSettings
from diffdrive.sensor_noise import DEFAULT_GYRO, GyroNoise

__all__ = [
    "GyroFit",
    "StandingFit",
    "allan_deviation",
    "identify_gyro",
    "identify_standing",
    "warm_up",
]


@dataclass(frozen=True, eq=False)
class GyroFit:
    """``identify_gyro``'s result: the gyro's ``noise`` (a ``GyroNoise``: its angle random
    walk, bias instability and rate random walk fitted; the bias prior an estimator takes from
    it, the instability or a small floor), and the overlapping Allan deviation it was fitted
    to: ``taus`` (s) and ``deviations`` (rad/s)."""

    noise: GyroNoise
    taus: np.ndarray
    deviations: np.ndarray


# Allan variance of each term (IEEE Std 952-1997, annex C): N^2 / tau for white rate noise,
# (2 ln 2 / pi) B^2 on the flat of a bias instability, K^2 tau / 3 for a rate random walk.
_FLAT = 2.0 * np.log(2.0) / np.pi


def allan_deviation(times: object, rates: object) -> tuple[np.ndarray, np.ndarray]:
    """The overlapping Allan deviation (rad/s) of gyro ``rates`` sampled evenly at ``times``
    (s), at cluster times ``tau`` (s) of 1, 2, 4, ... samples up to a quarter of the record:
    ``(taus, deviations)``. ``ValueError`` if the samples are not evenly spaced (to 1 %) or
    too few (100 or more)."""
    times = np.asarray(times, dtype=float)
    rates = np.asarray(rates, dtype=float)
    if times.ndim != 1 or rates.shape != times.shape:
        raise ValueError(f"times and rates must be (M,), got {times.shape} and {rates.shape}")
    if len(times) < 100:
        raise ValueError(
            f"the stationary stretch is too short for the Allan deviation: {len(times)} "
            "samples, 100 or more needed"
        )
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(rates))):
        raise ValueError("times and rates must be finite")
    steps = np.diff(times)
    dt = float(np.median(steps))
    if not dt > 0 or np.abs(steps - dt).max() > 0.01 * dt:
        raise ValueError(
            "the Allan deviation needs evenly spaced samples (to 1 %); resample the stretch"
        )
    # Each sample the mean rate over its period, as the Allan variance's clusters average.
    angle = np.concatenate([[0.0], np.cumsum(rates * dt)])
    clusters = 2 ** np.arange(int(np.log2(len(angle) / 4)) + 1)
    taus, deviations = [], []
    for m in clusters:
        second = angle[2 * m :] - 2.0 * angle[m:-m] + angle[: -2 * m]
        tau = m * dt
        taus.append(tau)
        deviations.append(np.sqrt(np.mean(second**2) / (2.0 * tau**2)))
    return np.array(taus), np.array(deviations)


def identify_gyro(times: object, rates: object) -> GyroFit:
    """A gyro's angle random walk, bias instability and rate random walk from a stretch in
    which it stands still: the three terms' Allan variances fitted to the measured one by
    non-negative least squares, relative to it, each cluster time weighed by how well the
    record measures it (its relative error falls as the square root of the clusters that fit
    in the record, the count the IEEE 952 annex's confidence uses)."""
    taus, deviations = allan_deviation(times, rates)
    design = np.column_stack([1.0 / taus, np.full(len(taus), _FLAT), taus / 3.0])
    target = deviations**2
    clusters = np.sqrt(float(np.asarray(times)[-1] - np.asarray(times)[0]) / taus)
    weighted = design / target[:, None] * clusters[:, None]
    n2, b2, k2 = nonnegative_least_squares(weighted, clusters)
    instability = float(np.sqrt(b2))
    noise = GyroNoise(
        angle_random_walk=float(np.sqrt(n2)),
        rate_random_walk=float(np.sqrt(k2)),
        initial_bias_sigma=max(instability, 1e-6),
        bias_instability=instability,
    )
    return GyroFit(noise, taus, deviations)


@dataclass(frozen=True)
class StandingFit:
    """``identify_standing``'s result: the gyro's ``noise`` and ``bias`` (rad/s) from the
    log's standing stretches (``standing`` s in all, the longest ``longest`` s), and the
    ``report``: one line per figure, what it is and where from."""

    noise: GyroNoise
    bias: float
    standing: float
    longest: float
    report: tuple[str, ...]

    def settings(self, given: EstimatorSettings | None = None) -> EstimatorSettings:
        """``given`` (default ``EstimatorSettings()``) with the gyro's ``noise`` and ``bias``
        where it leaves them None: ``PoseEstimator(robot, fit.settings())`` streams on from a
        warm-up."""
        given = EstimatorSettings() if given is None else given
        return given.replace(
            gyro_noise=self.noise if given.gyro_noise is None else given.gyro_noise,
            bias=self.bias if given.bias is None else given.bias,
        )


def identify_standing(
    times: object,
    increments: object,
    turned: object,
    *,
    samples: tuple[np.ndarray, np.ndarray] | None = None,
    least: float = 0.5,
) -> StandingFit | None:
    """The gyro's noise and bias from a log's standing stretches (see the module): wheel-angle
    ``increments`` ``(N-1, 2)`` rad and the gyro's ``turned`` ``(N-1,)`` rad between ``times``
    ``(N,)`` s; ``samples``: the gyro's own ``(times, rates)``, whose samples inside the
    longest stretch give the noise (at the gyro's rate; else the intervals' mean rates do).
    None when the wheels stand still for less than ``least`` s or fewer than 10 intervals."""
    t = np.asarray(times, dtype=float)
    steps, turns = np.diff(t), np.asarray(turned, dtype=float)
    still = np.all(np.asarray(increments, dtype=float) == 0.0, axis=1) & np.isfinite(turns)
    if np.count_nonzero(still) < 10 or float(steps[still].sum()) < least:
        return None
    duration = float(steps[still].sum())
    bias = float(turns[still].sum() / duration)
    first, last = _longest_run(still)
    longest = float(t[last + 1] - t[first])
    where = (
        f"{duration:.1f} s standing in all, the longest {longest:.1f} s from "
        f"{t[first] - t[0]:.1f} s into the log"
    )
    report = [f"gyro bias {bias:.3g} rad/s: its mean rate while the wheels stand still ({where})"]
    # The noise from the gyro's own samples in the longest stretch where given, else from the
    # intervals' mean rates there.
    stretch_t = t[first + 1 : last + 2]
    stretch = turns[first : last + 1] / steps[first : last + 1]
    source = "the wheel intervals' mean rates"
    if samples is not None:
        inside = (samples[0] > t[first]) & (samples[0] < t[last + 1])
        if np.count_nonzero(inside) >= 10:
            stretch_t, stretch = samples[0][inside], samples[1][inside]
            source = f"the gyro's {len(stretch)} samples"
    spread = float(np.std(stretch, ddof=1))
    fit = None
    if len(stretch) >= 100:
        try:
            fit = identify_gyro(stretch_t, stretch)
        except ValueError as why:  # uneven stamps: the spread below instead
            report.append(f"no Allan deviation of the longest stretch ({why})")
    if fit is not None and fit.noise.angle_random_walk > 0.0:
        arw, instability = fit.noise.angle_random_walk, fit.noise.bias_instability
        report.append(
            f"angle random walk {arw:.3g} rad/s/sqrt(Hz): the Allan deviation of {source} in "
            "the longest stretch"
        )
    else:
        arw, instability = spread * math.sqrt(float(np.median(np.diff(stretch_t)))), 0.0
        report.append(
            f"angle random walk {arw:.3g} rad/s/sqrt(Hz): the spread of {source} in the "
            f"longest stretch ({spread:.3g} rad/s; too few or uneven for an Allan deviation)"
        )
    if fit is not None:
        rrw = fit.noise.rate_random_walk
        seen = "" if rrw > 0.0 else f" (no rise of it over the {longest:.1f} s: the bias held)"
        report.append(
            f"rate random walk {rrw:.3g} rad/s^2/sqrt(Hz): the same Allan deviation{seen}"
        )
    else:
        rrw = DEFAULT_GYRO.rate_random_walk
        report.append(
            f"rate random walk {rrw:.3g} rad/s^2/sqrt(Hz): the default (no Allan deviation of "
            "the stretch to show the bias wander)"
        )
    # The standard error of the mean over every standing second: white rate noise of density
    # N averages to N / sqrt(T) over T s.
    prior = max(arw / math.sqrt(duration), 1e-6)
    report.append(f"bias prior {prior:.3g} rad/s: the standard error of the standing mean")
    noise = GyroNoise(
        angle_random_walk=arw,
        rate_random_walk=rrw,
        initial_bias_sigma=prior,
        bias_instability=instability,
    )
    return StandingFit(noise, bias, duration, longest, tuple(report))


def warm_up(times: object, increments: object, gyro) -> StandingFit | None:
    """``identify_standing`` of a warm-up: wheel-angle ``increments`` ``(N-1, 2)`` rad between
    ``times`` ``(N,)`` s, standing for part of it, and the ``Gyro`` (an ``imu.Gyro``) over
    them; a streaming estimator then starts from ``fit.settings()``."""
    t = np.asarray(times, dtype=float)
    turned = np.diff(gyro.angles(t))
    return identify_standing(t, increments, turned, samples=(gyro.times, gyro.rates))


def _longest_run(mask: np.ndarray) -> tuple[int, int]:
    """The first and last index of the longest run of True in ``mask`` (one True at least)."""
    edges = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    k = int(np.argmax(stops - starts))
    return int(starts[k]), int(stops[k] - 1)
