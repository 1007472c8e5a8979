"""``current_goal_seen``: whether the goal an episode is on has been in view (the camera's field
of view, within ``maps.view_distance``, a clear line on the grid), on hand-made states and on a
played episode that turns towards its goal and away again."""

from __future__ import annotations

import math

import numpy as np

from multion.config.episode import Episode, Goal
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion.task.measures import CurrentGoalSeen, EpisodeState
from multion_client.constants import Action

GOALS = (Goal(0, (5.0, 3.4, 0.0)), Goal(1, (1.0, 3.4, 0.0)))


def test_the_goal_the_episode_is_on_on_hand_made_states() -> None:
    episode = Episode("s", "room-6x4", (3.0, 0.6, 0.0), math.pi / 2, GOALS)
    state = EpisodeState(episode, (4.0, 4.0), np.array([3.0, 0.6, 0.0]))
    state.first_seen_step = [None, 7]
    measure = CurrentGoalSeen()
    measure.reset(state, {})
    assert measure.value is False  # on goal 1, never seen; goal 2 was
    state.goals_found = 1
    measure.update(state, {})
    assert measure.value is True  # on goal 2
    state.goals_found, state.first_seen_step = 2, [3, None]
    measure.update(state, {})
    assert measure.value is False  # every goal found: the last one's


def test_a_played_episode_sees_its_goal_once_turned_towards_it() -> None:
    # facing -y, away from the goal 3.4 m off; six 30° left turns face +y, the goal 35° right
    episode = Episode("t", "room-6x4", (3.0, 0.6, 0.0), -math.pi / 2, GOALS[:1])
    config = EnvConfig(
        task=TaskConfig(num_goals=1), camera=CameraConfig(width=16, height=16), sensors=("goal",)
    )
    env = MultiONEnv(config, episodes=[episode])
    try:
        _, info = env.reset(seed=0)
        assert info["metrics"]["current_goal_seen"] is False
        seen = []
        for _ in range(6):
            _, _, _, _, info = env.step(int(Action.TURN_LEFT))
            seen.append(info["metrics"]["current_goal_seen"])
        assert seen[-1] is True and seen[0] is False
        for _ in range(6):  # turned away again: it has been seen
            _, _, _, _, info = env.step(int(Action.TURN_LEFT))
            assert info["metrics"]["current_goal_seen"] is True
    finally:
        env.close()
