"""Optional parts: a module imported where it is needed, or an ``ImportError`` that names the
extra to install (``make test`` installs every extra; ``make demo`` only ``plot``)."""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["optional"]


def optional(module: str, extra: str, what: str) -> ModuleType:
    """``module`` (``"scipy.optimize"``), or ``ImportError``: ``what`` needs it, ``pip install
    'diffdrive[extra]'``."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError:
        package = module.split(".")[0]
        raise ImportError(
            f"{what} needs {package}: pip install 'diffdrive[{extra}]' (or make test, which "
            "installs every extra)"
        ) from None
