"""Shared fixtures of the API tests: a few 2-goal episodes in the empty room, small cameras."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from multion.config.episode import Episode
from multion.sim.simulator import Simulator
from multion.task.sampling import sample_episode

SCENE = "room-6x4"
NUM_GOALS = 2


@pytest.fixture(scope="session")
def room_episodes() -> list[Episode]:
    grid = Simulator().load_scene(SCENE)
    rng = np.random.default_rng(7)
    episodes = []
    while len(episodes) < 4:
        episode = sample_episode(grid, SCENE, NUM_GOALS, rng, f"room-{len(episodes)}")
        if episode is not None:
            episodes.append(episode)
    return episodes


@pytest.fixture(scope="session")
def small_config(room_episodes: list[Episode]) -> dict[str, Any]:
    """A session config: 32x32 RGB-D, 2 goals, short episodes, the room episodes inline."""
    return {
        "task": {"num_goals": NUM_GOALS, "max_steps": 30},
        "camera": {"width": 32, "height": 32},
        "episodes": [e.to_dict() for e in room_episodes],
    }
