"""Optional libraries of the test extra, imported when a test first uses one.

Collecting the suite then does not pay for JAX and PyTorch (about 2 s together); a test that uses
a missing library is skipped with the reason, as ``pytest.importorskip`` at module level would.
"""

from __future__ import annotations

import types

import pytest


class Library:
    """A stand-in for the module ``name``: attribute access imports it (or skips the test)."""

    def __init__(self, name: str) -> None:
        self._name = name

    def module(self) -> types.ModuleType:
        return pytest.importorskip(self._name, reason=f"{self._name} is part of the test extra")

    def __getattr__(self, attribute: str):
        if attribute.startswith("_"):  # pytest's probes at collection (_mock_name, __wrapped__)
            raise AttributeError(attribute)
        return getattr(self.module(), attribute)
