"""Fixtures shared by the test packages."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np
import pytest

from multion.config.episode import Episode
from multion.sim.simulator import Simulator
from multion.task.sampling import sample_episode

ROOM = "room-6x4"


@pytest.fixture(scope="session", autouse=True)
def navgrid_cache_in_a_temporary_directory(
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[None]:
    """Tests (and the servers they start, which inherit the environment) cache navigable grids
    in a fresh directory, never in the user's ~/.cache."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("MULTION_NAVGRID_CACHE", str(tmp_path_factory.mktemp("navgrids")))
        yield


@pytest.fixture(scope="session")
def room_episodes() -> Callable[[int, int, str], list[Episode]]:
    """``room_episodes(count, seed, prefix)``: 1-goal episodes in the empty 6 × 4 m room
    (fast to load), with ids ``{prefix}-0``, ``{prefix}-1``, …"""
    grid = Simulator().load_scene(ROOM)

    def make(count: int, seed: int, prefix: str) -> list[Episode]:
        rng = np.random.default_rng(seed)
        episodes: list[Episode] = []
        while len(episodes) < count:
            episode = sample_episode(grid, ROOM, 1, rng, f"{prefix}-{len(episodes)}")
            if episode is not None:
                episodes.append(episode)
        return episodes

    return make
