"""The simulator's half of the hidden episodes: houses built, grids kept, episodes sampled.

Imported only through :mod:`multion.leaderboard.hidden_entry`, inside the hidden-episode helper
process (or a command's own process): the leaderboard's server process never loads the
simulator. Everything secret is derived by :mod:`multion.leaderboard.hidden`, which passes plain
seeds, house ids and episode ids here.
"""

from __future__ import annotations

import functools
import threading
from collections import OrderedDict

import numpy as np

from multion.config.episode import Episode
from multion.sim.navgrid import NavGrid
from multion.sim.simulator import Simulator
from multion.task.generate import generate_episodes
from multion.task.sampling import sample_episode

GRIDS_KEPT = 32
"""Navigable grids the episode sampler keeps in memory (a phase may have up to 1000 houses)."""


def fixed_episode_set(
    num_goals: int, split: str, count: int, seed: int, houses: list[str], num_distractors: int
) -> list[Episode]:
    """A phase's fixed episode set, generated in ``houses`` from ``seed``."""
    return generate_episodes(
        num_goals,
        split,
        count,
        seed=seed,
        scenes=houses,
        progress=False,
        num_distractors=num_distractors,
    )


def episode_in_house(
    house: str,
    num_goals: int,
    num_distractors: int,
    seed: int,
    episode_id: str,
    tries: int,
) -> Episode | None:
    """One episode sampled in ``house`` from ``seed`` (up to ``tries`` attempts), or None."""
    rng = np.random.default_rng(seed)
    grid = _grid(house)
    for _ in range(tries):
        episode = sample_episode(
            grid, house, num_goals, rng, episode_id, num_distractors=num_distractors
        )
        if episode is not None:
            return episode
    return None


def build_grids(houses: list[str]) -> int:
    """Build (or load from the grid cache) the navigable grids of ``houses``."""
    for house in houses:
        _grid(house)
    return len(houses)


_grids: OrderedDict[str, NavGrid] = OrderedDict()
_grids_lock = threading.Lock()


def _grid(scene: str) -> NavGrid:
    """A house's navigable grid, kept for the next episodes (this process's own simulator)."""
    with _grids_lock:
        if scene in _grids:
            _grids.move_to_end(scene)
            return _grids[scene]
        simulator = _simulator()
        grid = simulator.load_scene(scene)
        simulator.close()  # the grid is all the sampler needs; free the bodies
        _grids[scene] = grid
        while len(_grids) > GRIDS_KEPT:
            _grids.popitem(last=False)
        return grid


@functools.cache
def _simulator() -> Simulator:
    return Simulator()
