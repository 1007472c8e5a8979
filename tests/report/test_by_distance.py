"""The report's table of Success by the goals' distance (issue 51): quarters of the packaged
dataset's shortest paths, each episode counted once, a run on another dataset left out."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from multion.config.datasets import load_dataset, packaged_dataset_path
from multion_agents.report.distances import by_distance
from multion_agents.report.paper import paper_results
from multion_agents.report.runs import EpisodeResult, Run


def _run(name: str, dataset: str, successes: dict[str, float]) -> Run:
    episodes = tuple(
        EpisodeResult(episode_id, "house", {"success": won}, index)
        for index, (episode_id, won) in enumerate(successes.items())
    )
    return Run(path=Path(name), agent=name, num_goals=1, split="val", dataset=dataset,
               found_budget=0, goal_set="colours", settings={}, camera_width=36,
               renderer="tiny", seed=0, multion_version="test", episodes=episodes)  # fmt: skip


def test_quarters_of_the_shortest_path_count_each_episode_once() -> None:
    path = packaged_dataset_path(1, "val")
    checksum = hashlib.sha256(path.read_bytes()).hexdigest()[:12]
    chosen = load_dataset(path)[:12]
    metres = {e.episode_id: sum(e.geodesic_distances) for e in chosen}
    nearest = sorted(metres, key=metres.__getitem__)[:6]  # the near half succeeds
    near = _run("near", checksum, {i: float(i in nearest) for i in metres})
    other = _run("elsewhere", "0123456789ab", {i: 1.0 for i in metres})
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


def test_no_table_without_a_packaged_dataset() -> None:
    run = _run("elsewhere", "0123456789ab", {"a": 1.0})
    assert by_distance([run], ["elsewhere"], paper_results()) is None
