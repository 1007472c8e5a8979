"""Issue 53 item 4 in a real headless Chromium: the pages' sorting script (static/sort.js)
orders a text column as the reader's language does ("Équipe" after "Team" was code-point
order), numbers within text by value, and numbers as numbers. Skips without Chromium."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from chromium import chromium
from multion.leaderboard.web.pages import HERE

TEAMS = ["Team", "équipe b", "Équipe", "zeta", "alpha", "house 10", "house 2", "Örn"]
TABLE = (
    '<!doctype html><html lang="en"><body><table class="sortable"><thead><tr>'
    '<th data-sort="text">team</th><th data-sort="number" data-first="descending">score</th>'
    "</tr></thead><tbody>"
    + "".join(
        f'<tr><td>{team}</td><td data-value="{score}">{score}</td></tr>'
        for team, score in zip(TEAMS, [5, 40, 3, 10, 0.5, 7, 8, 2], strict=True)
    )
    + "</tbody></table></body></html>"
)


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with chromium() as launched:
        yield launched


def test_text_columns_sort_as_the_language_does(browser: Any) -> None:
    page = browser.new_page(locale="en-GB")
    try:
        page.set_content(TABLE)
        page.add_script_tag(content=(HERE / "static" / "sort.js").read_text(encoding="utf-8"))
        page.evaluate("document.dispatchEvent(new Event('DOMContentLoaded'))")

        def column(k: int) -> list[str]:
            return page.eval_on_selector_all(
                f"tbody tr td:nth-child({k})", "cells => cells.map(c => c.textContent)"
            )

        page.click("th:nth-child(1)")
        assert column(1) == [
            "alpha", "Équipe", "équipe b", "house 2", "house 10", "Örn", "Team", "zeta",
        ]  # fmt: skip
        page.click("th:nth-child(1)")
        assert column(1)[0] == "zeta" and column(1)[-1] == "alpha"
        page.click("th:nth-child(2)")  # scores: best first, by value
        assert column(2) == ["40", "10", "8", "7", "5", "3", "2", "0.5"]
    finally:
        page.close()
