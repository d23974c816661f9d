"""Checks for scalar inputs: one place that words the errors the same way everywhere."""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import TypeVar

import numpy as np


def finite(name: str, value: object) -> float:
    """``value`` as a float; ``ValueError`` naming ``name`` if it is NaN or infinite (or an
    integer too large for a float); ``TypeError`` for what is not a number, strings included
    (``float("1_0")`` would read one)."""
    if isinstance(value, str | bytes):
        raise TypeError(f"{name} must be a real number, not text: got {value!r}")
    try:
        number = float(value)  # type: ignore[arg-type]
    except OverflowError:
        raise ValueError(f"{name} must be finite, got an integer too large for a float") from None
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(number):
        raise ValueError(f"{name} must be finite, got {number}")
    return number


def floats(name: str, value: object) -> np.ndarray:
    """``value`` as an array of floats; ``TypeError`` naming ``name`` for text and what is not
    numbers, ``ValueError`` for integers too large for a float."""
    if isinstance(value, str | bytes):
        raise TypeError(f"{name} must be numbers, not text: got {value!r}")
    try:
        return np.asarray(value, dtype=float)
    except OverflowError:
        raise ValueError(f"{name} must be finite, got an integer too large for a float") from None
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be numbers, got {value!r}") from None


def positive(name: str, value: object) -> float:
    """``value`` as a float; ``ValueError`` naming ``name`` unless it is finite and > 0."""
    number = finite(name, value)
    if number <= 0.0:
        raise ValueError(f"{name} must be > 0, got {number}")
    return number


def nonnegative(name: str, value: object) -> float:
    """``value`` as a float; ``ValueError`` naming ``name`` unless it is finite and >= 0."""
    number = finite(name, value)
    if number < 0.0:
        raise ValueError(f"{name} must be >= 0, got {number}")
    return number


def length(name: str, value: object) -> float:
    """A robot's length (a radius, a track): ``positive``, and not so small that what divides
    by it overflows (5e-324 m gives a turn of inf)."""
    number = positive(name, value)
    if not math.isfinite(1.0 / number):
        raise ValueError(f"{name} must be a length that divides to a finite number, got {number}")
    return number


def whole(name: str, value: object, smallest: int = 0) -> int:
    """``value`` as an int; ``ValueError`` naming ``name`` unless it is a whole number (2 or
    2.0, not 2.5) of at least ``smallest``; ``TypeError`` for booleans and what is not a
    number."""
    if isinstance(value, bool):
        raise TypeError(f"{name} must be a whole number, got {value!r}")
    number = finite(name, value)
    if not number.is_integer() or number < smallest:
        raise ValueError(f"{name} must be a whole number from {smallest}, got {value!r}")
    return int(number)


def rng_of(seed: object) -> np.random.Generator:
    """NumPy's generator for ``seed`` (an int >= 0, kept exactly; None: from the system)."""
    if seed is not None and (
        isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0
    ):
        raise ValueError(f"seed must be a whole number from 0 or None, got {seed!r}")
    return np.random.default_rng(None if seed is None else int(seed))


def increasing(name: str, times: np.ndarray) -> None:
    """``ValueError`` unless the stamps ``times`` ``(N,)`` are finite and increase strictly,
    naming ``name`` and the first stamp that is not."""
    finite_ = np.isfinite(times)
    if not finite_.all():
        index = int(np.argmin(finite_))
        raise ValueError(
            f"{name} must be finite and increase strictly: {name}[{index}] is {times[index]}"
        )
    rising = np.diff(times) > 0
    if not rising.all():
        index = int(np.argmin(rising)) + 1
        raise ValueError(
            f"{name} must be finite and increase strictly: {name}[{index}] = {times[index]} "
            f"does not come after {times[index - 1]}"
        )


def geodetic_point(name: str, value: object) -> tuple[float, float, float]:
    """``(latitude deg, longitude deg, height m)``: finite, on the globe; ``ValueError`` (or
    ``TypeError``) naming ``name`` and what is wrong."""
    parts: tuple[object, ...] = ()
    if isinstance(value, Iterable) and not isinstance(value, str | bytes):
        parts = tuple(value)
    if len(parts) != 3:
        raise ValueError(f"{name} must be (latitude deg, longitude deg, height m), got {value!r}")
    lat, lon, height = (finite(name, v) for v in parts)
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise ValueError(
            f"{name}: latitude must lie in [-90, 90] and longitude in [-180, 180] degrees, "
            f"got {lat:g}, {lon:g}"
        )
    return lat, lon, height


T = TypeVar("T")

MOST_SAMPLES = 10_000_000  # samples of one path, rows of one plan, steps of one simulation


def check_samples(count: float, what: str, advice: str) -> None:
    """Refuse ``count`` samples (or rows, or steps) of ``what`` beyond ``MOST_SAMPLES``, with
    ``advice`` (the arrays would take gigabytes, and the size is usually a unit gone wrong)."""
    if not count <= MOST_SAMPLES:
        raise ValueError(
            f"{what} would take {count:.3g} samples (at most {MOST_SAMPLES:,}): {advice}"
        )


def settings_of(value: object, kind: type[T]) -> T:
    """``value`` if it is a ``kind`` (a settings value), ``kind()`` (its defaults) for None;
    ``TypeError`` naming ``settings`` and what it got otherwise."""
    if value is None:
        return kind()
    if not isinstance(value, kind):
        name = kind.__name__  # "an" before a vowel's sound: an EstimatorSettings, an MPPI...
        spelt = name[:2].isupper() and name[0] in "FHLMNRSX"
        article = "an" if name[0] in "AEIOU" or spelt else "a"
        raise TypeError(f"settings must be {article} {name}, got {type(value).__name__}")
    return value
