"""``multion bench --only goal-pixels``: how many pixels the goal covers at each image size.

Issue 44 asks whether image size explains why the agents that must see their goal learn nothing
at 36². This measures what a camera of each size is shown: val episodes (1-ON), poses on
navigable cells at 1–2, 2–3 and 3–5 m from the goal, each facing it, the same poses rendered at
every size; per distance band, the share of poses where the goal shows at all (a wall may hide
it) and the median number of its pixels where it shows. Not a timing: the figures do not depend
on the machine's load.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from multion.config.episode import Episode
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.sim.camera import why_not_gl
from multion.sim.navgrid import NavGrid
from multion.task.env import MultiONEnv
from multion.task.generate import generate_episodes

SIZES = (36, 128, 256)
BANDS = ((1.0, 2.0), (2.0, 3.0), (3.0, 5.0))
"""Distances from the goal (m), as in docs/learned.md's 36² against 256² figures."""


@dataclass(frozen=True)
class BandPixels:
    """One distance band at one image size."""

    poses: int
    shown: int
    median_pixels: float
    """Over the poses where the goal shows; nan where it shows in none."""

    @property
    def shown_share(self) -> float:
        return self.shown / max(self.poses, 1)


def poses_facing(
    grid: NavGrid, goal: np.ndarray, band: tuple[float, float], count: int, seed: int
) -> list[tuple[float, float, float]]:
    """Up to ``count`` distinct navigable cell centres ``band`` metres from ``goal`` (seeded),
    each with the heading that looks straight at it."""
    rows, cols = np.nonzero(grid.navigable)
    points = grid.cell_to_world(rows, cols)
    distance = np.hypot(*(points - goal).T)
    candidates = points[(distance >= band[0]) & (distance < band[1])]
    rng = np.random.default_rng(seed)
    chosen = rng.choice(len(candidates), size=min(count, len(candidates)), replace=False)
    return [
        (float(x), float(y), math.atan2(goal[1] - y, goal[0] - x)) for x, y in candidates[chosen]
    ]


def goal_pixel_counts(
    episodes: Sequence[Episode],
    sizes: Sequence[int] = SIZES,
    poses_per_band: int = 6,
    renderer: str = "tiny",
) -> dict[int, dict[tuple[float, float], list[int]]]:
    """Pixels of each episode's first goal at every pose: ``counts[size][band]``, one entry per
    pose, the poses the same at every size."""
    envs = {
        size: MultiONEnv(
            EnvConfig(
                task=TaskConfig(num_goals=1),
                camera=CameraConfig(width=size, height=size, renderer=renderer),
                sensors=("depth",),
            ),
            episodes=list(episodes),
        )
        for size in sizes
    }
    counts: dict[int, dict[tuple[float, float], list[int]]] = {
        size: {band: [] for band in BANDS} for size in sizes
    }
    try:
        for index, episode in enumerate(episodes):
            for env in envs.values():
                env.reset(seed=index)
            first = envs[sizes[0]].sim
            assert first.grid is not None
            goal = np.asarray(episode.goals[0].position[:2], dtype=np.float64)
            for band_index, band in enumerate(BANDS):
                seed = index * len(BANDS) + band_index
                for x, y, yaw in poses_facing(first.grid, goal, band, poses_per_band, seed):
                    for size, env in envs.items():
                        assert env.sim.world is not None
                        body = env.sim.world.goal_bodies_in_use[0]
                        env.sim.set_agent(np.array([x, y]), yaw)
                        segmentation = env.sim.render(segmentation=True).segmentation
                        assert segmentation is not None
                        counts[size][band].append(int(np.count_nonzero(segmentation == body)))
    finally:
        for env in envs.values():
            env.close()
    return counts


def summarise(pixels: Sequence[int]) -> BandPixels:
    shown = [count for count in pixels if count > 0]
    median = float(np.median(shown)) if shown else math.nan
    return BandPixels(poses=len(pixels), shown=len(shown), median_pixels=median)


def run_goal_pixels_bench(
    episodes: int = 12, poses_per_band: int = 6, renderer: str = "all"
) -> dict[str, float]:
    """Print the table; ``renderer`` "all" takes gl where a GL context opens, else tiny."""
    if renderer == "all":
        renderer = "gl" if why_not_gl() is None else "tiny"
    chosen = generate_episodes(1, "val", episodes, seed=0, progress=False)
    counts = goal_pixel_counts(chosen, SIZES, poses_per_band, renderer)
    print(
        f"goal pixels: {len(chosen)} val 1-ON episodes (seed 0), up to {poses_per_band} poses "
        f"per band facing the goal, {renderer} renderer, the same poses at every size"
    )
    print(f"{'band':>8} {'size':>6} {'poses':>6} {'shown':>7} {'median pixels':>14}")
    results: dict[str, float] = {}
    for band in BANDS:
        for size in SIZES:
            row = summarise(counts[size][band])
            name = f"{band[0]:g}-{band[1]:g}m_{size}"
            results[f"goal_pixels_median_{name}"] = row.median_pixels
            results[f"goal_shown_share_{name}"] = row.shown_share
            print(
                f"{band[0]:g}–{band[1]:g} m {size:>5}² {row.poses:>6} "
                f"{100 * row.shown_share:>6.0f}% {row.median_pixels:>14.1f}"
            )
    return results
