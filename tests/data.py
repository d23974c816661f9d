"""Where the tests find the shared recordings: ``../shared/data`` beside the checkout.

Nothing here touches the disk at import: ``DATA / name`` is a path for collection (a
parametrisation may read a table when it is there), and ``data_folder(name)`` is the check at
use: a missing folder fails the test in CI (``CI`` set) and skips it elsewhere, naming the path.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def data_folder(name: str) -> Path:
    """The folder ``name`` under the shared data, checked at use (see the module)."""
    folder = DATA / name
    if not folder.is_dir():
        message = f"the recordings are expected in {folder}; check out shared/ beside the repo"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    return folder


def rows_or_missing(folder: str, rows) -> list:
    """``rows()`` (a parametrisation read from the data) when ``folder`` is there, else one
    parameter whose test fails or skips at use through ``data_folder``."""
    if (DATA / folder).is_dir():
        return rows()
    return [pytest.param(None, id=f"{folder}-missing")]
