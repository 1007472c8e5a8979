"""``multion bench``: speed measured in one run, printed as ratios (SPEC; issues 2, 3 and 5).

Timed unit tests are useless on shared, noisy machines; ratios measured back to back in one
process are not. ``sim`` compares the task's steps per second with PyBullet's bare
``getCameraImage`` on the same scene; ``http`` compares the server with the in-process env.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np
import pybullet as p

from multion.api.cli_serve import add_http_stack_arguments
from multion.sim.camera import CameraConfig
from multion.task.env import EnvConfig, MultiONEnv, TaskConfig
from multion.task.generate import generate_episodes

SCENE = "house-00061"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--only",
        choices=["sim", "http", "train", "memory"],
        action="append",
        help="run only these parts (repeatable; default: sim and http)",
    )
    add_http_stack_arguments(parser, " of the benchmarked servers")
    parser.add_argument(
        "--steps", type=int, default=300, help="steps per measurement (default 300)"
    )
    parser.add_argument(
        "--episodes",
        type=int,
        default=1000,
        help="3-ON episodes to generate for the generation timing (default 1000)",
    )
    train = parser.add_argument_group("training bench (--only train, needs torch)")
    train.add_argument(
        "--train-agent", default="oracle-map", help="learned agent (default oracle-map)"
    )
    train.add_argument("--train-image-size", type=int, default=64, help="camera size (default 64)")
    train.add_argument("--train-envs", type=int, default=4, help="local environments (default 4)")
    train.add_argument(
        "--train-updates",
        type=int,
        default=4,
        help="PPO updates, the first one not timed (default 4)",
    )


def run(args: argparse.Namespace) -> int:
    parts = args.only or ["sim", "http"]
    if "sim" in parts:
        bench_sim(args.steps, args.episodes)
    if "memory" in parts:
        from multion.api.bench_memory import bench_memory

        bench_memory()
    if "http" in parts:
        from multion.api.bench_http import run_http_bench

        run_http_bench(server_options=["--http", args.http, "--loop", args.loop])
    if "train" in parts:
        from multion_agents.bench_train import run_train_bench

        run_train_bench(
            args.train_agent, args.train_image_size, args.train_envs, args.train_updates
        )
    return 0


def bench_sim(steps: int = 300, episodes: int = 1000) -> dict[str, float]:
    """Print and return the simulator numbers of issue 2."""
    results: dict[str, float] = {}
    start = time.perf_counter()
    episode_list = generate_episodes(3, "val", 4, seed=0, scenes=[SCENE], progress=False)
    results["scene_build_s"] = time.perf_counter() - start  # includes 4 episodes (~0.2 s)
    print(f"scene {SCENE}: build + navigable grid + 4 episodes: {results['scene_build_s']:.2f} s")
    print(f"{'resolution':>10} {'env steps/s':>12} {'raw renders/s':>14} {'ratio':>6}")
    for size in (256, 128):
        config = EnvConfig(
            task=TaskConfig(num_goals=3),
            camera=CameraConfig(width=size, height=size),
            sensors=("rgb", "depth", "goal"),
        )
        env = MultiONEnv(config, episodes=episode_list)
        env_rate, poses = _env_rate(env, steps)
        raw_rate = _raw_render_rate(env, poses)
        env.close()
        ratio = env_rate / raw_rate
        results[f"env_sps_{size}"], results[f"raw_sps_{size}"], results[f"ratio_{size}"] = (
            env_rate,
            raw_rate,
            ratio,
        )
        print(
            f"{size:>8}² {env_rate:>12.1f} {raw_rate:>14.1f} {ratio:>6.2f}   (target ratio ≥ 0.90)"
        )
        if size == 256:
            plain, textured = _appearance_rates(poses, cfg_camera=config.camera)
            results["plain_rps_256"], results["textured_rps_256"] = plain, textured
            print(
                f"{'':>10} textures and lighting: {textured:.1f} vs {plain:.1f} renders/s with "
                f"plain colours (ratio {textured / plain:.2f}; target ≥ 0.80)"
            )
    start = time.perf_counter()
    generate_episodes(3, "val", episodes, seed=0, progress=False)
    results["generate_s"] = time.perf_counter() - start
    print(
        f"generating {episodes} 3-ON val episodes (11 scenes, grids included): {results['generate_s']:.1f} s"
    )
    return results


def _env_rate(env: MultiONEnv, steps: int) -> tuple[float, list[tuple[float, float, float]]]:
    """Steps per second of the full task step (motion, render, depth, measures), and its poses."""
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    done_steps, elapsed, poses = 0, 0.0, []
    while done_steps < steps:
        action = int(rng.choice([1, 1, 2, 3]))  # never FOUND: keep episodes running
        begin = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        elapsed += time.perf_counter() - begin
        poses.append((float(env.sim.position[0]), float(env.sim.position[1]), env.sim.yaw))
        done_steps += 1
        if terminated or truncated:
            env.reset()
    return done_steps / elapsed, poses


def _appearance_rates(
    poses: list[tuple[float, float, float]], cfg_camera: CameraConfig
) -> tuple[float, float]:
    """Renders/s of the bench scene with plain colours (textures off, default light) and as it
    is (textured floors and walls, its own light), at the same poses, back to back."""
    from multion.scenes.registry import layout_for
    from multion.sim.camera import Camera
    from multion.sim.world import DEFAULT_LIGHTING, PyBulletWorld

    layout = layout_for(SCENE)
    plain_layout = dataclasses.replace(
        layout,
        boxes=tuple(dataclasses.replace(b, texture="") for b in layout.boxes),
        metadata={k: v for k, v in layout.metadata.items() if k != "lighting"},
    )
    rates = []
    for scene in (plain_layout, layout):
        world = PyBulletWorld.from_layout(scene)
        camera = Camera(cfg_camera, world.client, world.lighting)
        assert scene is layout or world.lighting == DEFAULT_LIGHTING
        begin = time.perf_counter()
        for x, y, yaw in poses:
            camera.render(x, y, yaw, 0.0)
        rates.append(len(poses) / (time.perf_counter() - begin))
        world.close()
    return rates[0], rates[1]


def _raw_render_rate(env: MultiONEnv, poses: list[tuple[float, float, float]]) -> float:
    """Bare ``getCameraImage`` calls with the same camera, scene and lighting, at the same poses."""
    camera, grid, world = env.sim.camera, env.sim.grid, env.sim.world
    assert camera is not None and grid is not None and world is not None
    cfg = camera.config
    elapsed = 0.0
    for x, y, yaw in poses:
        eye = (x, y, grid.floor_z + cfg.sensor_height)
        view = p.computeViewMatrix(eye, (x + math.cos(yaw), y + math.sin(yaw), eye[2]), (0, 0, 1))
        begin = time.perf_counter()
        p.getCameraImage(
            cfg.width,
            cfg.height,
            view,
            camera.projection,
            shadow=0,
            lightAmbientCoeff=camera.ambient,
            lightDiffuseCoeff=camera.diffuse,
            lightSpecularCoeff=0.0,
            renderer=p.ER_TINY_RENDERER,
            flags=p.ER_NO_SEGMENTATION_MASK,
            physicsClientId=world.client,
        )
        elapsed += time.perf_counter() - begin
    return len(poses) / elapsed
