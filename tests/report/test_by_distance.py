"""The report's table of Success by the goals' distance (issue 51): quarters of the packaged
dataset's shortest paths, each episode counted once, a run on another dataset left out."""

from __future__ import annotations

import hashlib
from collections.abc import Callable

import numpy as np
import pytest

from multion.config.datasets import load_dataset, packaged_dataset_path
from multion_agents.report.distances import by_distance
from multion_agents.report.paper import paper_results
from multion_agents.report.runs import EpisodeResult, Run

RunOf = Callable[..., Run]


def _episodes(successes: dict[str, float]) -> list[EpisodeResult]:
    return [
        EpisodeResult(episode_id, "house", {"success": won}, index)
        for index, (episode_id, won) in enumerate(successes.items())
    ]


def test_quarters_of_the_shortest_path_count_each_episode_once(one_goal_run: RunOf) -> None:
    path = packaged_dataset_path(1, "val")
    checksum = hashlib.sha256(path.read_bytes()).hexdigest()[:12]
    chosen = load_dataset(path)[:12]
    metres = {e.episode_id: sum(e.geodesic_distances) for e in chosen}
    nearest = sorted(metres, key=metres.__getitem__)[:6]  # the near half succeeds
    near = one_goal_run("near", _episodes({i: float(i in nearest) for i in metres}), checksum)
    other = one_goal_run("elsewhere", _episodes({i: 1.0 for i in metres}))
    table = by_distance([near, other], ["near", "elsewhere"], paper_results())
    assert table is not None
    assert [row[0] for row in table.rows] == ["near"]
    assert any("Left out" in note and "elsewhere" in note for note in table.notes)
    records = table.records
    assert sum(r["episodes"] for r in records) == 12
    cuts = np.round(np.quantile(list(metres.values()), [0.25, 0.5, 0.75]), 1)
    for record, low, high in zip(records, [0.0, *cuts], [*cuts, np.inf], strict=True):
        inside = [i for i, m in metres.items() if low <= m < high]
        assert record["episodes"] == len(inside)
        won = sum(i in nearest for i in inside)
        assert record["success"] == pytest.approx(100 * won / len(inside), abs=0.01)
    assert records[0]["success"] == 100.0 and records[-1]["success"] == 0.0
    assert f"{cuts[1]:g}" in table.notes[0]


def test_no_table_without_a_packaged_dataset(one_goal_run: RunOf) -> None:
    run = one_goal_run("elsewhere", _episodes({"a": 1.0}))
    assert by_distance([run], ["elsewhere"], paper_results()) is None
