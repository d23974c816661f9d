"""The documentation site built as ``make docs`` builds it (strict: a broken link, a missing
reference or any warning fails), then served on a local port and used in a real headless
Chromium as a reader would: the home page, the navigation into a guide and the reference, and
a search; no console error and no request off this machine on the way. Each run leaves
screenshots in ``build/``."""

import os
import subprocess
import sys
import time

import pytest

import headless
from docs_pages import ROOT

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The site as ``make docs`` builds it, strict: its folder and the build's messages."""
    site = tmp_path_factory.mktemp("site")
    build = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=ROOT, capture_output=True, text=True, env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )  # fmt: skip
    return site, build


def test_the_site_builds_in_strict_mode_without_a_warning(built):
    site, build = built
    assert build.returncode == 0, build.stderr
    assert "WARNING" not in build.stderr, build.stderr
    page = site / "reference" / "calibration" / "index.html"
    assert "calibrate_to_reference" in page.read_text()


def test_every_name_a_face_exports_has_an_entry_on_its_page(built):
    """As a reader finds them: each name of each face's ``__all__`` (but the submodules, which
    have their own pages) is an entry of that face's reference page, with its own anchor."""
    import importlib
    import re

    from test_docs import FACES, _reference_page

    site, build = built
    assert build.returncode == 0, build.stderr
    missing = []
    for face in FACES:
        page = _reference_page(face)[: -len(".md")]
        html = site / (page[: -len("index")] if page.endswith("index") else page + "/")
        anchors = set(re.findall(r'id="([^"]+)"', (html / "index.html").read_text()))
        for name in getattr(importlib.import_module(face), "__all__", ()):
            if f"{face}.{name}" not in FACES and f"{face}.{name}" not in anchors:
                missing.append(f"{face}.{name}")
    assert missing == [], "\n".join(missing)


@pytest.fixture(scope="module")
def served(built):
    """The built site served by ``http.server``: yields its address."""
    chromium = headless.chromium("the documentation site")
    site, build = built
    assert build.returncode == 0, build.stderr
    port = headless.free_port()
    command = [sys.executable, "-m", "http.server", str(port), "--bind", "127.0.0.1"]
    with headless.serving(
        command, port, lambda: "", cwd=site, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    ) as address:
        yield address, chromium


def test_a_reader_follows_the_navigation_and_finds_a_name_by_search(served):
    from playwright.sync_api import expect, sync_playwright

    address, chromium = served
    errors: list[str] = []
    outside: list[str] = []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=chromium, args=headless.CHROMIUM_ARGS)
        tab = browser.new_page(viewport={"width": 1400, "height": 1000})
        tab.on("console", lambda message: message.type == "error" and errors.append(message.text))
        tab.on("pageerror", lambda error: errors.append(str(error)))
        tab.on("request", lambda request: headless.note_outside(request.url, outside))
        tab.goto(address)
        expect(tab.locator("h1").first).to_contain_text("diffdrive")
        headless.SCREENSHOTS.mkdir(exist_ok=True)
        tab.screenshot(path=headless.SCREENSHOTS / "docs-home.png")
        # Into a guide by the navigation, and on to the reference.
        tab.locator("nav.md-nav--primary a", has_text="A bag to a pose").first.click()
        expect(tab.locator("h1").first).to_contain_text("A bag to a pose")
        assert tab.locator("img").count() >= 1
        tab.goto(address + "reference/calibration/")
        expect(tab.locator("h1").first).to_contain_text("diffdrive.calibration")
        assert tab.get_by_text("calibrate_to_reference", exact=True).count() >= 1
        # A search for a public name lands on its reference page.
        tab.locator("label.md-search__icon, .md-search__input").first.click()
        field = tab.locator("input.md-search__input")
        results = tab.locator(".md-search-result__item a")
        # The index loads in a web worker, and a query typed before it is ready is dropped:
        # type it again until the results come (a busy machine takes seconds).
        deadline = time.monotonic() + 60
        while results.count() == 0 and time.monotonic() < deadline:
            field.fill("")
            field.press_sequentially("calibrate_to_reference")
            tab.wait_for_timeout(1000)
        expect(results.first).to_be_visible()
        targets = results.evaluate_all("links => links.map(link => link.href)")
        assert any("reference/calibration/" in target for target in targets), targets
        tab.screenshot(path=headless.SCREENSHOTS / "docs-search.png")
        browser.close()
    assert errors == []
    assert outside == []
