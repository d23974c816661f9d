"""One integration step over arrays: ``diffdrive.integrate`` for ``(..., 3)`` poses and twists."""

from __future__ import annotations

from typing import Any

from diffdrive._arrays import components, floating, leading_shape, namespace
from diffdrive.batch.se2 import TWIST, compose, exp
from diffdrive.integrate import Method, check_method

__all__ = ["delta", "step"]


def delta(twists: object, dt: object, method: Method = "exact") -> Any:
    """Body-frame pose changes ``(..., 3)`` over steps of ``dt`` s with ``twists`` held."""
    check_method(method)
    if method == "exact":
        return exp(twists, dt)
    xp = namespace(twists, dt)
    v = components(xp, twists, "twists", TWIST)
    step = floating(xp, dt, "dt", like=v)
    leading_shape(twists=tuple(v.shape[:-1]), dt=tuple(step.shape))
    turn = v[..., 2] * step
    dx, dy = v[..., 0] * step, v[..., 1] * step
    if method == "euler":
        return xp.stack([dx, dy, turn], axis=-1)
    c, s = xp.cos(0.5 * turn), xp.sin(0.5 * turn)
    return xp.stack([c * dx - s * dy, s * dx + c * dy, turn], axis=-1)


def step(poses: object, twists: object, dt: object, method: Method = "exact") -> Any:
    """Poses ``(..., 3)`` after one step of ``dt`` s with the body ``twists`` held constant."""
    return compose(poses, delta(twists, dt, method))
