"""One integration step over arrays: ``diffdrive.integrate`` for ``(..., 3)`` poses and twists."""

from __future__ import annotations

from typing import Any

from diffdrive.batch.se2 import compose, moves
from diffdrive.integrate import Method, check_method

__all__ = ["delta", "step"]


def delta(twists: object, dt: object, method: Method = "exact") -> Any:
    """Body-frame pose changes ``(..., 3)`` over steps of ``dt`` s with ``twists`` held."""
    return moves(twists, dt, check_method(method))


def step(poses: object, twists: object, dt: object, method: Method = "exact") -> Any:
    """Poses ``(..., 3)`` after one step of ``dt`` s with the body ``twists`` held constant."""
    return compose(poses, delta(twists, dt, method))
