"""``cells_visited``: the 2.5 m cells of the start frame an episode has stood in (the ground its
search covered), on hand-made poses and on a played episode against the ``gps`` sensor."""

from __future__ import annotations

import math

import numpy as np

from multion.config.episode import Episode, Goal
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion.task.measures import CellsVisited, EpisodeState, visit_cell
from multion_client.constants import Action

# facing +y: ahead is +y, left is -x
EPISODE = Episode("c", "room-6x4", (3.0, 0.6, 0.0), math.pi / 2, (Goal(0, (5.0, 3.4, 0.0)),))


def test_the_start_frame_grid_on_hand_made_poses() -> None:
    state = EpisodeState(EPISODE, (4.0,), np.array([3.0, 0.6, 0.0]))
    measure = CellsVisited()
    measure.reset(state, {})
    assert measure.value == 1  # the start's cell
    poses = [
        ((3.0, 1.8, 0.0), 1),  # 1.2 m ahead: still the start's cell
        ((3.0, 1.9, 0.0), 2),  # 1.3 m ahead: cell (1, 0)
        ((1.7, 1.9, 0.0), 3),  # and 1.3 m left (world -x): cell (1, 1)
        ((3.0, 0.6, 0.0), 3),  # back at the start: no new cell
        ((4.3, 0.6, 0.0), 4),  # 1.3 m right: cell (0, -1)
        ((4.3, -0.7, 0.0), 5),  # and 1.3 m behind: cell (-1, -1)
    ]
    for position, cells in poses:
        state.position = np.array(position)
        measure.update(state, {})
        assert measure.value == cells, position
    assert visit_cell(1.3, 1.3) == (1, 1) and visit_cell(-1.3, -1.3) == (-1, -1)


def test_a_played_episode_counts_the_cells_its_gps_passes_through() -> None:
    config = EnvConfig(
        task=TaskConfig(num_goals=1),
        camera=CameraConfig(width=16, height=16),
        sensors=("gps",),
    )
    env = MultiONEnv(config, episodes=[EPISODE])
    try:
        observation, info = env.reset(seed=0)
        cells = {visit_cell(*map(float, observation["gps"]))}
        assert info["metrics"]["cells_visited"] == 1
        rng = np.random.default_rng(0)
        moves = [Action.MOVE_FORWARD] * 12 + list(rng.choice([1, 2, 3], size=60))
        for action in moves:  # forward, left, right: never FOUND
            observation, _, terminated, truncated, info = env.step(int(action))
            cells.add(visit_cell(*map(float, observation["gps"])))
            assert not (terminated or truncated)
            assert info["metrics"]["cells_visited"] == len(cells)
        assert len(cells) >= 2  # 3 m of room ahead of the start: it left its first cell
    finally:
        env.close()
