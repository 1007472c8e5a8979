"""Issue 42 in a real headless Chromium: an oracle track's board with the shipped baselines fits
its box from 1280 to 1600 px (the date was cut off and the box scrolled sideways), and a sealed
phase's date never breaks across lines on a phone. Runs are stored straight into this module's
database (tests/leaderboard/stored_runs.py). Skips like test_browser.py without Chromium."""

from __future__ import annotations

from typing import Any

import pytest
import test_browser
from stored_runs import StoredRun, store_runs

browser = test_browser.browser  # the fixtures of test_browser.py, shared
visit = test_browser.visit

LINKS = {"paper_url": "https://example.org/paper", "code_url": "https://example.org/code"}


@pytest.fixture(scope="module")
def oracle_board(server: Any, database: str) -> list[str]:
    """1-on-oracle/minival as the baselines fill it: the four baseline methods (one with
    paper and code links) over 1,000 episodes each, and a team's run with links."""
    episodes = 1000
    # close scores: the runs below the leader carry the "overlaps leader" mark
    skills = (0.9, 0.89, 0.87, 0.85, 0.6)
    values = [[skill * ((k * 37) % 100) / 100 for k in range(episodes)] for skill in skills]
    runs = [
        StoredRun("baselines", method, values[k], track="1-on-oracle", minutes=k,
                  baseline=True, extra=LINKS if k == 1 else {})
        for k, method in enumerate(["random", "random-oracle-found", "explorer", "oracle-planner"])
    ] + [StoredRun("Team Rocket", "semantic map planner", values[4], track="1-on-oracle",
                   minutes=9, extra=LINKS)]  # fmt: skip
    return store_runs(database, runs)


@pytest.mark.parametrize("width", [1280, 1440, 1600])
def test_an_oracle_board_with_the_baselines_fits_its_box(
    visit: Any, oracle_board: list[str], width: int
) -> None:
    v = visit(viewport={"width": width, "height": 900})
    page = v.goto("/leaderboard")
    board = page.locator('section[data-track="1-on-oracle"][data-phase="minival"]')
    assert board.locator("tbody tr").count() == len(oracle_board)
    v.shot(f"oracle-board-{width}")
    region = board.locator("div.scroll")
    sizes = region.evaluate("b => ({scroll: b.scrollWidth, client: b.clientWidth})")
    assert sizes["scroll"] <= sizes["client"], sizes  # no sideways scrolling
    box = region.bounding_box()
    assert box is not None
    for cell in board.locator("td.date").all():
        fits = cell.evaluate("c => c.scrollWidth <= c.clientWidth")
        cell_box = cell.bounding_box()
        assert fits and cell_box is not None, cell.inner_text()
        assert cell_box["x"] + cell_box["width"] <= box["x"] + box["width"] + 0.5
        assert cell.inner_text().endswith(" UTC")


DATE_LINES = """(box, needle) => {
  const walker = document.createTreeWalker(box, NodeFilter.SHOW_TEXT);
  const nodes = []; let text = '';
  while (walker.nextNode()) { nodes.push([walker.currentNode, text.length]); text += walker.currentNode.data; }
  const start = text.indexOf(needle), end = start + needle.length;
  if (start < 0) return -1;
  const range = document.createRange();
  for (const [n, at] of nodes) if (at <= start && start <= at + n.data.length) { range.setStart(n, start - at); break; }
  for (const [n, at] of nodes) if (at <= end && end <= at + n.data.length) { range.setEnd(n, end - at); break; }
  return new Set([...range.getClientRects()].filter(r => r.width > 0).map(r => Math.round(r.top))).size;
}"""
"""How many lines the text ``needle`` inside element ``box`` spans (-1: not there)."""


def test_a_sealed_date_never_breaks_on_a_phone(visit: Any, server: Any) -> None:
    date = "2999-01-01 00:00 UTC"  # conftest.TINY's sealed test-challenge phase
    for width in range(300, 452, 4):
        v = visit(viewport={"width": width, "height": 800}, is_mobile=True)
        page = v.goto("/leaderboard")
        sealed = page.locator(
            'section[data-track="1-on-oracle"][data-phase="test-challenge"] p.sealed'
        )
        lines = sealed.evaluate(DATE_LINES, date)
        assert lines == 1, (width, lines)
        v.context.close()
        v.context = v.page.context  # closed: Visit.close() must not close it twice
