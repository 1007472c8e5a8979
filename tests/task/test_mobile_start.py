"""Starts where the agent cannot move: `can_step` agrees with the simulator, and
`EpisodeConstraints(mobile_start=True)` (hidden episodes) refuses them while changing nothing
else of the random stream."""

from __future__ import annotations

import numpy as np

from multion.scenes.registry import scene_ids
from multion.sim.simulator import Simulator
from multion.task.dataset import (
    EpisodeConstraints,
    can_step,
    iter_chunks,
    load_dataset,
    packaged_dataset_path,
    sample_episode,
)
from multion.task.env import EnvConfig, MultiONEnv

IMMOBILE = "val-1-on-00261"  # one of the 5 packaged v2 episodes that start walled in
SEED = 1  # scripts/make_datasets.py's val seed


def packaged() -> dict[str, object]:
    return {e.episode_id: e for e in load_dataset(packaged_dataset_path(1, "val"), 1)}


def test_can_step_agrees_with_the_simulator() -> None:
    episodes = packaged()
    env = MultiONEnv(EnvConfig(sensors=("gps",)), episodes=[episodes[IMMOBILE]])
    try:
        for episode_id in (IMMOBILE, "val-1-on-00000"):
            episode = episodes[episode_id]
            obs, _ = env.reset(options={"episode": episode})
            moved = False
            for _ in range(12):  # a step in every heading the agent can turn to
                obs, *_ = env.step(1)
                moved |= bool(np.any(np.abs(obs["gps"]) > 1e-6))
                obs, *_ = env.step(2)
            grid = env.sim.load_scene(episode.scene_id)
            start = np.asarray(episode.start_position[:2])
            assert can_step(grid, start, episode.start_yaw) == moved == (episode_id != IMMOBILE)
    finally:
        env.close()


def scene_of(number: int, scenes: int, count: int) -> tuple[int, int]:
    """The scene index of packaged episode ``number`` and the number of its scene's first."""
    first = 0
    for index, quota in iter_chunks(range(scenes), count):
        if first <= number < first + quota:
            return index, first
        first += quota
    raise AssertionError(f"no episode {number}")


def test_mobile_start_refuses_only_immobile_starts() -> None:
    episodes = [e for e in packaged().values()]
    scenes = scene_ids("val")
    index, first = scene_of(261, len(scenes), len(episodes))
    scene = scenes[index]
    simulator = Simulator()
    try:
        grid = simulator.load_scene(scene)
        streams = {
            mobile: np.random.default_rng([SEED, 1, index]) for mobile in (False, True)
        }
        for k in range(261 - first + 1):
            plain, guarded = (
                sample_episode(grid, scene, 1, streams[m], f"e{k}", EpisodeConstraints(mobile_start=m))
                for m in (False, True)
            )
            assert plain is not None and guarded is not None
            assert plain.start_position == episodes[first + k].start_position  # the packaged stream
            if first + k < 261:
                assert guarded == plain  # nothing else changes
        start = np.asarray(guarded.start_position[:2])
        assert not can_step(grid, np.asarray(plain.start_position[:2]), plain.start_yaw)
        assert guarded.start_position != plain.start_position
        assert can_step(grid, start, guarded.start_yaw)
    finally:
        simulator.close()
