"""``multion bench --only goal-pixels``: the goal's pixels by image size (issue 44)."""

import math

import numpy as np

from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion.task.generate import generate_episodes
from multion_agents.bench.goal_pixels import (
    BANDS,
    goal_pixel_counts,
    poses_facing,
    run_goal_pixels_bench,
    summarise,
)


def _env(size: int, episodes) -> MultiONEnv:
    config = EnvConfig(
        task=TaskConfig(num_goals=1),
        camera=CameraConfig(width=size, height=size),
        sensors=("depth",),
    )
    return MultiONEnv(config, episodes=episodes)


def test_poses_stand_on_navigable_cells_in_the_band_and_face_the_goal() -> None:
    episodes = generate_episodes(1, "val", 1, seed=0, progress=False)
    env = _env(16, episodes)
    try:
        env.reset(seed=0)
        grid = env.sim.grid
        assert grid is not None
        goal = np.asarray(episodes[0].goals[0].position[:2])
        poses = poses_facing(grid, goal, (2.0, 3.0), 6, seed=1)
        assert len(poses) == 6 and len(set(poses)) == 6
        assert poses == poses_facing(grid, goal, (2.0, 3.0), 6, seed=1)
        assert poses != poses_facing(grid, goal, (2.0, 3.0), 6, seed=2)
        for x, y, yaw in poses:
            assert grid.is_navigable(np.array([x, y]))
            assert 2.0 <= math.hypot(goal[0] - x, goal[1] - y) < 3.0
            ahead = np.array([math.cos(yaw), math.sin(yaw)])
            to_goal = (goal - (x, y)) / np.linalg.norm(goal - (x, y))
            assert float(ahead @ to_goal) > 0.999
        # the goal never shows behind the camera
        world = env.sim.world
        assert world is not None
        for x, y, yaw in poses:
            env.sim.set_agent(np.array([x, y]), yaw + math.pi)
            segmentation = env.sim.render(segmentation=True).segmentation
            assert not np.any(segmentation == world.goal_bodies_in_use[0])
    finally:
        env.close()


def test_the_same_poses_show_the_goal_larger_on_a_larger_image() -> None:
    episodes = generate_episodes(1, "val", 3, seed=0, progress=False)
    counts = goal_pixel_counts(episodes, sizes=(24, 48), poses_per_band=3)
    for band in BANDS:
        assert len(counts[24][band]) == len(counts[48][band]) > 0
    small = sum(sum(counts[24][band]) for band in BANDS)
    large = sum(sum(counts[48][band]) for band in BANDS)
    assert small > 0
    assert 2.5 < large / small < 6.0  # four times the pixels, give or take the goal's edges
    shown_small = sum(c > 0 for band in BANDS for c in counts[24][band])
    shown_large = sum(c > 0 for band in BANDS for c in counts[48][band])
    assert shown_large >= shown_small


def test_the_median_is_taken_where_the_goal_shows() -> None:
    row = summarise([0, 0, 4, 10, 30])
    assert (row.poses, row.shown, row.median_pixels) == (5, 3, 10.0)
    assert math.isnan(summarise([0, 0]).median_pixels)


def test_the_bench_prints_every_band_and_size(capsys) -> None:
    results = run_goal_pixels_bench(episodes=2, poses_per_band=2, renderer="tiny")
    out = capsys.readouterr().out
    assert "tiny renderer" in out
    for size in (36, 128, 256):
        assert f"{size}²" in out
        assert 0.0 <= results[f"goal_shown_share_2-3m_{size}"] <= 1.0
    assert len(results) == 2 * 3 * len(BANDS)
