"""The leaderboard's pages in a real headless Chromium (Playwright, with Debian's chromium).

Screenshots of every page visited are saved under the test's temporary directory. Without
Chromium or Playwright these tests skip; ``MULTION_REQUIRE_BROWSER=1`` (set by .ci/run) makes
them required.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from played_runs import PlayedRun, percent

from chromium import chromium


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with chromium() as launched:
        yield launched


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
    visit: Any, server: Any, played: dict[str, PlayedRun]
) -> None:
    from test_pages import drawn_pictures

    drawn_pictures(server, played["beta"].run_id)
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
    page.wait_for_url("**/leaderboard#board-1-on-minival")


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
    heading.click()  # a score: best first on the first click
    assert heading.get_attribute("aria-sort") == "descending"
    assert column("progress") == sorted(column("progress"), reverse=True)
    heading.click()
    assert heading.get_attribute("aria-sort") == "ascending"
    assert column("progress") == sorted(column("progress"))
    v.shot("sorted-by-progress")
    team_heading = board.locator("thead th", has_text="team")
    team_heading.click()
    assert teams() == sorted(teams(), key=str.lower)
    # the keyboard sorts too: Space (without scrolling the page) and Enter
    team_heading.focus()
    scrolled = page.evaluate("window.scrollY")
    page.keyboard.press(" ")
    assert team_heading.get_attribute("aria-sort") == "descending"
    assert teams() == sorted(teams(), key=str.lower, reverse=True)
    assert page.evaluate("window.scrollY") == scrolled
    page.keyboard.press("Enter")
    assert team_heading.get_attribute("aria-sort") == "ascending"


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


# ---------------------------------------------------------------------- issue 21
LONG_METHOD = "A rather long method name: hierarchical semantic memory with learned exploration v2"


def _found_at_once(url: str, token: str, method: str) -> str:
    """A finished run whose agent calls FOUND at once in every episode: every score is 0."""
    from multion_client.run import RunEnv

    env = RunEnv(url, "1-on", "minival", method, token=token, sensors=["goal"])
    while not env.run_done:
        env.reset()
        done = False
        while not done:
            *_, terminated, truncated, _ = env.step(0)
            done = terminated or truncated
    env.close()
    return env.run_id


@pytest.fixture(scope="module")
def ties(server: Any, played: dict[str, PlayedRun], new_team: Any) -> dict[str, str]:
    """Runs with equal scores (0 on every metric): team delta's abandoned run (first), then two
    finished ones; team omega's abandoned run with a long method and paper / code links. The
    abandoned runs play one episode (FOUND at once) first: a run that played none is no entry."""
    from multion_client.run import RunEnv

    token = new_team("delta")
    abandoned = RunEnv(server.url, "1-on", "minival", "delta", token=token, sensors=["goal"])
    abandoned.reset()
    abandoned.step(0)
    abandoned.abandon()
    first = _found_at_once(server.url, token, "delta")
    second = _found_at_once(server.url, token, "delta")
    long = RunEnv(
        server.url, "1-on", "minival", LONG_METHOD, token=new_team("omega"), sensors=["goal"],
        paper_url="https://example.org/paper", code_url="https://example.org/code",
    )  # fmt: skip
    long.reset()
    long.step(0)
    long.abandon()
    return {"abandoned": abandoned.run_id, "first": first, "second": second, "long": long.run_id}


def _rows(board: Any) -> list[dict[str, Any]]:
    return board.locator("tbody tr").evaluate_all(
        """rows => rows.map(r => ({run: r.dataset.run, rank: parseInt(r.cells[0].dataset.value),
             team: r.cells[1].innerText.trim(), score: parseFloat(r.cells[3].dataset.value)}))"""
    )


def test_equal_scores_share_a_rank_and_the_best_run_is_the_exports(
    visit: Any, ties: dict[str, str], database: str, challenge_file: Path, tmp_path: Path
) -> None:
    import json

    from multion_agents.cli import main

    v = visit()
    page = v.goto("/leaderboard")
    rows = _rows(_board(page, "1-on", "minival"))
    v.shot("ties")
    for k, row in enumerate(rows):  # competition ranks: equal scores, equal ranks
        assert row["rank"] == 1 + sum(r["score"] > row["score"] for r in rows), rows
        if k and row["score"] == rows[k - 1]["score"]:
            assert row["rank"] == rows[k - 1]["rank"]
    zeros = [r for r in rows if r["score"] == 0]
    assert {"delta", "omega"} <= {r["team"] for r in zeros}
    assert len({r["rank"] for r in zeros}) == 1
    # delta: at equal scores a finished run before the ended one, then the earliest
    delta = next(r for r in rows if r["team"] == "delta")
    assert delta["run"] == ties["first"]
    out = tmp_path / "best.json"
    assert main(["leaderboard", "export", "--best", "--database", database, "--out", str(out),
                 "--challenge", str(challenge_file)]) == 0  # fmt: skip
    best = json.loads(out.read_text())["runs"]
    exported = {r["run_id"] for r in best if (r["track"], r["phase"]) == ("1-on", "minival")}
    assert exported == {r["run"] for r in rows}
    ordered = [r["run_id"] for r in best if (r["track"], r["phase"]) == ("1-on", "minival")]
    assert ordered == [r["run"] for r in rows]  # the same order too


def test_a_phone_sees_the_ranking_metric_and_dates_say_utc(
    visit: Any, ties: dict[str, str]
) -> None:
    v = visit(viewport={"width": 390, "height": 844}, device_scale_factor=2, is_mobile=True)
    page = v.goto("/leaderboard")
    board = _board(page, "1-on", "minival")
    v.shot("phone-ties")
    for cell in board.locator("tbody td.primary").all():
        box = cell.bounding_box()
        assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= 390, box
    heading = board.locator("thead th.primary").bounding_box()
    assert heading is not None and heading["x"] + heading["width"] <= 390
    assert board.locator("tbody td.secondary").first.is_hidden()
    assert board.locator("p.phone-only").is_visible()
    long_row = board.locator(f'tr[data-run="{ties["long"]}"]')
    assert long_row.locator("a.run").is_visible()
    # the team column is stacked under the method (issue 33: the score stays on screen)
    assert long_row.locator("td.method .sub", has_text="by omega").is_visible()

    desktop = visit(viewport={"width": 1280, "height": 900})
    page = desktop.goto("/leaderboard")
    board = _board(page, "1-on", "minival")
    desktop.shot("desktop-long-method")
    date = board.locator(f'tr[data-run="{ties["long"]}"] td.date')
    assert date.inner_text().endswith(" UTC")
    # the date stays inside its cell and the table inside its box: nothing pushed out
    fits = date.evaluate("c => c.scrollWidth <= c.clientWidth")
    table = board.locator("table").bounding_box()
    scroller = board.locator(".scroll").bounding_box()
    cell = date.bounding_box()
    assert fits and table is not None and scroller is not None and cell is not None
    assert table["x"] + table["width"] <= scroller["x"] + scroller["width"] + 0.5
    assert cell["x"] + cell["width"] <= scroller["x"] + scroller["width"] + 0.5
    method = board.locator(f'tr[data-run="{ties["long"]}"] td.method')
    assert method.locator("a.ext").count() == 2


def test_the_team_chart_has_round_ticks_times_and_a_legend_outside(
    visit: Any, ties: dict[str, str]
) -> None:
    v = visit(viewport={"width": 1280, "height": 900})
    page = v.goto("/leaderboard/teams/delta")
    v.shot("team-chart")
    chart = page.locator("svg.chart").first
    labels = chart.locator("text.tick").all_text_contents()  # SVG text has no innerText
    percents = [float(t.rstrip("%")) for t in labels if t.endswith("%")]
    step = percents[1] - percents[0]
    assert percents[0] == 0 and step in (1, 2, 5, 10, 20, 25)
    assert all(p == k * step for k, p in enumerate(percents))
    times = [t for t in labels if ":" in t]
    assert times, f"no times on the time axis: {labels}"
    assert "when the run ended (UTC)" in labels
    plot_bottom = max(float(line.get_attribute("y1")) for line in chart.locator("line.axis").all())
    legend = chart.locator("text.legend")
    assert legend.count() >= 2  # a phase and the hollow-dot note
    assert all(float(t.get_attribute("y")) > plot_bottom for t in legend.all())
    text = chart.text_content() or ""
    assert "each run (dot)" in text and "best PPL so far (line)" in text
    assert "Each dot is one of the team's runs" in page.locator("main").inner_text()
    hollow = chart.locator('circle.run-dot[fill="#fff"]')  # delta's abandoned run
    assert hollow.count() == 1


def test_run_pictures_load_at_display_size_without_scrolling(
    visit: Any, server: Any, played: dict[str, PlayedRun]
) -> None:
    from test_pages import drawn_pictures

    run = played["beta"]
    drawn_pictures(server, run.run_id)  # drawn in the background after the run ended
    v = visit(viewport={"width": 1280, "height": 700})
    page = v.goto(f"/leaderboard/runs/{run.run_id}")
    images = page.locator(".pictures img")
    assert images.count() >= 1
    assert images.evaluate_all("imgs => imgs.every(i => !i.loading || i.loading === 'auto')")
    # never scrolled into view, yet loaded (no lazy loading: no empty boxes)
    page.wait_for_function(
        "() => [...document.querySelectorAll('.pictures img')].every(i => i.complete && i.naturalWidth > 0)",
        timeout=60_000,
    )
    v.shot("run-pictures")
    sizes = images.evaluate_all(
        """imgs => imgs.map(i => ({w: i.getBoundingClientRect().width, nw: i.naturalWidth,
             h: i.getBoundingClientRect().height, nh: i.naturalHeight,
             aw: parseInt(i.getAttribute('width')), ah: parseInt(i.getAttribute('height'))}))"""
    )
    for size in sizes:  # shown at half their pixel size: one scale for all, sharp at 2x
        assert (size["aw"], size["ah"]) == (size["nw"] // 2, size["nh"] // 2)
        assert abs(size["w"] - size["nw"] / 2) <= 1 and abs(size["h"] - size["nh"] / 2) <= 1
