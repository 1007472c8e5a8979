"""The report's movement table (issue 51): action shares, refused forward steps and metres per
step from the actions ``episodes.jsonl`` keeps; runs without actions left out; a corrupt
actions string refused with the line named."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from multion_agents.report.movement import movement
from multion_agents.report.paper import paper_results
from multion_agents.report.runs import EpisodeResult, Run, RunError, _read_episodes

RunOf = Callable[..., Run]


def _episodes(played: list[tuple[str, dict[str, Any]]]) -> list[EpisodeResult]:
    return [
        EpisodeResult(f"e{index}", "house", metrics, index, actions)
        for index, (actions, metrics) in enumerate(played)
    ]


def test_shares_refusals_and_metres_per_step(one_goal_run: RunOf) -> None:
    walker = one_goal_run(
        "walker",
        _episodes(
            [
                # 5 forward (1 refused: 1 m), 1 left, 1 right, then FOUND: 8 steps
                ("11211130", {"collisions": 1, "path_length": 1.0, "cells_visited": 1}),
                # 2 forward, both refused, 2 left: 4 steps
                ("1212", {"collisions": 2, "path_length": 0.0, "cells_visited": 1}),
            ]
        ),
    )
    older = one_goal_run("older", _episodes([("", {"collisions": 0, "path_length": 1.0})]))
    unmeasured = one_goal_run(
        "unmeasured", _episodes([("11", {"collisions": 0, "path_length": 0.5})])
    )
    table = movement(
        [walker, older, unmeasured], ["walker", "older", "unmeasured"], paper_results()
    )
    assert table is not None
    assert [row[0] for row in table.rows] == ["walker", "unmeasured"]
    assert table.rows[1][-1] == "–" and table.records[1]["metres_per_cell"] is None
    record = table.records[0]
    assert record["steps"] == 12
    assert record["forward_share"] == pytest.approx(100 * 7 / 12, abs=1e-3)
    assert record["left_share"] == pytest.approx(100 * 3 / 12)
    assert record["right_share"] == pytest.approx(100 * 1 / 12, abs=1e-3)
    assert record["found_share"] == pytest.approx(100 * 1 / 12, abs=1e-3)
    assert record["forward_refused_share"] == pytest.approx(100 * 3 / 7, abs=1e-3)
    assert record["metres_per_step"] == pytest.approx(1.0 / 12, abs=1e-4)
    assert record["metres_per_cell"] == pytest.approx(0.5)  # 1 m over 2 cells
    assert table.rows[0][2:] == ["58.3", "25.0", "8.3", "8.3", "42.9", "0.083", "0.5"]
    assert any("Left out" in note and "older" in note for note in table.notes)


def test_no_table_when_no_run_kept_its_actions(one_goal_run: RunOf) -> None:
    older = one_goal_run("older", _episodes([("", {"collisions": 0, "path_length": 1.0})]))
    assert movement([older], ["older"], paper_results()) is None


@pytest.mark.parametrize("actions", ["1145", 12, "1 2"])
def test_corrupt_actions_are_refused_naming_the_line(tmp_path: Path, actions: object) -> None:
    good = {"episode_id": "a", "metrics": {"success": 1.0, "spl": 1.0, "progress": 1.0,
            "ppl": 1.0}, "actions": "110"}  # fmt: skip
    bad = {**good, "episode_id": "b", "actions": actions}
    path = tmp_path / "episodes.jsonl"
    path.write_text(json.dumps(good) + "\n" + json.dumps(bad) + "\n")
    with pytest.raises(RunError, match=r"line 2: actions must be a string of the digits 0-3"):
        _read_episodes(path, num_goals=1)
