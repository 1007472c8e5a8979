"""The val and test datasets shipped with the package."""

import pytest

from multion.scenes.registry import scene_ids
from multion.task.dataset import load_dataset, packaged_dataset_path
from multion.task.env import EnvConfig, MultiONEnv, TaskConfig


@pytest.mark.parametrize("split", ["val", "test"])
@pytest.mark.parametrize("m", [1, 2, 3])
def test_packaged_dataset(split, m):
    episodes = load_dataset(packaged_dataset_path(m, split), num_goals=m)
    assert len(episodes) == 1000
    assert {e.scene_id for e in episodes} == set(
        scene_ids(split)
    )  # every scene of the split, no other
    for episode in episodes:
        assert len(episode.geodesic_distances) == m
        assert all(2.0 <= d <= 20.0 for d in episode.geodesic_distances)


def test_env_uses_the_packaged_dataset_by_default():
    env = MultiONEnv(EnvConfig(task=TaskConfig(num_goals=2), sensors=("goal",), split="test"))
    _, info = env.reset(seed=0)
    assert info["episode_id"].startswith("test-2-on-")
    first = load_dataset(packaged_dataset_path(2, "test"))[0]
    assert info["metrics"]["distance_to_goal"] == pytest.approx(
        first.geodesic_distances[0], abs=1e-3
    )  # stored to 4 decimals
