"""Distractor cylinders (``task.num_distractors``): sampling rules, FOUND rules, sensors, maps.

Hand-made episodes in ``room-10x4`` (free interior x∈[0, 10], y∈[0, 4]).
"""

import gymnasium as gym
import numpy as np
import pytest

from multion.config.datasets import DatasetError, check_episode, load_dataset, save_dataset
from multion.config.episode import Episode, Goal
from multion.config.task import EnvConfig, EpisodeConstraints, MapConfig, TaskConfig
from multion.sim.simulator import Simulator
from multion.task.env import MultiONEnv
from multion.task.sampling import sample_episode
from multion_client.constants import NUM_CATEGORIES, Action

SCENE = "room-10x4"
RED, GREEN, BLUE = 0, 1, 2


def episode(distractors=((GREEN, (1.0, 2.0)),), goal=(RED, (8.0, 2.0))):
    return Episode(
        "d", SCENE, (4.0, 2.0, 0.0), np.pi,  # facing -x, towards the distractor
        (Goal(goal[0], (*goal[1], 0.0)),),
        distractors=tuple(Goal(c, (x, y, 0.0)) for c, (x, y) in distractors),
    )  # fmt: skip


def env_for(ep, sensors=("goal",), **task):
    config = EnvConfig(
        task=TaskConfig(num_goals=1, num_distractors=len(ep.distractors), **task),
        sensors=sensors,
        maps=MapConfig(cell_size=0.5, ego_size=21),
    )
    return MultiONEnv(config, episodes=[ep])


def test_found_at_a_distractor_is_a_wrong_found():
    env = env_for(episode())
    env.reset(seed=0)
    for _ in range(8):  # 2 m towards the distractor: 1.0 m from it, 6 m from the goal
        env.step(Action.MOVE_FORWARD)
    _, reward, terminated, _, info = env.step(Action.FOUND)
    m = info["metrics"]
    assert terminated and m["end_reason"] == "wrong_found" and m["success"] == 0.0
    assert m["wrong_founds"] == 1 and m["distractor_founds"] == 1


def test_a_wrong_found_away_from_distractors_is_not_counted_as_one():
    env = env_for(episode(), found_budget=1)
    env.reset(seed=0)
    _, _, terminated, _, info = env.step(Action.FOUND)  # 3 m from the distractor
    assert not terminated
    assert info["metrics"]["wrong_founds"] == 1 and info["metrics"]["distractor_founds"] == 0


def test_distractors_are_drawn_in_the_goal_mask_and_marked_in_the_oracle_map():
    env = env_for(episode(), sensors=("goal_mask", "oracle_map", "rgb"))
    obs, _ = env.reset(seed=0)
    # the distractor (green, category 1) is 3 m ahead: its pixels carry category + 1 = 2
    assert (obs["goal_mask"] == GREEN + 1).sum() > 20
    assert obs["rgb"][obs["goal_mask"] == GREEN + 1].mean(axis=0)[1] > 150
    assert env.observation_space["goal_mask"].contains(obs["goal_mask"])
    values = set(np.unique(obs["oracle_map"][..., 1]))
    assert GREEN + 1 in values and RED + 1 in values
    # without distractors the same room shows only the goal
    obs, _ = env_for(episode(distractors=()), sensors=("goal_mask",)).reset(seed=0)
    assert (obs["goal_mask"] == GREEN + 1).sum() == 0


def test_sampled_distractors_follow_the_rules():
    grid = Simulator().load_scene("room-12x8")
    rng = np.random.default_rng(0)
    constraints = EpisodeConstraints()
    for k in range(20):
        ep = sample_episode(grid, "room-12x8", 2, rng, f"e{k}", constraints, num_distractors=3)
        assert ep is not None and len(ep.distractors) == 3
        goals = {g.category for g in ep.goals}
        others = [d.category for d in ep.distractors]
        assert not goals & set(others) and len(set(others)) == 3  # never a goal's category
        for d in ep.distractors:
            assert grid.is_navigable(np.asarray(d.position[:2]))
            for g in ep.goals:  # > 2 × 1.5 m: no spot is within reach of both
                gap = np.hypot(d.position[0] - g.position[0], d.position[1] - g.position[1])
                assert gap >= constraints.min_distractor_separation > 3.0
        assert check_episode(ep, 2) is None


def test_no_distractors_leaves_the_random_stream_unchanged():
    grid = Simulator().load_scene("room-12x8")
    a = sample_episode(grid, "room-12x8", 2, np.random.default_rng(5), "e")
    b = sample_episode(grid, "room-12x8", 2, np.random.default_rng(5), "e", num_distractors=0)
    assert a == b and a.distractors == ()


def test_bad_distractor_settings_are_refused(tmp_path):
    with pytest.raises(ValueError, match="num_distractors"):
        EnvConfig(task=TaskConfig(num_goals=3, num_distractors=6))
    with pytest.raises(ValueError, match="num_distractors"):
        TaskConfig(num_distractors=-1)
    overlap = episode(distractors=((RED, (1.0, 2.0)),))
    assert "overlap" in check_episode(overlap, 1)
    # a dataset with distractors needs a task with as many
    path = save_dataset(tmp_path / "d.json.gz", [episode()], 1, "val", num_distractors=1)
    assert len(load_dataset(path)[0].distractors) == 1
    with pytest.raises(DatasetError, match="distractors"):
        MultiONEnv(EnvConfig(task=TaskConfig(num_goals=1), dataset=str(path), sensors=("goal",)))


def test_episode_round_trip_keeps_distractors():
    ep = episode(distractors=((GREEN, (1.0, 2.0)), (BLUE, (1.0, 3.0))))
    back = Episode.from_dict(ep.to_dict())
    assert back.distractors == ep.distractors and back.goals == ep.goals
    assert len(ep.to_dict()["distractors"]) == 2 < NUM_CATEGORIES


def test_registered_distractor_variant():
    env = gym.make("MultiON/3-ON-distractors-v0")
    try:
        assert env.unwrapped.config.task.num_distractors == 3
        _, info = env.reset(seed=0)
        assert len(env.unwrapped.episode.distractors) == 3
    finally:
        env.close()
