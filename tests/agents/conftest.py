"""Fixtures of the agent tests: a tiny 1-ON dataset in the empty 6 × 4 m room (fast to load)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from multion.config.datasets import save_dataset
from multion.config.episode import Episode


@pytest.fixture(scope="session")
def room_dataset(
    tmp_path_factory: pytest.TempPathFactory,
    room_episodes: Callable[[int, int, str], list[Episode]],
) -> tuple[Path, list[Episode]]:
    """Three 1-goal episodes in the empty room, saved as a dataset file."""
    episodes = room_episodes(3, 11, "room-ep")
    path = tmp_path_factory.mktemp("agents-data") / "room-1-on.json.gz"
    save_dataset(path, episodes, 1, "val")
    return path, episodes
