"""Gymnasium conformance and determinism of the in-process environment."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import multion  # noqa: F401  (registers the environment ids)
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion.task.generate import generate_episodes

SENSORS = ("rgb", "depth", "goal", "goal_onehot", "gps", "compass", "oracle_map", "oracle_ego_map")


def small_env(episodes, sensors=SENSORS):
    config = EnvConfig(
        task=TaskConfig(num_goals=2), camera=CameraConfig(width=64, height=64), sensors=sensors
    )
    return MultiONEnv(config, episodes=episodes)


def test_passes_gymnasium_env_checker():
    episodes = generate_episodes(2, "val", 3, seed=1, scenes=["house-00061"], progress=False)
    env = small_env(episodes)
    check_env(env, skip_render_check=True)


def test_same_seed_same_actions_same_everything():
    episodes = generate_episodes(2, "val", 3, seed=1, scenes=["house-00061"], progress=False)
    runs = []
    for _ in range(2):
        env = small_env(episodes)
        rng = np.random.default_rng(0)
        obs, _ = env.reset(seed=5)
        trace = [obs]
        for _ in range(40):
            obs, reward, terminated, truncated, info = env.step(int(rng.integers(1, 4)))
            trace.append((obs, reward, terminated, truncated, info["metrics"]))
            if terminated or truncated:
                break
        runs.append(trace)
        env.close()
    a, b = runs
    assert len(a) == len(b)
    for x, y in zip(a[1:], b[1:], strict=True):
        for key in x[0]:
            assert x[0][key].tobytes() == y[0][key].tobytes()
        assert x[1:] == y[1:]


def test_registered_ids():
    for m in (1, 2, 3):
        assert f"MultiON/{m}-ON-v0" in gym.registry
    env = gym.make(
        "MultiON/1-ON-v0",
        config=EnvConfig(task=TaskConfig(num_goals=1)),
        episodes=generate_episodes(1, "val", 1, seed=0, scenes=["house-00061"], progress=False),
    )
    obs, info = env.reset(seed=0)
    assert set(obs) == {"rgb", "depth", "goal"} and "metrics" in info


def test_online_train_sampling_stays_in_a_house_for_episodes_per_scene():
    config = EnvConfig(
        task=TaskConfig(num_goals=1),
        split="train",
        sensors=("goal",),
        episodes_per_scene=3,
    )
    env = MultiONEnv(config)
    scenes = []
    for seed in (5, None, None):
        _, info = env.reset(seed=seed)
        scenes.append(info["scene_id"])
    env.close()
    assert scenes[0].startswith("house-") and len(set(scenes)) == 1


@pytest.mark.parametrize("max_geodesic", [3.0, 20.0])
def test_online_max_geodesic_bounds_the_online_episodes(max_geodesic: float):
    config = EnvConfig(
        task=TaskConfig(num_goals=2),
        split="train",
        sensors=("goal",),
        episodes_per_scene=8,
        online_max_geodesic=max_geodesic,
    )
    env = MultiONEnv(config)
    distances = []
    for seed in (3, *[None] * 7):
        env.reset(seed=seed)
        distances.extend(env.episode.geodesic_distances)
    env.close()
    assert min(distances) >= 2.0
    if max_geodesic < 20:
        assert max(distances) <= max_geodesic
    else:  # the default draws far goals too: the bound above is not vacuous
        assert max(distances) > 3.0


def test_online_max_geodesic_outside_its_range_names_the_field():
    with pytest.raises(
        ValueError, match=r"online_max_geodesic = 1.5 is out of range: allowed \[2, 20\]"
    ):
        EnvConfig(online_max_geodesic=1.5)
