"""The integration step, defined once; every backend follows this module.

One step turns the wheel-angle increments ``dl``, ``dr`` (rad) of an interval into a move of
the body frame:

1. the wheel-to-body map (``wheel_move``): wheel arcs ``r_l dl``, ``r_r dr`` (m) give the
   forward travel ``(left + right) / 2``, the turn ``(right - left) / track`` (rad) and the
   sideways travel of a reference point ``axle_offset`` ahead of the axle, ``offset * turn``;
2. the body move (``body_move``): that travel turned by ``weight * turn`` and scaled by the
   chord factor, by the method's flags (``METHOD_FLAGS``): euler ``(0, no chord)``, along the
   heading at the start (seeds 000, 002); rk2 ``(1/2, no chord)``, along the mid-step heading;
   exact ``(1/2, chord)``, the same times ``sinc(turn / 2)``: the chord of the arc, seed 001's
   ``T_bb'``, exact for constant wheel velocities.

``move_jacobians`` is the world move of a wheel step with its derivatives with respect to the
forward travel and the turn: the Jacobians every estimator propagates its covariance with.

``sinc`` has one rule in every precision: below ``TAYLOR_LIMIT`` (1/16) its Taylor form to
``u^8`` (the first term left out, ``u^10 / 11!``, is under 1e-20 there: an ulp even in float64),
above it ``sin(u) / u``. ``sinc_cos`` gives ``cos u`` the same way.

Who follows it (``diffdrive.backends`` lists them): ``integrate.delta`` and the pure-Python
odometry core use these functions as written; the numba kernels compile them; the batch layer
applies the same flags and rule to arrays (``batch.integrate.delta``, ``batch.sinc``); the C
core mirrors them (``c/src/step.h``).
``tests/test_backends.py`` holds every backend to one table of cases.
"""

from __future__ import annotations

import math
from typing import Any, Literal

__all__ = [
    "METHODS",
    "METHOD_FLAGS",
    "TAYLOR_LIMIT",
    "Method",
    "body_move",
    "check_method",
    "method_flags",
    "move_jacobians",
    "sinc",
    "sinc_cos",
    "sinc_derivative",
    "twist_move",
    "wheel_move",
]

# Per method: the share of the step's turn by which the move's direction is turned, and
# whether the move is scaled to the chord of the arc.
Method = Literal["euler", "rk2", "exact"]
"""The integration methods' names: ``"euler"``, ``"rk2"`` (midpoint heading) and ``"exact"`` (the
SE(2) exponential of a constant twist)."""
METHOD_FLAGS: dict[Method, tuple[float, bool]] = {
    "euler": (0.0, False),
    "rk2": (0.5, False),
    "exact": (0.5, True),
}
METHODS: tuple[Method, ...] = tuple(METHOD_FLAGS)
"""Every ``Method``, in order of accuracy."""
TAYLOR_LIMIT = 1.0 / 16.0


def check_method(method: object) -> Method:
    """``method`` itself if it names an integration method; ``ValueError`` listing them if not."""
    for known in METHODS:
        if method == known:
            return known
    raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")


def method_flags(method: object) -> tuple[float, bool]:
    """``(weight, chord)`` of the method named ``method``, checked: the one place a method's
    name becomes its flags (the C core mirrors the table, indexed as ``METHODS``)."""
    return METHOD_FLAGS[check_method(method)]


def sinc_cos_small(u: float) -> tuple[float, float]:
    """``(sin(u) / u, cos u)`` by their Taylor forms, for ``|u|`` below ``TAYLOR_LIMIT``
    (branch-free, so a compiled loop over many ``u`` can be made vector instructions)."""
    u2 = u * u
    # Multiplying by reciprocals (not dividing) keeps it to a few multiplies when compiled.
    sinus = 1.0 - u2 * (1 / 6) * (
        1.0 - u2 * (1 / 20) * (1.0 - u2 * (1 / 42) * (1.0 - u2 * (1 / 72)))
    )
    cosine = 1.0 - u2 * 0.5 * (1.0 - u2 * (1 / 12) * (1.0 - u2 * (1 / 30) * (1.0 - u2 * (1 / 56))))
    return sinus, cosine


def sinc(u: float) -> float:
    """``sin(u) / u``, 1 at 0: the Taylor form below ``TAYLOR_LIMIT``, libm above."""
    if abs(u) >= TAYLOR_LIMIT:
        return math.sin(u) / u
    return sinc_cos_small(u)[0]


def sinc_cos(u: float) -> tuple[float, float]:
    """``(sin(u) / u, cos u)``, both by the rule of ``sinc``."""
    if abs(u) >= TAYLOR_LIMIT:
        return math.sin(u) / u, math.cos(u)
    return sinc_cos_small(u)


def sinc_derivative(u: float) -> float:
    """d/du of ``sin(u) / u``, with its Taylor form near 0 where the closed form cancels."""
    if abs(u) < 0.05:
        u2 = u * u
        return -u / 3.0 * (1.0 - u2 / 10.0 * (1.0 - u2 / 28.0 * (1.0 - u2 / 54.0)))
    return (u * math.cos(u) - math.sin(u)) / (u * u)


# wheel_move's arithmetic holds for arrays as it is: the batch layer and ``desaturate`` call it
# with arrays of any array-API library (``Values``), the scalar paths with floats.
Values = Any


def wheel_move(
    r_left: Values, r_right: Values, track: Values, offset: Values, dl: Values, dr: Values
) -> tuple[Values, Values, Values]:
    """``(forward, sideways, turn)``: m, m, rad, from wheel-angle increments ``dl``, ``dr``
    (rad; or, as forward kinematics, wheel velocities to ``(vx, vy, omega)``), floats or
    arrays that broadcast."""
    left, right = r_left * dl, r_right * dr
    turn = (right - left) / track
    return 0.5 * (left + right), offset * turn, turn


def body_move(
    forward: float, sideways: float, turn: float, weight: float, chord: bool, heading: float = 0.0
) -> tuple[float, float]:
    """The move ``(dx, dy)`` by the method's flags: in the frame at the step's start, or in
    the world when the ``heading`` (rad) at the start is given."""
    angle = heading + weight * turn
    scale = sinc(0.5 * turn) if chord else 1.0
    c, s = math.cos(angle), math.sin(angle)
    return scale * (c * forward - s * sideways), scale * (s * forward + c * sideways)


def twist_move(
    vx: float, vy: float, omega: float, dt: float, weight: float, chord: bool
) -> tuple[float, float, float]:
    """``(dx, dy, dtheta)`` of a body twist held for ``dt`` s, by the method's flags (the
    move is linear in the travel: the velocity's move, times ``dt``)."""
    turn = omega * dt
    dx, dy = body_move(vx, vy, turn, weight, chord)
    return dx * dt, dy * dt, turn


def move_jacobians(
    forward: float, offset: float, turn: float, weight: float, chord: bool, heading: float
) -> tuple[float, float, tuple[float, float], tuple[float, float]]:
    """The world move ``(dx, dy)`` of ``body_move(forward, offset * turn, turn, ...)`` from
    the ``heading`` (rad), and its derivatives ``(d/dforward, d/dturn)``, each ``(x, y)``.

    The heading's own derivative is ``(-dy, dx)``; the sideways travel of a reference point
    ``offset`` m ahead of the axle follows the turn.
    """
    angle = heading + weight * turn
    ca, sa = math.cos(angle), math.sin(angle)
    sideways = offset * turn
    gx, gy = ca * forward - sa * sideways, sa * forward + ca * sideways
    scale, slope = 1.0, 0.0
    if chord:
        scale, slope = sinc(0.5 * turn), 0.5 * sinc_derivative(0.5 * turn)
    by_turn = (
        slope * gx + scale * (-sa * offset - gy * weight),
        slope * gy + scale * (ca * offset + gx * weight),
    )
    return scale * gx, scale * gy, (scale * ca, scale * sa), by_turn
