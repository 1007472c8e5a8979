"""The report's table of ground searched (issue 51): the task's ``cells_visited`` per episode
and at the step limit, a run evaluated before the task measured it left out."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from multion_agents.report.paper import paper_results
from multion_agents.report.runs import EpisodeResult, Run
from multion_agents.report.search import search_coverage

RunOf = Callable[..., Run]


def _episodes(metrics: list[dict[str, Any]]) -> list[EpisodeResult]:
    return [EpisodeResult(f"e{index}", "house", m, index) for index, m in enumerate(metrics)]


def test_cells_per_episode_and_at_the_step_limit(one_goal_run: RunOf) -> None:
    searcher = one_goal_run(
        "searcher",
        _episodes(
            [
                {"cells_visited": 4, "end_reason": "success"},
                {"cells_visited": 10, "end_reason": "max_steps"},
                {"cells_visited": 13, "end_reason": "max_steps"},
                {"cells_visited": 1, "end_reason": "wrong_found"},
            ]
        ),
    )
    older = one_goal_run("older", _episodes([{"success": 1.0, "end_reason": "success"}]))
    table = search_coverage([searcher, older], ["searcher", "older"], paper_results())
    assert table is not None
    assert [row[0] for row in table.rows] == ["searcher"]
    (record,) = table.records
    assert record["cells"] == pytest.approx(7.0)
    assert record["cells_low"] <= 7.0 <= record["cells_high"]
    assert record["episodes_at_step_limit"] == 2
    assert record["cells_at_step_limit"] == pytest.approx(11.5)
    assert table.rows[0][3] == "11.5 (2)"
    assert any("Left out" in note and "older" in note for note in table.notes)


def test_no_table_when_no_run_measured_it(one_goal_run: RunOf) -> None:
    older = one_goal_run("older", _episodes([{"success": 1.0, "end_reason": "success"}]))
    assert search_coverage([older], ["older"], paper_results()) is None
