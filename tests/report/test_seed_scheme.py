"""Issue 53 item 8: ``multion eval`` seeds each episode's agent from the seed and the episode's
id, records the scheme, and ``multion report`` says when it pairs runs seeded differently."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_report import report, run_eval

from multion.config.datasets import save_dataset
from multion.sim.simulator import Simulator
from multion.task.sampling import sample_episode
from multion_agents.report.runs import load_run
from multion_agents.seeding import episode_id_seed, episode_seed, scheme_seed

ROOM = "room-6x4"


def actions(run: Path) -> dict[str, str]:
    lines = (run / "episodes.jsonl").read_text().splitlines()
    return {item["episode_id"]: item["actions"] for item in map(json.loads, lines)}


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


@pytest.fixture(scope="module")
def long_and_short(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A stochastic agent on 6 room episodes, and on 3 of them (the 1st, 3rd and 5th)."""
    root = tmp_path_factory.mktemp("seeding")
    grid = Simulator().load_scene(ROOM)
    rng = np.random.default_rng(53)
    episodes: list = []
    while len(episodes) < 6:
        episode = sample_episode(grid, ROOM, 1, rng, f"room-seed-{len(episodes)}")
        if episode is not None:
            episodes.append(episode)
    dataset = save_dataset(root / "room-1-on.json.gz", episodes, 1, "val")
    common = ["--agent", "random-oracle-found", "--task", "1-on", "--max-steps", "60"]
    common += ["--in-process", "--pictures", "0", "--quiet", "--image-size", "16"]
    common += ["--dataset", str(dataset), "--seed", "3"]
    long, short = root / "long", root / "short"
    assert run_eval([*common, "--out", str(long)]) == 0
    assert run_eval([*common, "--episodes", "3", "--out", str(short)]) == 0
    return long, short


def test_an_episode_plays_the_same_in_every_run_that_holds_it(
    long_and_short: tuple[Path, Path],
) -> None:
    long, short = long_and_short
    played_long, played_short = actions(long), actions(short)
    assert len(played_long) == 6 and len(played_short) == 3
    # the 2nd and 3rd episodes of the short run are the 3rd and 5th of the long one: seeded by
    # their position, they drew other random turns (60 steps of them) in the two runs
    assert all(played_short[i] == played_long[i] for i in played_short)
    for run in (long, short):
        recorded = json.loads((run / "metrics.json").read_text())["run"]
        assert recorded["seed_scheme"] == "episode_id" and recorded["seed"] == 3


def test_the_seed_of_an_episode_is_its_ids() -> None:
    assert episode_id_seed(0, "val-1-on-00460") == episode_id_seed(0, "val-1-on-00460")
    assert episode_id_seed(0, "val-1-on-00460") != episode_id_seed(1, "val-1-on-00460")
    assert episode_id_seed(0, "val-1-on-00460") != episode_id_seed(0, "val-1-on-00470")
    assert scheme_seed("episode_id", 0, 7, "x") == scheme_seed("episode_id", 0, 2, "x")
    assert scheme_seed("index", 0, 7, "x") == episode_seed(0, 7) != episode_seed(0, 2)
    with pytest.raises(ValueError, match="unknown seed scheme 'position'; schemes: index"):
        scheme_seed("position", 0, 0, "x")


def test_runs_seeded_alike_are_paired_without_a_note(
    long_and_short: tuple[Path, Path], tmp_path: Path
) -> None:
    long, short = long_and_short
    assert report([str(long), str(short), "--out", str(tmp_path)]) == 0
    (row,) = read_csv(tmp_path / "paired.csv")
    assert row["common_episodes"] == "3" and row["seeded_alike"] == "True"
    text = (tmp_path / "report.md").read_text()
    assert "seeded their agents differently" not in text
    assert "every run seeded each episode's agent from its seed by episode id (" in text


def test_a_run_from_before_the_scheme_reads_as_index_and_is_flagged_when_paired(
    long_and_short: tuple[Path, Path], tmp_path: Path
) -> None:
    long, short = long_and_short
    old = tmp_path / "old"
    shutil.copytree(short, old)
    payload = json.loads((old / "metrics.json").read_text())
    del payload["run"]["seed_scheme"]
    (old / "metrics.json").write_text(json.dumps(payload))
    run = load_run(old)
    assert (run.seed_scheme, run.seed_scheme_recorded) == ("index", False)
    assert [e.index for e in run.episodes] == [0, 1, 2]
    out = tmp_path / "out"
    assert report([str(long), str(old), "--out", str(out)]) == 0
    (row,) = read_csv(out / "paired.csv")
    assert row["seeded_alike"] == "False"
    text = (out / "report.md").read_text()
    assert "long and old seeded their agents differently on 3 of 3 shared episodes" in text
    assert "seed schemes 3 (episode id) and 3 (index, unrecorded)" in text
    assert "by episode id: long; by index, unrecorded: old (" in text
    # an unknown scheme is refused by name
    payload["run"]["seed_scheme"] = "position"
    (old / "metrics.json").write_text(json.dumps(payload))
    with pytest.raises(ValueError, match="'run.seed_scheme' is 'position', not one of index"):
        load_run(old)
