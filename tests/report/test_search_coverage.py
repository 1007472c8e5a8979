"""The report's search tables (issue 51): the task's ``cells_visited`` per episode and at the
step limit; episodes within reach of their goal and the lost ones split into stopping and
search failures by ``closest_to_goal``; runs evaluated before the task measured them left out."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import pytest

from multion_agents.report.paper import paper_results
from multion_agents.report.runs import EpisodeResult, Run
from multion_agents.report.search import search_coverage, search_or_stop, search_pairs

RunOf = Callable[..., Run]


def _episodes(metrics: list[dict[str, Any]]) -> list[EpisodeResult]:
    return [EpisodeResult(f"e{index}", "house", m, index) for index, m in enumerate(metrics)]


def test_cells_per_episode_and_at_the_step_limit(one_goal_run: RunOf) -> None:
    searcher = one_goal_run(
        "searcher",
        _episodes(
            [
                {"cells_visited": 4, "end_reason": "success", "path_length": 3.0},
                {"cells_visited": 10, "end_reason": "max_steps", "path_length": 80.0},
                {"cells_visited": 13, "end_reason": "max_steps", "path_length": 120.0},
                {"cells_visited": 2, "end_reason": "max_steps", "path_length": 9.5},
                {"cells_visited": 1, "end_reason": "wrong_found", "path_length": 0.5},
            ]
        ),
    )
    older = one_goal_run("older", _episodes([{"success": 1.0, "end_reason": "success"}]))
    table = search_coverage([searcher, older], ["searcher", "older"], paper_results())
    assert table is not None
    assert [row[0] for row in table.rows] == ["searcher"]
    (record,) = table.records
    assert record["cells"] == pytest.approx(6.0)
    assert record["cells_low"] <= 6.0 <= record["cells_high"]
    assert record["episodes_at_step_limit"] == 3
    assert record["cells_at_step_limit"] == pytest.approx(8.333)
    assert table.rows[0][3] == "8.3 (3)"
    # the step-limited episodes walked 80, 120 and 9.5 m: the last one stuck
    assert record["walked_at_step_limit_median"] == pytest.approx(80.0)
    assert record["stuck_at_step_limit"] == 1
    assert table.rows[0][4:] == ["80", "1"]
    assert any("Left out" in note and "older" in note for note in table.notes)


def test_no_table_when_no_run_measured_it(one_goal_run: RunOf) -> None:
    older = one_goal_run("older", _episodes([{"success": 1.0, "end_reason": "success"}]))
    assert search_coverage([older], ["older"], paper_results()) is None


def _ended(success: float, closest: float, reason: str, seen: bool | None = None) -> dict[str, Any]:
    metrics = {"success": success, "closest_to_goal": closest, "end_reason": reason}
    return metrics if seen is None else {**metrics, "current_goal_seen": seen}


def test_lost_episodes_split_into_stopping_and_search_failures(one_goal_run: RunOf) -> None:
    played = _episodes(
        [
            _ended(1.0, 0.0, "success"),
            _ended(0.0, 1.2, "wrong_found"),  # stood within reach, called FOUND elsewhere
            _ended(0.0, 4.0, "max_steps"),
            _ended(0.0, 6.0, "max_steps"),
        ]
    )
    older = one_goal_run("older", _episodes([{"success": 1.0, "end_reason": "success"}]))
    table = search_or_stop([one_goal_run("agent", played), older], ["agent", "older"],
                           paper_results())  # fmt: skip
    assert table is not None
    (record,) = table.records
    assert record["within_reach"] == pytest.approx(0.5)
    assert record["within_reach_low"] <= 0.5 <= record["within_reach_high"]
    assert (record["won"], record["lost_within_reach"], record["lost_never_within_reach"]) == (
        1,
        1,
        2,
    )
    assert record["closest_approach_median"] == pytest.approx(5.0)
    assert record["lost_never_within_reach_seen"] is None  # not measured: "–"
    assert table.rows[0][3:] == ["–", "1", "1", "2", "–", "5.0"]
    assert any("Left out" in note and "older" in note for note in table.notes)
    # the run's own success distance decides what "within reach" is
    strict = dataclasses.replace(one_goal_run("strict", played), success_distance=1.0)
    strict_table = search_or_stop([strict], ["strict"], paper_results())
    assert strict_table is not None
    (strict_record,) = strict_table.records
    assert strict_record["lost_within_reach"] == 0
    assert strict_record["lost_never_within_reach"] == 3
    assert strict_record["closest_approach_median"] == pytest.approx(4.0)


def test_no_split_when_no_run_measured_closest_approach(one_goal_run: RunOf) -> None:
    older = one_goal_run("older", _episodes([{"success": 0.0, "end_reason": "max_steps"}]))
    assert search_or_stop([older], ["older"], paper_results()) is None


def test_search_failures_split_by_whether_the_goal_was_seen(one_goal_run: RunOf) -> None:
    played = _episodes(
        [
            _ended(1.0, 0.0, "success", seen=False),  # won: not counted among the lost
            _ended(0.0, 1.0, "max_steps", seen=True),  # lost within reach
            _ended(0.0, 3.0, "max_steps", seen=True),  # saw it, never got there
            _ended(0.0, 7.0, "wrong_found", seen=False),
            _ended(0.0, 9.0, "max_steps", seen=False),
        ]
    )
    table = search_or_stop([one_goal_run("agent", played)], ["agent"], paper_results())
    assert table is not None
    (record,) = table.records
    assert (record["lost_within_reach"], record["lost_never_within_reach"]) == (1, 3)
    assert record["lost_never_within_reach_seen"] == 1
    assert record["saw_goal"] == 2
    assert table.rows[0][3].startswith("40 [") and table.rows[0][7] == "1"


def test_pairs_asked_for_compare_reach_and_sight_on_common_episodes(one_goal_run: RunOf) -> None:
    a = one_goal_run("a", _episodes([
        _ended(1.0, 0.0, "success", seen=True),
        _ended(0.0, 1.2, "max_steps", seen=True),
        _ended(0.0, 4.0, "max_steps", seen=True),
        _ended(0.0, 9.0, "max_steps", seen=False),
    ]))  # fmt: skip
    b = one_goal_run("b", _episodes([
        _ended(0.0, 3.0, "max_steps", seen=False),
        _ended(0.0, 3.0, "max_steps", seen=False),
        _ended(0.0, 4.0, "max_steps", seen=True),
        _ended(0.0, 9.0, "max_steps", seen=False),
    ]))  # fmt: skip
    older = one_goal_run("older", _episodes([{"success": 1.0, "end_reason": "success"}] * 4))
    runs = [a, b, older]
    table = search_pairs(runs, ["a", "b", "older"], [(0, 1), (0, 2)])
    assert table is not None
    (record,) = table.records  # the pair with a run that lacks the measures is left out
    assert record["common_episodes"] == 4
    assert record["diff_within_reach"] == pytest.approx(50.0)  # 2 of 4 against 0
    assert record["diff_saw_goal"] == pytest.approx(50.0)  # 3 of 4 against 1
    assert record["diff_within_reach_low"] <= 50.0 <= record["diff_within_reach_high"]
    assert search_pairs(runs, ["a", "b", "older"], [(0, 2)]) is None
    assert search_pairs(runs, ["a", "b", "older"], []) is None
