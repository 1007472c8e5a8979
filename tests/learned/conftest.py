"""Fixtures of the learned-agent tests: a tiny 1-ON dataset in the empty 6 × 4 m room."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")

from multion.sim.simulator import Simulator  # noqa: E402
from multion.task.dataset import sample_episode, save_dataset  # noqa: E402

ROOM = "room-6x4"


@pytest.fixture(scope="session")
def room_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Four 1-goal episodes in the empty room (loads in a fraction of a second)."""
    grid = Simulator().load_scene(ROOM)
    rng = np.random.default_rng(5)
    episodes = []
    while len(episodes) < 4:
        episode = sample_episode(grid, ROOM, 1, rng, f"room-train-{len(episodes)}")
        if episode is not None:
            episodes.append(episode)
    path = tmp_path_factory.mktemp("learned-data") / "room-1-on.json.gz"
    save_dataset(path, episodes, 1, "train")
    return path
