"""Timed env steps shared by the simulator benches (``multion bench --only sim``)."""

from __future__ import annotations

import time

import numpy as np

from multion.task.env import MultiONEnv

Pose = tuple[float, float, float]


def timed_steps(env: MultiONEnv, steps: int, warm_up: int = 0) -> tuple[float, list[Pose]]:
    """Steps per second of the full task step (motion, render, depth, measures) over seeded
    actions that never call FOUND, and the poses walked, so that every renderer walks the same
    poses. ``warm_up`` untimed turns first (the gl renderer compiles its shaders then)."""
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    for _ in range(warm_up):
        env.step(int(rng.choice([2, 3])))
    done, elapsed, poses = 0, 0.0, []
    while done < steps:
        action = int(rng.choice([1, 1, 2, 3]))
        begin = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        elapsed += time.perf_counter() - begin
        poses.append((float(env.sim.position[0]), float(env.sim.position[1]), env.sim.yaw))
        done += 1
        if terminated or truncated:
            env.reset()
    return done / elapsed, poses
