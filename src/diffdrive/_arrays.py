"""Array coercion and shape checks for the batch layer.

Batch kernels are written against the Python array API: an array of another library (JAX,
PyTorch, CuPy, array-api-strict, ...) is computed in that library, on its device, through
``array-api-compat``; anything else becomes a NumPy array. Floating dtypes are kept; integers
become float64.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

import array_api_compat
import numpy as np


def namespace(*arrays: object) -> ModuleType:
    """The array library of the first input that is an array of a library other than NumPy
    (its array-API namespace); NumPy itself otherwise."""
    for array in arrays:
        if isinstance(array, np.ndarray | np.generic):
            continue
        if array_api_compat.is_array_api_obj(array):
            return array_api_compat.array_namespace(array)
    return np


def device(array: Any) -> Any:
    """The device ``array`` lives on (``"cpu"`` for NumPy)."""
    return array_api_compat.device(array)


def floating(xp: ModuleType, value: object, name: str, like: Any = None) -> Any:
    """``value`` as a real floating array of ``xp`` (integers become float64).

    A plain Python number takes the dtype of the array ``like`` when one is given, so that
    ``dt=0.1`` does not turn float32 data into float64.
    """
    if like is not None and isinstance(value, (int, float)) and not isinstance(value, bool):
        return xp.asarray(value, dtype=like.dtype, device=device(like))
    to_array = getattr(value, "to_array", None)
    if callable(to_array) and not array_api_compat.is_array_api_obj(value):
        value = to_array()  # a Pose, Twist or WheelVelocities: its numbers, in field order
    array = xp.asarray(value)
    if xp is np and not array.dtype.isnative:  # big-endian data: compiled kernels want native
        array = array.astype(array.dtype.newbyteorder("="))
    if not xp.isdtype(array.dtype, "real floating"):
        if not xp.isdtype(array.dtype, ("integral", "bool")):
            raise TypeError(f"{name} must hold real numbers, got dtype {array.dtype}")
        array = xp.astype(array, xp.float64)
    return array


def components(xp: ModuleType, value: object, name: str, labels: str) -> Any:
    """``value`` as a floating array whose last axis holds the comma-separated ``labels``."""
    array = floating(xp, value, name)
    size = labels.count(",") + 1
    if array.ndim == 0 or array.shape[-1] != size:
        raise ValueError(
            f"{name} must have shape (..., {size}) [{labels}], got {tuple(array.shape)}"
        )
    return array


def leading_shape(**named: tuple[int, ...]) -> tuple[int, ...]:
    """The broadcast of the named leading shapes; ``ValueError`` naming them if impossible."""
    try:
        return np.broadcast_shapes(*named.values())
    except ValueError:
        listed = ", ".join(f"{name} {shape}" for name, shape in named.items())
        raise ValueError(f"leading axes do not broadcast: {listed}") from None


def finite_positive_dt(xp: ModuleType, dt: object, like: Any) -> Any:
    """``dt`` as a floating array (see ``floating``); ``ValueError`` unless finite and > 0."""
    array = floating(xp, dt, "dt", like)
    if not bool(xp.all(xp.isfinite(array) & (array > 0))):
        raise ValueError(f"dt must be finite and > 0, got {dt!r}")
    return array
