"""Every figure a page quotes is held by something that fails when the figure goes stale:

- the page's own ``text`` blocks, which ``test_docs.py`` compares with what its code prints;
- the record of a script the page names (``examples/records/NAME.txt``,
  ``benchmarks/records/NAME.txt``: what ``python examples/NAME.py`` printed, written by
  ``benchmarks/record.py``; the example tests hold each example's record against a fresh run
  to its last printed digit or 0.5 %), or that script's own settings;
- a test file the page names (``tests/test_NAME.py``), which asserts it;
- or the ledger, ``tests/figures_ledger.txt``: a figure the page gives rather than measures
  (a setting of a worked example, a default or constant of the library, a target, a peer's or
  a paper's figure, a reading of a recording), each with why.

A figure found nowhere fails the test with its page, line and words; an entry of the ledger
whose figure a page no longer quotes fails too, so that the ledger cannot go stale."""

from __future__ import annotations

import re

import docs_pages
from docs_pages import DOCS, ROOT

LEDGER = ROOT / "tests" / "figures_ledger.txt"


def _ledger() -> dict[str, dict[str, str]]:
    """The ledger by page (its path under docs/, or README.md) and figure: why it is given.
    A line is ``PAGE: FIGURE: why``; ``#`` starts a comment."""
    entries: dict[str, dict[str, str]] = {}
    for number, line in enumerate(LEDGER.read_text().splitlines(), 1):
        if not line.strip() or line.startswith("#"):
            continue
        page, figure, why = (part.strip() for part in line.split(":", 2))
        assert why, f"{LEDGER.name}, line {number}: say why {figure} is given on {page}"
        entries.setdefault(page, {})[figure] = why
    return entries


def _holders(text: str) -> set[str]:
    """The figures a page's blocks, the scripts' records and settings and the tests it names
    hold."""
    held: set[str] = set()
    for block in re.findall(r"```text\n(.*?)```", text, re.S):
        held |= docs_pages.figures_in(block, rounded=True)
    for folder, name in set(re.findall(r"\b(examples|benchmarks)/(\w+)\.py", text)):
        script, record = ROOT / folder / f"{name}.py", ROOT / folder / "records" / f"{name}.txt"
        if script.is_file():  # not the page's "benchmarks/NAME.py", which names none
            held |= docs_pages.figures_in(script.read_text(), rounded=True)
        if record.is_file():
            held |= docs_pages.figures_in(record.read_text(), rounded=True)
    for name in set(re.findall(r"\b(test_\w+)\.py", text)):
        held |= docs_pages.figures_in((ROOT / "tests" / f"{name}.py").read_text())
    return held


def _key(path) -> str:
    return "README.md" if path == docs_pages.README else str(path.relative_to(DOCS))


def test_every_figure_a_page_quotes_is_held():
    ledger = _ledger()
    loose = []
    for path, text in docs_pages.pages().items():
        held = _holders(text) | set(ledger.get(_key(path), {}))
        for line, figure, words in docs_pages.quoted(text):
            if figure not in held and figure.lstrip("-") not in held:
                loose.append(f"{_key(path)}, line {line}: {figure} in '{words}'")
    assert loose == [], f"{len(loose)} figures nothing holds:\n" + "\n".join(loose)


def test_the_ledger_names_only_figures_the_pages_quote():
    pages = {_key(path): text for path, text in docs_pages.pages().items()}
    stale = []
    for page, figures in _ledger().items():
        assert page in pages, f"{LEDGER.name} names {page}, which is no page"
        quoted = {figure for _, figure, _ in docs_pages.quoted(pages[page])}
        stale += [f"{page}: {figure}" for figure in figures if figure not in quoted]
    assert stale == [], stale


def test_every_record_says_when_where_and_how_it_was_taken():
    """A record's first line: the command, the date (UTC) and the machine."""
    from records import HEADER

    records = sorted(ROOT.glob("examples/records/*.txt")) + sorted(
        ROOT.glob("benchmarks/records/*.txt")
    )
    assert records
    for path in records:
        first = path.read_text().splitlines()[0]
        assert re.fullmatch(HEADER, first), (path.name, first)
        script = ROOT / path.parent.parent.name / f"{path.stem}.py"
        assert script.is_file(), f"{path} records {script.name}, which is gone"


def test_a_record_holds_each_number_to_its_last_digit_or_half_a_percent():
    """The comparison the example tests make: the record's own lines pass; a number moved
    past its last printed digit and 0.5 %, a word changed or a line gone fails."""
    import pytest

    from records import assert_as_recorded, record

    lines = record("examples", "gyro_slip")
    printed = "\n".join(lines)
    assert_as_recorded("gyro_slip", printed)
    assert_as_recorded("gyro_slip", printed.replace("13.21 m", "13.22 m"))  # the last digit
    for changed in (
        printed.replace("13.21 m", "13.35 m"),
        printed.replace("fused    0.36 m", "fused    0.38 m"),
        printed.replace("largest position", "mean position"),
        "\n".join(lines[1:]),
    ):
        with pytest.raises(AssertionError):
            assert_as_recorded("gyro_slip", changed)


def test_a_figure_is_held_by_the_block_or_record_it_rounds():
    """0.56 m and 33 % are what a block printing 0.5588 m and 33.2 % shows; 0.57 m and a
    figure in inline code, a link or a formula are not the page's figures; a record the page
    names holds what its script printed (95 mm, and 1.096 as 1.10 or 1.1e0)."""
    page = (
        "Fused within 0.56 m and 33 % flagged, not 0.57 m; `k = 0.99` and $x^{12}$ are code.\n"
        "Seed 004's eq. 13.14; [the run](runs/2020.md); 95 mm and 1.10 times the plan in\n"
        "`python examples/mppi_obstacles.py`.\n"
        "```text\nerror 0.5588 m, 33.2% flagged\n```\n"
    )
    held = _holders(page)
    assert [figure for _, figure, _ in docs_pages.quoted(page)] == [
        "0.56",
        "33",
        "0.57",
        "95",
        "1.10",
    ]
    assert {"0.56", "33", "95", "1.10", "1.1e0"} <= held
    assert "0.57" not in held
