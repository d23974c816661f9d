"""The sensors' noise as values: one type each for the wheels and the gyro, one default each,
one draw each for wheel noise and a robot's geometry.

``WheelNoise(left, right)`` (m) is the random-walk model of each wheel's travel that every
part of the library shares (Kelly's, and ``Odometry``'s covariance): a wheel that travels
``s`` m is off by a zero-mean Gaussian of variance ``k |s|`` m^2, independent between wheels and
intervals. ``WheelNoise.symmetric(k)`` is both wheels alike, and a plain number or a pair
``(left, right)`` is read as those wherever a ``WheelNoise`` is taken.

One default, ``DEFAULT`` (``k`` = 1e-4 m both, 1 cm of spread per metre driven): what every
estimator (``Odometry``, ``PoseEstimator``, ``GyroOdometry``, ``estimate_trajectory``) and the
command line assume when given none. Simulators (``monte_carlo``, ``sensors.encoder_readings``,
``control.follow``) draw no noise unless given some: a noise-free run is what a simulation
without a noise figure means.

``GyroNoise`` is the gyro's: white rate noise (``angle_random_walk``), the bias's random walk
(``rate_random_walk``) and its first-order Gauss-Markov wander (``bias_instability`` with its
``correlation_time``), and ``initial_bias_sigma``, what an estimator assumes of the bias before
it has seen any. The synthetic gyro (``sensors.GyroModel``) draws it, the estimators assume
it, ``estimation.standing.identify_gyro`` finds it from a standing stretch, and the whole-log
estimator (``estimate_trajectory``) takes it from the log's standing stretches when none is
given (``identify_standing``). Its default, ``DEFAULT_GYRO``, is a mid-range MEMS gyro's: what
the streaming estimator assumes, and the whole-log one where the wheels never stand still.

Either type made without arguments is no noise at all; the ``DEFAULT`` values are what an
estimator assumes when given none.

``draw_travel`` is the one draw of wheel noise and ``draw_geometry`` the one draw of a robot's
radii and track around their nominal values (``numba_montecarlo`` repeats both inside its
compiled loop, held to them by the Monte Carlo tests).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Union

import numpy as np

from diffdrive._validate import finite, nonnegative, positive

__all__ = [
    "DEFAULT",
    "DEFAULT_GYRO",
    "NONE",
    "GyroNoise",
    "WheelNoise",
    "WheelNoiseLike",
    "draw_geometry",
    "draw_travel",
]


@dataclass(frozen=True)
class WheelNoise:
    """Each wheel's random-walk constant (m): ``left``, ``right``, both >= 0 (see the module)."""

    left: float = 0.0
    right: float = 0.0

    def __post_init__(self) -> None:
        for name in ("left", "right"):
            value = getattr(self, name)
            if isinstance(value, bool) or not finite(f"wheel noise {name}", value) >= 0.0:
                raise ValueError(f"wheel noise {name} must be a number >= 0 m, got {value!r}")
            if not math.isfinite(float(value) * 1e12):  # variances k |s| of long runs stay finite
                raise ValueError(f"wheel noise {name} {value!r} m is past any wheel's")
            object.__setattr__(self, name, float(value))

    @classmethod
    def symmetric(cls, k: float) -> WheelNoise:
        """Both wheels with the constant ``k`` (m)."""
        return cls(k, k)

    @classmethod
    def coerce(cls, value: object, name: str = "wheel_noise") -> WheelNoise:
        """``value`` as a ``WheelNoise``: one already, a number (both wheels) or a pair ``(left,
        right)``; ``ValueError`` naming ``name`` otherwise."""
        if isinstance(value, WheelNoise):
            return value
        if isinstance(value, int | float | np.floating | np.integer) and not isinstance(
            value, bool
        ):
            try:
                return cls.symmetric(float(value))
            except ValueError as error:
                raise ValueError(f"{name}: {error}") from None
        if isinstance(value, tuple | list | np.ndarray) and len(value) == 2:
            try:
                return cls(*(float(v) for v in value))
            except (TypeError, ValueError) as error:
                raise ValueError(f"{name}: {error}") from None
        raise ValueError(
            f"{name} must be a WheelNoise, a number k (m, both wheels) or a pair (left, right), "
            f"got {value!r}"
        )

    @property
    def k(self) -> np.ndarray:
        """``(2,)`` ``[left, right]`` (m)."""
        return np.array([self.left, self.right])

    def __bool__(self) -> bool:
        return self.left > 0.0 or self.right > 0.0


WheelNoiseLike = Union[WheelNoise, float, tuple[float, float]]  # noqa: UP007 (a runtime alias)
"""What a wheel-noise argument takes: a ``WheelNoise``, one ``k`` (m) for both wheels, or
``(k_left, k_right)``."""

DEFAULT = WheelNoise.symmetric(1e-4)
"""The library's wheel noise where none is given to an estimator: ``k`` = 1e-4 m on each wheel."""
NONE = WheelNoise()  # a simulator's default: no noise drawn
"""No wheel noise: a simulator's default, which draws none."""


@dataclass(frozen=True)
class GyroNoise:
    """The gyro's noise (see the module): ``angle_random_walk`` (rad/s/sqrt(Hz)),
    ``rate_random_walk`` (rad/s/sqrt(s)), ``initial_bias_sigma`` (rad/s, an estimator's prior
    on the bias), ``bias_instability`` (rad/s) and its ``correlation_time`` (s)."""

    angle_random_walk: float = 0.0
    rate_random_walk: float = 0.0
    initial_bias_sigma: float = 0.0
    bias_instability: float = 0.0
    correlation_time: float = 100.0

    def __post_init__(self) -> None:
        for name in (
            "angle_random_walk",
            "rate_random_walk",
            "initial_bias_sigma",
            "bias_instability",
        ):
            value = nonnegative(name, getattr(self, name))
            if not math.isfinite(value * value):  # a filter works with its square
                raise ValueError(f"{name} {value!r} squares past the largest float")
        positive("correlation_time", self.correlation_time)


DEFAULT_GYRO = GyroNoise(angle_random_walk=2e-3, rate_random_walk=1e-4, initial_bias_sigma=5e-3)
"""The library's gyro noise where none is given: angle random walk 2e-3 rad/s^0.5, rate random walk
1e-4 rad/s^1.5, initial bias sigma 5e-3 rad/s."""


def draw_travel(travel: np.ndarray, k: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Noise of each wheel's ``travel`` (m, any shape), drawn: ``sqrt(k |travel|)`` times a
    standard normal, ``k`` (m) broadcasting against ``travel`` (``WheelNoise.k`` where the last
    axis is the wheel's)."""
    sigma = np.sqrt(k * np.abs(travel))
    return sigma * rng.standard_normal(sigma.shape)


def draw_geometry(
    nominal: np.ndarray, sigma: np.ndarray, count: int, rng: np.random.Generator
) -> np.ndarray:
    """``count`` robots' ``[r_left, r_right, track]`` ``(count, 3)`` (m), each drawn around
    ``nominal`` ``(3,)`` with relative standard deviations ``sigma`` ``(3,)``; ``ValueError``
    if a draw is not positive (the spread is too wide for a Gaussian)."""
    if not np.any(sigma):
        return np.broadcast_to(nominal, (count, 3))
    drawn = nominal * (1.0 + sigma * rng.standard_normal((count, 3)))
    if np.any(drawn <= 0):
        raise ValueError("geometry_sigma draws a radius or track <= 0: make it smaller")
    return drawn
