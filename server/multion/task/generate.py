"""Generating episode datasets for a split: seeded, reproducible, spread evenly over its scenes."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from tqdm import tqdm

from multion.config.datasets import save_dataset, variant_name
from multion.config.episode import Episode
from multion.config.task import EpisodeConstraints
from multion.scenes.registry import scene_ids
from multion.sim.simulator import Simulator
from multion.task.sampling import iter_chunks, sample_episode


def generate_episodes(
    num_goals: int,
    split: str,
    count: int,
    seed: int = 0,
    scenes: Sequence[str] | None = None,
    constraints: EpisodeConstraints = EpisodeConstraints(),
    progress: bool = True,
    num_distractors: int = 0,
) -> list[Episode]:
    """``count`` episodes of m-ON over the split's scenes (or ``scenes``), grouped by scene.

    Each scene gets its own random stream derived from ``(seed, m, scene index)``, so a scene's
    episodes do not change when other scenes are added or removed.
    """
    scenes = list(scenes) if scenes is not None else scene_ids(split)
    sim = Simulator()
    episodes: list[Episode] = []
    name = variant_name(num_goals, num_distractors)
    bar = tqdm(total=count, desc=f"{name} {split}", unit="ep", disable=not progress)
    try:
        for index, quota in iter_chunks(scenes, count):
            if quota == 0:
                continue
            scene = scenes[index]
            grid = sim.load_scene(scene)
            rng = np.random.default_rng([seed, num_goals, index])
            made = 0
            failures = 0
            while made < quota:
                episode_id = f"{split}-{name}-{len(episodes):05d}"
                episode = sample_episode(
                    grid,
                    scene,
                    num_goals,
                    rng,
                    episode_id,
                    constraints,
                    num_distractors=num_distractors,
                )
                if episode is None:
                    failures += 1
                    if failures > 3:
                        raise RuntimeError(
                            f"{scene}: cannot place {num_goals} goals under the constraints"
                        )
                    continue
                episodes.append(episode)
                made += 1
                bar.update(1)
    finally:
        bar.close()
        sim.close()
    return episodes


def generate_dataset(
    out: str | Path,
    num_goals: int,
    split: str,
    count: int,
    seed: int = 0,
    scenes: Sequence[str] | None = None,
    progress: bool = True,
    num_distractors: int = 0,
) -> Path:
    """Generate and write a dataset file; returns its path."""
    episodes = generate_episodes(
        num_goals, split, count, seed, scenes, progress=progress, num_distractors=num_distractors
    )
    info = {"seed": seed, "count": count, "scenes": sorted({e.scene_id for e in episodes})}
    return save_dataset(out, episodes, num_goals, split, info, num_distractors)
