"""The package's layering: no import circle among diffdrive's modules, not even through an
import made inside a function (which is how an upward import hides), and the floors the
README's layout names kept."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SOURCE = Path(__file__).resolve().parent.parent / "src"


def _modules() -> dict[str, Path]:
    found = {}
    for path in (SOURCE / "diffdrive").rglob("*.py"):
        parts = list(path.relative_to(SOURCE).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def _imports(tree: ast.Module, modules: dict[str, Path]) -> set[str]:
    """The diffdrive modules a module imports, anywhere in it but under ``TYPE_CHECKING``."""
    found: set[str] = set()
    hidden = {
        id(inner)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
        for inner in ast.walk(node)
    }
    for node in ast.walk(tree):
        if id(node) in hidden:
            continue
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names if alias.name in modules)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                submodule = f"{node.module}.{alias.name}"
                if submodule in modules:
                    found.add(submodule)
                elif node.module in modules:
                    found.add(node.module)
    return found


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    modules = _modules()
    return {
        name: _imports(ast.parse(path.read_text(encoding="utf-8")), modules) - {name}
        for name, path in modules.items()
    }


def test_no_module_imports_one_that_imports_it_back(graph):
    """A depth-first search over every import finds no circle."""
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(module: str) -> None:
        state[module] = 1
        path.append(module)
        for other in sorted(graph[module]):
            if state.get(other) == 1:
                circle = [*path[path.index(other) :], other]
                pytest.fail("import circle: " + " -> ".join(circle))
            if not state.get(other):
                visit(other)
        path.pop()
        state[module] = 2

    for module in sorted(graph):
        if not state.get(module):
            visit(module)


# The floors of the layout on the design page (docs/guides/design.md), bottom up: a module
# imports from its own floor or below.
FLOORS = [
    ("diffdrive._step", "diffdrive._validate", "diffdrive.angles", "diffdrive.types",
     "diffdrive._arrays", "diffdrive._stats", "diffdrive.errors", "diffdrive.atomic",
     "diffdrive._optional", "diffdrive._progress", "diffdrive._lazy"),
    ("diffdrive.se2", "diffdrive.model", "diffdrive.skid_steer", "diffdrive.integrate",
     "diffdrive.encoders", "diffdrive.sensor_noise", "diffdrive.batch", "diffdrive.backends"),
    ("diffdrive.simulation", "diffdrive.trajectory", "diffdrive.montecarlo"),
    ("diffdrive.estimation", "diffdrive.evaluation", "diffdrive.dynamics", "diffdrive.io",
     "diffdrive.sensors"),
    ("diffdrive.calibration", "diffdrive.control", "diffdrive.distributed"),
    ("diffdrive.export", "diffdrive.plot", "diffdrive.demo", "diffdrive.learn"),
    ("diffdrive.cli", "diffdrive.__main__", "diffdrive"),
]  # fmt: skip


def _floor(module: str) -> int:
    for level, names in enumerate(FLOORS):
        if any(module == name or module.startswith(name + ".") for name in names):
            return level
    raise AssertionError(f"{module} is on no floor: add it to FLOORS")


def test_no_module_imports_from_a_floor_above_its_own(graph):
    upward = [
        f"{name} (floor {_floor(name)}) imports {other} (floor {_floor(other)})"
        for name, imported in graph.items()
        for other in imported
        if name != "diffdrive" and _floor(other) > _floor(name)
    ]
    assert not upward, "\n".join(upward)
