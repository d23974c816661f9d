"""Skid-steer robots: several wheels (or a track) a side, turning by sliding.

A skid-steer robot turns about instantaneous centres of rotation (ICRs) that lie further out
than its wheels (Martinez, Mandow, Morales, Pedraza and Garcia-Cerezo, "Approximating
kinematics for tracked mobile robots", IJRR 24(10), 2005; Mandow, Martinez, Morales,
Blanco, Garcia-Cerezo and Gonzalez, "Experimental kinematics for wheeled skid-steer mobile
robots", IROS 2007). With the sides' ground speeds ``v_l = r_l w_l``, ``v_r = r_r w_r`` (the
mean of a side's wheels, as ROS's diff_drive_controller takes them), and the ICRs of the
left and right sides at ``y = icr_left`` and ``y = icr_right`` and of the whole robot at
``x = icr_x`` (body frame, m):

    omega = (v_r - v_l) / (icr_left - icr_right)
    vx    = (v_r icr_left - v_l icr_right) / (icr_left - icr_right)
    vy    = -icr_x omega

An ideal differential drive is the case ``icr_left = track/2``, ``icr_right = -track/2``,
``icr_x = -axle_offset``; a skid-steer robot's ICRs typically lie 1.5 to 2 times as far
apart as its wheels (the "wheel separation multiplier" of ROS configurations).

The same motion is that of a differential drive with track ``icr_left - icr_right`` whose
reference point lies ``(icr_left + icr_right) / 2`` to the left of the body origin
(``equivalent`` and ``reference_offset``): ``simulate``, ``Odometry`` and ``calibrate`` run on
it and move the poses back to the body origin, exactly (a rigid offset).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from diffdrive._validate import finite, length, positive
from diffdrive.model import DiffDrive, ReferencePoint, path_radius, wheel_radii
from diffdrive.types import Twist, TwistLike, WheelsLike, WheelVelocities

__all__ = ["SkidSteer"]


@dataclass(frozen=True, slots=True, init=False)
class SkidSteer(ReferencePoint):
    """A skid-steer robot by its ICRs (see the module).

    Give ``wheel_radius`` (or ``left_wheel_radius`` and ``right_wheel_radius``), m; the ICRs
    ``icr_left`` > ``icr_right`` (m, the sides' ICRs on body y) and ``icr_x`` (m, default 0);
    ``wheels_per_side`` (default 1) is how many wheel velocities ``side_velocities`` averages.
    """

    left_wheel_radius: float
    right_wheel_radius: float
    icr_left: float
    icr_right: float
    icr_x: float
    wheels_per_side: int

    # Calibration may widen the ICR spread to 3 times its nominal value (1.5 to 2 times the
    # wheels' track is common).
    TRACK_RANGE: ClassVar[tuple[float, float]] = (0.5, 3.0)

    def __init__(
        self,
        wheel_radius: float | None = None,
        icr_left: float | None = None,
        icr_right: float | None = None,
        *,
        left_wheel_radius: float | None = None,
        right_wheel_radius: float | None = None,
        icr_x: float = 0.0,
        wheels_per_side: int = 1,
    ) -> None:
        radii = wheel_radii(wheel_radius, left_wheel_radius, right_wheel_radius)
        if icr_left is None or icr_right is None:
            raise ValueError("give icr_left and icr_right (m), the sides' ICRs on body y")
        left, right = finite("icr_left", icr_left), finite("icr_right", icr_right)
        if not left > right:
            raise ValueError(f"icr_left must lie left of icr_right, got {left} and {right}")
        if not math.isfinite(left - right):
            raise ValueError(
                f"icr_left - icr_right (the ICR spread, the effective track) overflows: "
                f"{left} and {right}"
            )
        length("icr_left - icr_right (the ICR spread, the effective track)", left - right)
        if (
            isinstance(wheels_per_side, bool)
            or not isinstance(wheels_per_side, int | np.integer)
            or (wheels_per_side < 1)
        ):
            raise ValueError(
                f"wheels_per_side must be a whole number >= 1, got {wheels_per_side!r}"
            )
        object.__setattr__(self, "left_wheel_radius", radii[0])
        object.__setattr__(self, "right_wheel_radius", radii[1])
        object.__setattr__(self, "icr_left", left)
        object.__setattr__(self, "icr_right", right)
        object.__setattr__(self, "icr_x", finite("icr_x", icr_x))
        object.__setattr__(self, "wheels_per_side", int(wheels_per_side))

    @classmethod
    def from_effective_track(
        cls, wheel_radius: float, track_width: float, multiplier: float = 1.0, **options
    ) -> SkidSteer:
        """Symmetric ICRs at ``+-multiplier * track_width / 2`` (ROS's separation multiplier)."""
        half = 0.5 * positive("track_width", track_width) * positive("multiplier", multiplier)
        return cls(wheel_radius, half, -half, **options)

    @property
    def icr_spread(self) -> float:
        """``icr_left - icr_right``, m: the effective track."""
        return self.icr_left - self.icr_right

    @property
    def track_width(self) -> float:
        """The effective track width, m: the ICR spread (what calibration fits)."""
        return self.icr_spread

    @property
    def wheel_radius(self) -> float:
        """The mean of the two wheel radii, m."""
        return 0.5 * (self.left_wheel_radius + self.right_wheel_radius)

    @property
    def reference_offset(self) -> float:
        """How far left of the body origin the ICRs' midpoint lies, m (0 when symmetric)."""
        return 0.5 * (self.icr_left + self.icr_right)

    @property
    def equivalent(self) -> DiffDrive:
        """The differential drive that moves the point ``(0, reference_offset)`` as this robot
        moves it."""
        return DiffDrive(
            left_wheel_radius=self.left_wheel_radius,
            right_wheel_radius=self.right_wheel_radius,
            track_width=self.icr_spread,
            axle_offset=-self.icr_x,
        )

    def with_geometry(
        self,
        left_wheel_radius: float,
        right_wheel_radius: float,
        track_width: float,
        axle_offset: float | None = None,
    ) -> SkidSteer:
        """This robot with other wheel radii and ICR spread ``track_width`` (m) about the same
        midpoint; ``axle_offset``, if given, is the equivalent drive's (``icr_x`` is minus it)."""
        middle = self.reference_offset
        return SkidSteer(
            left_wheel_radius=left_wheel_radius,
            right_wheel_radius=right_wheel_radius,
            icr_left=middle + 0.5 * track_width,
            icr_right=middle - 0.5 * track_width,
            icr_x=self.icr_x if axle_offset is None else -axle_offset,
            wheels_per_side=self.wheels_per_side,
        )

    def settings(self) -> dict[str, float]:
        """The robot file's keys for this robot (``diffdrive.io.write_robot``)."""
        return {
            "left_wheel_radius": self.left_wheel_radius,
            "right_wheel_radius": self.right_wheel_radius,
            "icr_left": self.icr_left,
            "icr_right": self.icr_right,
            "icr_x": self.icr_x,
        }

    def side_velocities(self, left: object, right: object) -> WheelVelocities:
        """The sides' wheel velocities (rad/s): the mean of ``wheels_per_side`` each."""
        sides = []
        for name, wheels in (("left", left), ("right", right)):
            values = [
                finite(name, v) for v in (wheels if isinstance(wheels, list | tuple) else [wheels])
            ]
            if len(values) != self.wheels_per_side:
                raise ValueError(
                    f"{name}: {self.wheels_per_side} wheel velocities a side, got {len(values)}"
                )
            sides.append(sum(values) / len(values))
        return WheelVelocities(*sides)

    def to_twist(self, wheels: WheelsLike) -> Twist:
        """The body twist from the sides' wheel velocities (the ICR kinematics, computed as
        the equivalent drive's, so that the ideal case is a ``DiffDrive`` to the bit)."""
        return self.twist_from_reference(
            self.equivalent.to_twist(WheelVelocities.coerce(wheels, "wheels"))
        )

    def to_wheel_velocities(self, twist: TwistLike) -> WheelVelocities:
        """The sides' wheel velocities that drive ``twist``; its ``vy`` is not used."""
        at_reference = self.twist_to_reference(Twist.coerce(twist, "twist"))
        return self.equivalent.to_wheel_velocities(Twist(at_reference.vx, 0.0, at_reference.omega))

    def turning_radius(self, wheels: WheelsLike) -> float:
        """Signed radius of the body origin's path, m (as ``DiffDrive.turning_radius``)."""
        return path_radius(self.to_twist(wheels))
