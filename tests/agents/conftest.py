"""Fixtures of the agent tests: a tiny 1-ON dataset in the empty 6 × 4 m room (fast to load)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from multion.sim.simulator import Simulator
from multion.task.dataset import sample_episode, save_dataset
from multion.task.episode import Episode

ROOM = "room-6x4"


@pytest.fixture(scope="session")
def room_dataset(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Episode]]:
    """Three 1-goal episodes in the empty room, saved as a dataset file."""
    grid = Simulator().load_scene(ROOM)
    rng = np.random.default_rng(11)
    episodes: list[Episode] = []
    while len(episodes) < 3:
        episode = sample_episode(grid, ROOM, 1, rng, f"room-ep-{len(episodes)}")
        if episode is not None:
            episodes.append(episode)
    path = tmp_path_factory.mktemp("agents-data") / "room-1-on.json.gz"
    save_dataset(path, episodes, 1, "val")
    return path, episodes
