"""Scalar value types: frozen, slotted dataclasses of floats, cheap like a float.

``Pose`` owns the SE(2) group operations (compose, inverse, relative_to); ``diffdrive.se2``
adds the exponential, the logarithm and the matrix forms. Every field is checked to be finite
when built, so NaN never enters the scalar layer silently.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import astuple, dataclass, fields
from typing import TypeVar

import numpy as np

from diffdrive._validate import finite, positive
from diffdrive.angles import wrap_angle

_V = TypeVar("_V", bound="_Vector")


class _Vector:
    """Shared behaviour of the value types: field checks and array conversion."""

    __slots__ = ()

    def __post_init__(self) -> None:
        for field in fields(self):  # type: ignore[arg-type]
            name = f"{type(self).__name__}.{field.name}"
            object.__setattr__(self, field.name, finite(name, getattr(self, field.name)))

    def to_array(self) -> np.ndarray:
        """The fields as a float64 array, in field order; shape ``(n,)``."""
        return np.array(astuple(self), dtype=np.float64)  # type: ignore[call-overload]

    @classmethod
    def coerce(cls: type[_V], value: object, name: str | None = None) -> _V:
        """``value`` as this type: itself, or a sequence, array or NumPy array of its fields'
        numbers in field order (``(8.0, 10.0)`` for wheels). ``TypeError`` naming ``name``
        for anything else: another value type, strings, booleans."""
        if isinstance(value, cls):
            return value
        names = ", ".join(f.name for f in fields(cls))  # type: ignore[arg-type]
        what = name or cls.__name__
        if not isinstance(value, _Vector | str | bytes):
            array = np.asarray(value) if isinstance(value, list | tuple | np.ndarray) else None
            if array is not None and array.dtype.kind in "iuf":
                if array.shape == (len(fields(cls)),):  # type: ignore[arg-type]
                    return cls(*array.astype(np.float64).tolist())
                size = len(fields(cls))  # type: ignore[arg-type]
                raise ValueError(
                    f"{what} must have {size} numbers [{names}], got shape {array.shape}"
                )
        raise TypeError(
            f"{what} must be a {cls.__name__} or a sequence of numbers [{names}], got {value!r}"
        )

    @classmethod
    def from_array(cls: type[_V], array: object) -> _V:
        """Build from a sequence or array of shape ``(n,)`` in field order."""
        values = np.asarray(array, dtype=np.float64)
        size = len(fields(cls))  # type: ignore[arg-type]
        if values.shape != (size,):
            names = ", ".join(f.name for f in fields(cls))  # type: ignore[arg-type]
            raise ValueError(
                f"{cls.__name__}.from_array expects shape ({size},) [{names}], got {values.shape}"
            )
        return cls(*values.tolist())


@dataclass(frozen=True, slots=True)
class Pose(_Vector):
    """Planar pose of the body frame in the world frame.

    ``x``, ``y`` in m; ``theta`` in rad, counter-clockwise from world x, kept unwrapped.
    """

    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0

    def compose(self, other: Pose) -> Pose:
        """``self * other``: ``other`` is expressed in this pose's frame (a delta)."""
        other = Pose.coerce(other, "other")
        c, s = math.cos(self.theta), math.sin(self.theta)
        return Pose(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            self.theta + other.theta,
        )

    def inverse(self) -> Pose:
        """The pose that composes with this one to the identity."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return Pose(-c * self.x - s * self.y, s * self.x - c * self.y, -self.theta)

    def relative_to(self, reference: Pose) -> Pose:
        """This pose seen from ``reference``: ``reference.inverse() * self``."""
        reference = Pose.coerce(reference, "reference")
        c, s = math.cos(reference.theta), math.sin(reference.theta)
        dx, dy = self.x - reference.x, self.y - reference.y
        return Pose(c * dx + s * dy, -s * dx + c * dy, self.theta - reference.theta)

    def transform_point(self, x: float, y: float) -> tuple[float, float]:
        """A point given in the body frame, in m, expressed in the world frame (seed 003)."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return (self.x + c * x - s * y, self.y + s * x + c * y)

    def wrapped(self) -> Pose:
        """The same pose with ``theta`` wrapped to (-pi, pi]."""
        return Pose(self.x, self.y, wrap_angle(self.theta))


@dataclass(frozen=True, slots=True)
class Twist(_Vector):
    """Body-frame velocity ``(vx, vy, omega)`` in m/s, m/s, rad/s (the ROS order).

    Modern Robotics writes the same vector as ``V_b = (omega, vx, vy)``.
    """

    vx: float = 0.0
    vy: float = 0.0
    omega: float = 0.0


@dataclass(frozen=True, slots=True)
class WheelVelocities(_Vector):
    """Angular wheel velocities in rad/s; positive drives the robot forward."""

    left: float = 0.0
    right: float = 0.0

    @classmethod
    def from_positions(
        cls, before: WheelPositions, after: WheelPositions, dt: float
    ) -> WheelVelocities:
        """Mean wheel velocities between two wheel-angle readings taken ``dt`` s apart."""
        dt = positive("dt", dt)
        return cls((after.left - before.left) / dt, (after.right - before.right) / dt)


@dataclass(frozen=True, slots=True)
class WheelPositions(_Vector):
    """Accumulated wheel angles in rad (the encoders' reading, converted)."""

    left: float = 0.0
    right: float = 0.0

    def advance(self, velocities: WheelVelocities, dt: float) -> WheelPositions:
        """The wheel angles after turning at ``velocities`` for ``dt`` s (seed 001, eq. 5-6)."""
        dt = positive("dt", dt)
        return WheelPositions(self.left + velocities.left * dt, self.right + velocities.right * dt)


# What a scalar function takes for a value: the type itself, or its numbers in field order.
PoseLike = Pose | Sequence[float] | np.ndarray
TwistLike = Twist | Sequence[float] | np.ndarray
WheelsLike = WheelVelocities | Sequence[float] | np.ndarray
