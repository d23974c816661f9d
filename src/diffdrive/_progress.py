"""Progress bars on standard error, where tqdm is installed (the ``plot`` extra brings it):
without it the work runs the same, silently."""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["progress_bar"]


def progress_bar(shown: bool, **options: Any) -> Any:
    """A tqdm bar on standard error with ``options`` (``total``, ``desc``, ``unit``), or None
    when not ``shown`` or tqdm is not installed."""
    if not shown:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(file=sys.stderr, **options)
