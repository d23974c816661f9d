"""Names a package loads on first use (PEP 562), so that importing it stays light."""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Callable
from typing import cast


class _Package(types.ModuleType):
    """A package whose submodule, once imported, does not hide the name of the same name it
    defines (``control.follow``, the function, not the module): an import sets the parent's
    attribute to the submodule, which an eager ``from .follow import follow`` would undo."""

    _shadowed: frozenset[str] = frozenset()

    def __setattr__(self, name: str, value: object) -> None:
        submodule = f"{self.__name__}.{name}"
        if name in self._shadowed and getattr(value, "__name__", None) == submodule:
            value = getattr(value, name)
        super().__setattr__(name, value)


def attach(
    package: str, names: dict[str, str], modules: tuple[str, ...] = ()
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for ``package``: each of ``names`` (an attribute: the
    submodule, relative, that defines it) imported from its submodule when first reached,
    and kept; each of ``modules`` (submodules) imported when first reached."""
    module = cast(_Package, sys.modules[package])
    module.__class__ = _Package
    module._shadowed = frozenset(name for name, source in names.items() if name == source)

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
