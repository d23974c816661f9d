"""Hypothesis strategies shared by the tests: finite reals, batch shapes, robot geometry."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

# The batch shapes the issue names: a scalar, a singleton, a vector, and broadcasting axes.
BATCH_SHAPES = [(), (1,), (7,), (3, 1, 2)]


def reals(bound: float = 10.0) -> st.SearchStrategy[float]:
    """Finite floats in [-bound, bound]."""
    return st.floats(-bound, bound, allow_nan=False, allow_infinity=False)


def batch_of(size: int, bound: float = 10.0, shapes=None) -> st.SearchStrategy[np.ndarray]:
    """float64 arrays of shape ``(*leading, size)`` for a leading shape from ``shapes``."""
    return st.sampled_from(shapes or BATCH_SHAPES).flatmap(
        lambda shape: hnp.arrays(np.float64, (*shape, size), elements=reals(bound))
    )


def geometry() -> st.SearchStrategy[dict[str, float]]:
    """Keyword arguments of a plausible ``DiffDrive``, unequal wheels and any axle offset."""
    return st.fixed_dictionaries(
        {
            "left_wheel_radius": st.floats(0.01, 0.5),
            "right_wheel_radius": st.floats(0.01, 0.5),
            "track_width": st.floats(0.05, 2.0),
            "axle_offset": st.floats(-0.5, 0.5),
        }
    )
