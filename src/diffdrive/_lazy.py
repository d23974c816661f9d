"""Names a package loads on first use (PEP 562), so that importing it stays light."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable


def attach(
    package: str, names: dict[str, str], modules: tuple[str, ...] = ()
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for ``package``: each of ``names`` (an attribute: the
    submodule, relative, that defines it) imported from its submodule when first reached,
    and kept; each of ``modules`` (submodules) imported when first reached."""
    module = sys.modules[package]

    def lookup(name: str) -> object:
        if name in names:
            value = getattr(importlib.import_module(f"{package}.{names[name]}"), name)
            setattr(module, name, value)  # the next access is a plain lookup
            return value
        if name in modules:
            return importlib.import_module(f"{package}.{name}")
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def listing() -> list[str]:
        return sorted({*vars(module), *names, *modules})

    return lookup, listing
