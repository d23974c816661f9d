"""Angle wrapping, shared by the scalar and batch layers."""

from __future__ import annotations

import math

from diffdrive._validate import finite

TAU = 2.0 * math.pi


def wrap_angle(angle: float) -> float:
    """Map an angle in rad to the interval (-pi, pi].

    Headings stay unwrapped in poses and trajectories; wrap only to display or compare.
    """
    wrapped = math.remainder(finite("angle", angle), TAU)
    # remainder() rounds half to even, so -pi (and 3*pi, ...) lands on -pi: move it to +pi.
    return wrapped + TAU if wrapped <= -math.pi else wrapped
