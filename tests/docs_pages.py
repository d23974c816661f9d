"""The documentation's pages, for the tests that hold what they say: the README (the front
page) and every Markdown page of the site under ``docs/``."""

from __future__ import annotations

import re
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


# A figure: a number that is not part of a word, a path, a version or a date (a ratio's
# trailing x, 1.98x, is not a word).
FIGURE = re.compile(
    r"(?<![\w.\-/#^])([-+]?)(\d{1,3}(?:,\d{3})+|\d+)(\.\d+)?(e[-+]?\d+)?(?!\.\d|(?!x\b)\w)"
)
# Words before a number that make it a name, not a figure: the notes' pages and equations,
# versions of the tools, a figure's or a section's number, a standard's.
NAMING = re.compile(r"(eqs?\.|[Ss]eeds?|Python|NumPy|ROS|evo|version|[Ss]ection|[Ff]ig\.|Std) *$")


def _figure(match: re.Match) -> str:
    sign, whole, fraction, exponent = match.groups()
    exponent = f"e{int(exponent[1:])}" if exponent else ""  # 2.48e+08 as 2.48e8
    return ("-" if sign == "-" else "") + whole.replace(",", "") + (fraction or "") + exponent


def figures_in(text: str, rounded: bool = False) -> set[str]:
    """Every number ``text`` holds, written as ``quoted`` writes them, with and without
    its sign; ``rounded``: each also rounded to every fewer number of decimals (a page may
    quote 0.091 m where its block prints 0.0907 m)."""
    text = re.sub(r"(?<=\d)_(?=\d{3})", "", text)  # Python's 10_000
    found = {_figure(match) for match in FIGURE.finditer(text)}
    if rounded:
        for figure in list(found):
            if "." in figure and "e" not in figure:
                decimals = len(figure.split(".")[1])
                found |= {f"{float(figure):.{d}f}" for d in range(decimals)}
            if float(figure):  # 0.00013 quoted as 1.3e-4
                for digits in range(4):
                    mantissa, exponent = f"{float(figure):.{digits}e}".split("e")
                    found.add(f"{mantissa}e{int(exponent)}")
    return found | {figure.lstrip("-") for figure in found}


def prose(text: str) -> str:
    """A page without its code blocks, inline code, formulas, comments and link targets: the
    text a reader takes figures from, its lines numbered as the page's."""
    for pattern in (r"```.*?```", r"<!--.*?-->", r"\$\$.*?\$\$", r"`[^`]*`", r"\$[^$\n]*\$"):
        text = re.sub(pattern, lambda found: "\n" * found.group(0).count("\n"), text, flags=re.S)
    return re.sub(r"\]\([^)]*\)", "]", text)


def quoted(text: str) -> list[tuple[int, str, str]]:
    """The figures a page quotes in its prose and tables: (line of the prose, the figure with
    its thousands' commas dropped, the words around it). Headings, years, single digits
    (counts such as "two runs" written as numbers), zero-padded names (the notes' pages) and
    the numbers ``NAMING`` marks are left out."""
    found = []
    for number, line in enumerate(prose(text).splitlines(), 1):
        if line.startswith("#"):
            continue
        for match in FIGURE.finditer(line):
            figure = _figure(match)
            if (
                re.fullmatch(r"-?\d|(19|20)\d\d", figure)
                or re.fullmatch(r"0\d+", match.group(2))
                or NAMING.search(line[: match.start()])
            ):
                continue
            found.append((number, figure, line[max(0, match.start() - 40) : match.end() + 20]))
    return found
