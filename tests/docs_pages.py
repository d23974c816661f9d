"""The documentation's pages, for the tests that hold what they say: the README (the front
page) and every Markdown page of the site under ``docs/``."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"


def pages() -> dict[Path, str]:
    """Each page's text by its path: the README first, then ``docs/`` in order."""
    paths = [README, *sorted(DOCS.rglob("*.md"))]
    return {path: path.read_text() for path in paths}


def text(flat: bool = False) -> str:
    """Every page's text together; ``flat``: its whitespace runs made one space, as a figure
    quoted across a line break is found."""
    joined = "\n\n".join(pages().values())
    return " ".join(joined.split()) if flat else joined


def page(name: str) -> str:
    """One page of ``docs/`` by its path there (``guides/bags.md``)."""
    return (DOCS / name).read_text()


def name(path: Path) -> str:
    """A page's path from the clone's root: its name in a test's id."""
    return str(path.relative_to(ROOT))
