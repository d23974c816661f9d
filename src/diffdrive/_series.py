"""Where the Taylor form of sinc takes over, per floating-point precision.

``sinc(u) = sin(u)/u`` is evaluated as ``1 - u**2/6 + u**4/120`` below a threshold chosen so
the first dropped term, ``u**6/5040``, is under half an ulp of 1. Above it ``sin(u)/u`` is
accurate to about one ulp, so the two forms meet within rounding: no jump at the threshold.
"""

from __future__ import annotations


def sinc_threshold(eps: float) -> float:
    """The |u| below which the Taylor form of sin(u)/u is used, for machine epsilon ``eps``."""
    return (2520.0 * eps) ** (1.0 / 6.0)
