"""The leaderboard's pages in a real headless Chromium (Playwright, with Debian's chromium).

Screenshots of every page visited are saved under the test's temporary directory. Without
Chromium or Playwright these tests skip; ``MULTION_REQUIRE_BROWSER=1`` (set by .ci/run) makes
them required.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from played_runs import PlayedRun, percent

REQUIRE_BROWSER = "MULTION_REQUIRE_BROWSER"
BROWSER_HINT = (
    "needs Chromium and Playwright: `apt-get install chromium` (Debian) and "
    f"`pip install playwright` (in the dev extra); {REQUIRE_BROWSER}=1 (set by .ci/run) makes "
    "these tests required"
)
# No sandbox as root (CI); no background connections to Google's hosts (the network is closed).
CHROMIUM_ARGS = [
    "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-quic",
]  # fmt: skip


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    executable = _chromium()
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        executable = None
    if executable is None:
        if os.environ.get(REQUIRE_BROWSER) == "1":
            pytest.fail(BROWSER_HINT)
        pytest.skip(BROWSER_HINT)
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=executable, args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


class Visit:
    """A page in a fresh context that records every request and console error."""

    def __init__(self, browser: Any, server: Any, shots: Path, **context: Any) -> None:
        self.context = browser.new_context(**context)
        self.page = self.context.new_page()
        self.server, self.shots = server, shots
        self.requests: list[str] = []
        self.errors: list[str] = []
        self.page.on("request", lambda request: self.requests.append(request.url))
        self.page.on("console", lambda m: m.type == "error" and self.errors.append(m.text))
        self.page.on("pageerror", lambda error: self.errors.append(str(error)))

    def goto(self, path: str) -> Any:
        self.page.goto(self.server.url + path)
        return self.page

    def shot(self, name: str) -> Path:
        path = self.shots / f"{name}.png"
        self.page.screenshot(path=str(path), full_page=True)
        assert path.stat().st_size > 1000
        return path

    def close(self) -> None:
        outside = [u for u in self.requests if not u.startswith(self.server.url)]
        assert outside == [], f"requests outside the server: {outside}"
        assert self.errors == [], f"console errors (CSP violations show here): {self.errors}"
        self.context.close()


@pytest.fixture
def visit(browser: Any, server: Any, tmp_path: Path) -> Iterator[Any]:
    visits: list[Visit] = []

    def open_page(**context: Any) -> Visit:
        visits.append(Visit(browser, server, tmp_path, **context))
        return visits[-1]

    yield open_page
    for v in visits:
        v.close()


def _board(page: Any, track: str, phase: str) -> Any:
    return page.locator(f'section[data-track="{track}"][data-phase="{phase}"]')


def test_click_from_the_leaderboard_to_a_run_and_back(
    visit: Any, played: dict[str, PlayedRun]
) -> None:
    v = visit()
    page = v.goto("/leaderboard")
    v.shot("leaderboard")
    run = played["beta"]
    board = _board(page, "1-on", "minival")
    row = board.locator(f'tr[data-run="{run.run_id}"]')
    shown = row.locator('td[data-metric="progress"]').inner_text()
    assert shown == percent(run.summary["progress"]["mean"])
    row.locator("a.run").click()
    page.wait_for_url(f"**/leaderboard/runs/{run.run_id}")
    v.shot("run")
    assert page.locator("h1").inner_text().startswith(run.method)
    for metric in ("ppl", "progress", "success", "spl"):
        cells = page.locator(f'table.scores tr[data-metric="{metric}"] td')
        value = run.summary[metric]
        assert cells.nth(1).inner_text() == percent(value["mean"])
        assert cells.nth(2).inner_text() == f"[{percent(value['low'])}, {percent(value['high'])}]"
    pictures = page.locator(".pictures img")
    assert pictures.count() >= 1
    pictures.first.scroll_into_view_if_needed()
    page.wait_for_function(
        "() => [...document.querySelectorAll('.pictures img')].every(i => i.complete && i.naturalWidth > 0)",
        timeout=120_000,
    )
    v.shot("run-with-pictures")
    page.go_back()
    page.wait_for_url("**/leaderboard")
    assert page.url == v.server.url + "/leaderboard"
    assert _board(page, "1-on", "minival").locator(f'tr[data-run="{run.run_id}"]').count() == 1
    # and from the run page's own link back to its board
    page.goto(v.server.url + f"/leaderboard/runs/{run.run_id}")
    page.locator(".crumbs a").click()
    page.wait_for_url("**/leaderboard#1-on-minival")


def test_sorting_a_column(visit: Any, played: dict[str, PlayedRun]) -> None:
    v = visit()
    page = v.goto("/leaderboard")
    board = _board(page, "1-on", "minival")

    def column(metric: str) -> list[float]:
        cells = board.locator(f'tbody td[data-metric="{metric}"]')
        return [float(c.get_attribute("data-value")) for c in cells.all()]

    def teams() -> list[str]:
        return [c.inner_text() for c in board.locator("tbody tr td:nth-child(2)").all()]

    heading = board.locator("thead th", has_text="Progress %")
    heading.click()
    assert heading.get_attribute("aria-sort") == "ascending"
    assert column("progress") == sorted(column("progress"))
    heading.click()
    assert heading.get_attribute("aria-sort") == "descending"
    assert column("progress") == sorted(column("progress"), reverse=True)
    v.shot("sorted-by-progress")
    team_heading = board.locator("thead th", has_text="team")
    team_heading.click()
    assert teams() == sorted(teams(), key=str.lower)


def test_a_sealed_phase_shows_nothing_in_the_browser(
    visit: Any, played: dict[str, PlayedRun]
) -> None:
    v = visit()
    page = v.goto("/leaderboard")
    sealed = _board(page, "1-on-oracle", "test-challenge")
    assert "sealed until 2999-01-01" in sealed.inner_text()
    assert sealed.locator("tbody tr").count() == 0
    assert played["sealed"].run_id not in page.content()
    page = v.goto(f"/leaderboard/runs/{played['sealed'].run_id}")
    assert page.locator("table.scores").count() == 0
    assert "sealed until" in page.locator("main").inner_text()


def test_the_pages_fit_a_phone(visit: Any, played: dict[str, PlayedRun]) -> None:
    v = visit(viewport={"width": 390, "height": 844}, device_scale_factor=2, is_mobile=True)
    for name, path in [
        ("phone-leaderboard", "/leaderboard"),
        ("phone-run", f"/leaderboard/runs/{played['beta'].run_id}"),
        ("phone-team", "/leaderboard/teams/alpha"),
        ("phone-rules", "/leaderboard/rules"),
    ]:
        page = v.goto(path)
        # wide tables scroll inside their own box; the page itself never scrolls sideways
        width = page.evaluate("() => document.documentElement.scrollWidth")
        assert width <= 390, f"{path} is {width} px wide"
        v.shot(name)
