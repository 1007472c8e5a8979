"""The val and test datasets shipped with the package."""

import pytest

from multion.config.datasets import (
    DISTRACTOR_VARIANT,
    load_dataset,
    packaged_dataset_path,
    read_header,
)
from multion.config.task import EnvConfig, TaskConfig
from multion.scenes.registry import GENERATOR_VERSION, scene_ids
from multion.task.env import MultiONEnv


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
    assert (
        read_header(packaged_dataset_path(m, split))["scene_generator_version"] == GENERATOR_VERSION
    )


@pytest.mark.parametrize("split", ["val", "test"])
def test_packaged_distractor_datasets(split):
    path = packaged_dataset_path(3, split, DISTRACTOR_VARIANT)
    assert path.parent.name == "3-on-distractors"
    episodes = load_dataset(path, num_goals=3, num_distractors=DISTRACTOR_VARIANT)
    assert len(episodes) == 1000 and {e.scene_id for e in episodes} == set(scene_ids(split))
    for episode in episodes:
        goals = {g.category for g in episode.goals}
        assert len(episode.distractors) == 3 and not goals & {
            d.category for d in episode.distractors
        }


def test_env_uses_the_packaged_dataset_by_default():
    env = MultiONEnv(EnvConfig(task=TaskConfig(num_goals=2), sensors=("goal",), split="test"))
    _, info = env.reset(seed=0)
    assert info["episode_id"].startswith("test-2-on-")
    first = load_dataset(packaged_dataset_path(2, "test"))[0]
    assert info["metrics"]["distance_to_goal"] == pytest.approx(
        first.geodesic_distances[0], abs=1e-3
    )  # stored to 4 decimals
