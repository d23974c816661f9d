"""Where the tests find the shared recordings: ``../shared/data`` beside the checkout."""

from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def data_folder(name: str) -> Path:
    """The folder ``name`` under the shared data; fails (never skips) when it is missing."""
    folder = DATA / name
    if not folder.is_dir():
        pytest.fail(f"the recordings are expected in {folder}; check out shared/ beside the repo")
    return folder
