"""Fixtures of the learned-agent tests: a tiny 1-ON dataset in the empty 6 × 4 m room."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

pytest.importorskip("torch")

from multion.config.datasets import save_dataset  # noqa: E402
from multion.config.episode import Episode


@pytest.fixture(scope="session")
def room_dataset(
    tmp_path_factory: pytest.TempPathFactory,
    room_episodes: Callable[[int, int, str], list[Episode]],
) -> Path:
    """Four 1-goal training episodes in the empty room (loads in a fraction of a second)."""
    path = tmp_path_factory.mktemp("learned-data") / "room-1-on.json.gz"
    save_dataset(path, room_episodes(4, 5, "room-train"), 1, "train")
    return path
