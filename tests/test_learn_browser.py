"""``diffdrive learn`` served on a local port and used in a real headless Chromium, as a student
would: move a slider, type an answer, and check the page's numbers against the library.

Needs Debian's ``chromium`` (``apt-get install chromium``); ``.ci/run`` installs it. Without it
these tests are skipped with a message that says so, except under CI, where they fail. Each
run leaves screenshots in ``build/`` for a person to look at.
"""

import subprocess
import sys

import pytest

import headless
from diffdrive import DiffDrive
from diffdrive.learn import lessons

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """``diffdrive learn --no-browser`` on a free local port: yields its address."""
    chromium = headless.chromium("the learning page")
    port = headless.free_port()
    log = tmp_path_factory.mktemp("learn") / "server.log"
    command = [sys.executable, "-m", "diffdrive", "learn", "--no-browser", "--port", str(port)]
    with (
        log.open("w") as out,
        headless.serving(
            command, port, log.read_text, stdout=out, stderr=subprocess.STDOUT
        ) as address,
    ):
        yield address, chromium


@pytest.fixture(scope="module")
def page(served):
    from playwright.sync_api import sync_playwright

    address, chromium = served
    outside: list[str] = []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=chromium, args=headless.CHROMIUM_ARGS)
        tab = browser.new_page(viewport={"width": 1400, "height": 1000})
        tab.on("request", lambda request: headless.note_outside(request.url, outside))
        tab.goto(address)
        tab.get_by_test_id("dd-exact-theta").wait_for(timeout=90_000)  # the last cell has run
        tab.outside_requests = outside
        yield tab
        browser.close()


def number(tab, test_id: str) -> float:
    return float(tab.get_by_test_id(f"dd-{test_id}").inner_text())


def _images(tab) -> list[str]:
    return tab.locator("img").evaluate_all("images => images.map(image => image.src)")


def test_the_turning_radius_follows_a_slider_and_matches_the_library(page):
    from playwright.sync_api import expect

    radius, track = number(page, "radius"), number(page, "track")
    right = page.get_by_role("slider").nth(3)  # radius, track, left, right
    before = number(page, "right")
    assert float(right.get_attribute("aria-valuenow")) == before
    pictures = _images(page)
    right.focus()
    page.keyboard.press("ArrowRight")
    page.keyboard.press("ArrowRight")  # two steps of 0.5 rad/s
    expect(page.get_by_test_id("dd-right")).to_have_text(f"{before + 1.0:g}")
    robot = DiffDrive(radius, track)
    wheels = (number(page, "left"), before + 1.0)
    expect(page.get_by_test_id("dd-turning-radius")).to_have_text(
        lessons.fmt(robot.turning_radius(wheels))
    )
    assert number(page, "omega") == pytest.approx(robot.to_twist(wheels).omega, rel=1e-5)
    after = _images(page)
    assert after[0] != pictures[0], "the robot's picture did not change with the wheel"
    right.blur()  # no slider tooltip in the picture
    headless.SCREENSHOTS.mkdir(exist_ok=True)
    page.screenshot(path=headless.SCREENSHOTS / "learn-section-1.png")
    assert page.outside_requests == [], "the page reached beyond this machine"


def test_check_my_answer_matches_the_library(page):
    from playwright.sync_api import expect

    fields = page.locator("input")  # r, track, wheels, T, k, x0, y0, theta0
    typed = {0: "0.1", 1: "0.5", 2: "2", 3: "3", 4: "0.5", 5: "4", 6: "1", 7: "-1", 8: "0.3"}
    for index, text in typed.items():
        fields.nth(index).fill(text)
        fields.nth(index).press("Tab")
    page.locator("select").nth(1).select_option(label="full track (2L)")
    page.get_by_role("button", name="Check my answer").click()
    want = lessons.check_answer(0.1, 0.5, "full", 2.0, 3.0, 0.5, 4, (1.0, -1.0, 0.3))
    expect(page.get_by_test_id("dd-exact-theta")).to_have_text(lessons.fmt(want.exact.theta))
    expect(page.get_by_test_id("dd-euler-x")).to_have_text(lessons.fmt(want.poses[-1].x))
    assert number(page, "euler-y") == pytest.approx(want.poses[-1].y, rel=1e-5)
    assert number(page, "exact-x") == pytest.approx(want.exact.x, rel=1e-5)
    assert number(page, "check-omega") == pytest.approx(want.twist.omega, rel=1e-5)
    page.set_viewport_size({"width": 1400, "height": 5600})  # the whole page, for a person
    page.wait_for_timeout(500)
    page.screenshot(path=headless.SCREENSHOTS / "learn-page.png")
    print(f"screenshots: {headless.SCREENSHOTS}/learn-page.png, learn-section-1.png")
    assert page.outside_requests == [], "the page reached beyond this machine"
