"""``multion bench``: speed measured in one run, printed as ratios (SPEC; issues 2, 3, 5, 14).

Timed unit tests are useless on shared, noisy machines; ratios measured back to back in one
process are not. ``sim`` measures the task's frames per second with each available renderer
(TinyRenderer, EGL) at 256² and 128² on the same poses, and compares each with PyBullet's bare
``getCameraImage``; ``cache`` times house builds with a cold and a warm navigable-grid cache
and a 100-episode oracle-planner evaluation without and with the cache; ``http`` compares the
server with the in-process env. ``explorer`` (in ``multion_agents.bench.explorer``) times the
explorer baseline's thinking before and after issue 23 on the same observations.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import math
import os
import sys
import time

import gymnasium as gym
import numpy as np

from multion.api.cli_serve import add_http_stack_arguments
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.scenes.registry import layout_for
from multion.sim.bullet import pybullet as p
from multion.sim.camera import EGL_LIGHT_POSITION, EGL_PLUGIN_LIGHT, Camera, egl_plugin_loads
from multion.sim.world import DEFAULT_LIGHTING, PyBulletWorld
from multion.task.env import MultiONEnv
from multion.task.generate import generate_episodes
from multion_agents.bench.explorer import run_explorer_bench
from multion_agents.bench.gl import bench_gl
from multion_agents.bench.goal_pixels import run_goal_pixels_bench
from multion_agents.bench.grid_cache import bench_cache
from multion_agents.bench.http import http_renderers, run_http_bench
from multion_agents.bench.lanes import MAX_LANES, run_lanes_bench
from multion_agents.bench.leaderboard import run_leaderboard_bench
from multion_agents.bench.memory import bench_memory
from multion_agents.bench.pages import run_pages_bench
from multion_agents.bench.participants import run_participants_bench
from multion_agents.bench.reset import run_reset_bench
from multion_agents.bench.site_diversity import run_diversity_bench
from multion_agents.bench.site_memory import run_site_memory_bench
from multion_agents.bench.stepping import timed_steps

SCENE = "house-00061"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--only",
        choices=[
            *("sim", "cache", "http", "train", "memory", "leaderboard", "lanes", "pages"),
            *("explorer", "reset", "diversity", "site-memory", "participants", "learner"),
            *("env-processes", "goal-pixels"),
        ],
        action="append",
        help="run only these parts (repeatable; default: sim, cache and http)",
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
    parser.add_argument(
        "--eval-episodes",
        type=int,
        default=100,
        help="3-ON val episodes of the timed oracle-planner evaluations (default 100)",
    )
    explorer = parser.add_argument_group("explorer bench (--only explorer)")
    explorer.add_argument("--explorer-image", type=int, default=256, help="camera size (256)")
    explorer.add_argument(
        "--explorer-houses", type=int, default=3, help="val houses, one episode each (3)"
    )
    explorer.add_argument("--explorer-steps", type=int, default=500, help="steps per episode (500)")
    train = parser.add_argument_group("training bench (--only train, needs torch)")
    train.add_argument(
        "--train-recipe",
        choices=["default", "v3"],
        default="default",
        help="settings: issue 22's bench (default) or the v3 recipe's (docs/learned.md)",
    )
    train.add_argument("--train-agent", help="learned agent (default oracle-map)")
    train.add_argument("--train-image-size", type=int, help="camera size (64; v3: 36)")
    train.add_argument(
        "--train-envs",
        help="comma-separated numbers of local environments, one row each (4; v3: 8; "
        "e.g. 8,16,32,64 with --train-updates 2)",
    )
    train.add_argument(
        "--train-envs-per-process",
        type=int,
        default=1,
        help="local environments per simulator process (default 1)",
    )
    train.add_argument(
        "--train-updates", type=int, help="PPO updates, the first one not timed (default 4)"
    )
    learner = parser.add_argument_group("learner bench (--only learner, needs torch, no simulator)")
    learner.add_argument(
        "--learner-agents",
        help="comma-separated learned agents (default: the central comparison's five)",
    )
    learner.add_argument(
        "--learner-updates", type=int, default=2, help="timed PPO updates per agent (default 2)"
    )
    learner.add_argument(
        "--learner-envs",
        help="comma-separated numbers of environments, one row each (default 8,16,32,64)",
    )
    learner.add_argument(
        "--learner-mixed-precision",
        default="off",
        help="the update's precision: off (default), bf16 or fp16 (CUDA only)",
    )
    learner.add_argument(
        "--learner-image-size",
        type=int,
        default=36,
        help="RGB-D side in pixels (36-128, default 36; the 128² recipe: 128)",
    )
    learner.add_argument(
        "--learner-freeze-vision",
        action="store_true",
        help="also time each agent with its image encoder frozen (--freeze-vision), a row each",
    )
    parser.add_argument(
        "--participants",
        type=int,
        default=8,
        help="participants playing at once in the participants bench (1-64, default 8)",
    )
    parser.add_argument(
        "--lanes",
        type=int,
        default=2,
        help="lanes of the lanes bench's second run (2-8, default 2: the ×1.6 target)",
    )
    parser.add_argument(
        "--camera-size",
        type=int,
        help="camera width and height of the lanes bench (default 256) and the participants "
        "bench (default 64), 16-512",
    )
    parser.add_argument(
        "--device",
        default="cpu",
        help="torch device of the training and learner benches: cpu (default) or cuda (needs a "
        "CUDA GPU)",
    )
    parser.add_argument(
        "--renderer",
        choices=["all", "tiny", "gl", "egl"],
        default="all",
        help="renderers of the sim bench: every one that loads here (default), or only one "
        "(gl and egl need a GPU or Mesa's EGL; gl is measured beside tiny); the goal-pixels "
        "bench draws with this one, or with gl where it opens (default); the http, lanes and "
        "participants benches measure this one, or tiny and gl where it opens (default)",
    )


def run(args: argparse.Namespace) -> int:
    parts = args.only or ["sim", "cache", "http"]
    if "sim" in parts:
        if args.renderer == "egl" and not egl_plugin_loads():
            print(
                "sim bench with --renderer egl needs EGL: pybullet's eglRenderer plugin did not "
                "load here (a GPU with its driver's libEGL, or Mesa's: apt-get install libegl1 "
                "libegl-mesa0 libgl1-mesa-dri)"
            )
            return 2
        if args.renderer != "gl":
            bench_sim(args.steps, args.episodes, args.renderer)
        if args.renderer in ("all", "gl") and bench_gl(args.steps):
            # on a GPU machine: frames/s per process and per GPU, one process per core
            bench_processes("gl", 256, args.steps)
    if "reset" in parts:
        run_reset_bench()
    if "diversity" in parts:
        run_diversity_bench()
    if "site-memory" in parts:
        run_site_memory_bench()
    if "goal-pixels" in parts:
        run_goal_pixels_bench(renderer=args.renderer)
    if "env-processes" in parts:
        from multion_agents.bench.env_processes import run_env_processes_bench

        run_env_processes_bench(steps=min(args.steps, 100))
    if "cache" in parts:
        bench_cache(args.eval_episodes)
    if "memory" in parts:
        bench_memory()
    renderers, why_not = http_renderers(args.renderer)
    served = {"http", "lanes", "participants"} & set(parts)
    if served and why_not is not None:
        print(f"{' and '.join(sorted(served))} bench with --renderer {args.renderer}: {why_not}")
        return 2
    if args.camera_size is not None and not 16 <= args.camera_size <= 512:
        print(f"multion bench: --camera-size must be in [16, 512], got {args.camera_size}")
        return 2
    if "http" in parts:
        run_http_bench(
            steps=args.steps,
            server_options=["--http", args.http, "--loop", args.loop],
            renderers=renderers,
        )
    if "lanes" in parts:
        if not 2 <= args.lanes <= MAX_LANES:
            print(f"multion bench: --lanes must be in [2, {MAX_LANES}], got {args.lanes}")
            return 2
        for renderer in renderers:
            run_lanes_bench(size=args.camera_size or 256, renderer=renderer, lanes=args.lanes)
    if "participants" in parts:
        for renderer in renderers:
            try:
                run_participants_bench(
                    args.participants, size=args.camera_size or 64, renderer=renderer
                )
            except ValueError as error:
                print(f"multion bench: --participants: {error}", file=sys.stderr)
                return 2
    if "leaderboard" in parts:
        run_leaderboard_bench(server_options=["--http", args.http, "--loop", args.loop])
    if "pages" in parts:
        run_pages_bench()
    if "explorer" in parts:
        run_explorer_bench(args.explorer_image, args.explorer_houses, args.explorer_steps)
    if "train" in parts:
        from multion_agents.bench.learner import parse_counts
        from multion_agents.bench.train import bench_settings, run_train_bench

        try:
            envs = parse_counts("--train-envs", args.train_envs, 256) if args.train_envs else None
            settings = bench_settings(
                args.train_recipe, args.train_agent, args.train_image_size, envs,
                args.train_updates, args.device, args.train_envs_per_process,
            )  # fmt: skip
        except ValueError as error:
            print(f"multion bench: {error}", file=sys.stderr)
            return 2
        if run_train_bench(settings) is None:
            return 2
    if "learner" in parts:
        from multion_agents.bench.learner import learner_settings, run_learner_bench

        try:
            bench = learner_settings(
                args.learner_agents, args.learner_updates, args.device, args.learner_envs,
                args.learner_mixed_precision, args.learner_image_size, args.learner_freeze_vision,
            )  # fmt: skip
        except ValueError as error:
            print(f"multion bench: {error}", file=sys.stderr)
            return 2
        if run_learner_bench(bench) is None:
            return 2
    return 0


def bench_sim(steps: int = 300, episodes: int = 1000, renderer: str = "all") -> dict[str, float]:
    """Print and return the simulator numbers of issue 2, and frames/s of several simulator
    processes side by side (per process and per GPU for EGL); ``renderer`` "all" measures every
    renderer that loads here."""
    results: dict[str, float] = {}
    start = time.perf_counter()
    episode_list = generate_episodes(3, "val", 4, seed=0, scenes=[SCENE], progress=False)
    results["scene_build_s"] = time.perf_counter() - start  # includes 4 episodes (~0.2 s)
    print(f"scene {SCENE}: build + navigable grid + 4 episodes: {results['scene_build_s']:.2f} s")
    renderers = ["tiny"] + (["egl"] if egl_plugin_loads() else [])
    if len(renderers) == 1:
        print(
            "EGL: the eglRenderer plugin does not load here (see docs/training-speed.md); tiny only"
        )
    if renderer != "all":
        renderers = [renderer]
    print(
        f"{'resolution':>10} {'renderer':>8} {'env frames/s':>13} {'raw renders/s':>14} "
        f"{'env/raw':>8}   (RGB-D + goal, one process, same poses)"
    )
    for size in (256, 128):
        for renderer in renderers:
            config = EnvConfig(
                task=TaskConfig(num_goals=3),
                camera=CameraConfig(width=size, height=size, renderer=renderer),
                sensors=("rgb", "depth", "goal"),
            )
            env = MultiONEnv(config, episodes=episode_list)
            env_rate, walked = timed_steps(env, steps)
            assert env.sim.world is not None
            results[f"draws_{renderer}"] = env.sim.world.scene_draws()
            raw_rate = _raw_render_rate(env, walked)
            used = env.sim.renderer
            env.close()
            ratio = env_rate / raw_rate
            results[f"env_sps_{renderer}_{size}"] = env_rate
            results[f"raw_sps_{renderer}_{size}"] = raw_rate
            results[f"ratio_{renderer}_{size}"] = ratio
            print(
                f"{size:>8}² {used:>8} {env_rate:>13.1f} {raw_rate:>14.1f} {ratio:>8.2f}"
                "   (target env/raw ≥ 0.90)"
            )
            if size == 256 and renderer == "egl":
                _egl_rates(walked, config.camera, results)
                _print_egl_rates(results, size)
            if size == 256 and renderer == "tiny":
                plain, textured = _appearance_rates(walked, cfg_camera=config.camera)
                results["plain_rps_256"], results["textured_rps_256"] = plain, textured
                print(
                    f"{'':>10} textures and lighting: {textured:.1f} vs {plain:.1f} renders/s "
                    f"with plain colours (ratio {textured / plain:.2f}; target ≥ 0.80)"
                )
        if size == 256 and {"egl", "tiny"} <= set(renderers):
            egl_draws = (
                f", EGL {results['draws_egl_per_box']:.0f} with a body per box (before issue "
                f"23), {results['draws_egl']:.0f} merged"
            )
            print(
                f"{'':>10} {SCENE} scene draws per image: TinyRenderer "
                f"{results['draws_tiny']:.0f}{egl_draws}"
            )
        if {"egl", "tiny"} <= set(renderers):
            speedup = results[f"env_sps_egl_{size}"] / results[f"env_sps_tiny_{size}"]
            results[f"egl_speedup_{size}"] = speedup
            target = "   (target ≥ 1.3 at 256², one EGL thread per process)" if size == 256 else ""
            print(f"{size:>8}² EGL / TinyRenderer frames per second: {speedup:.2f}×{target}")
    for name in renderers:  # EGL at the GPU target's 256² (≥ 500 frames/s per process)
        results.update(bench_processes(name, 256 if name == "egl" else 128, steps))
    start = time.perf_counter()
    generate_episodes(3, "val", episodes, seed=0, progress=False)
    results["generate_s"] = time.perf_counter() - start
    print(
        f"generating {episodes} 3-ON val episodes (11 scenes, grids included): {results['generate_s']:.1f} s"
    )
    return results


def bench_processes(renderer: str, size: int, steps: int) -> dict[str, float]:
    """Frames/s of 1, 4 and up to one simulator process per core stepping side by side (3-ON
    val, RGB-D + goal, never FOUND): per process, and in all (per GPU for EGL, all processes
    rendering on this machine's one GPU)."""
    cores = os.cpu_count() or 1
    counts = sorted({1, min(4, cores), cores})
    config = EnvConfig(
        task=TaskConfig(num_goals=3),
        camera=CameraConfig(width=size, height=size, renderer=renderer),
        sensors=("rgb", "depth", "goal"),
    )
    results: dict[str, float] = {}
    # Mesa's EGL renders on the CPU: only on a GPU machine is the total the GPU's
    where = "in all (per GPU on a one-GPU machine)" if renderer in ("egl", "gl") else "in all"
    for count in counts:
        vector = gym.vector.AsyncVectorEnv(
            [functools.partial(MultiONEnv, config) for _ in range(count)], context="spawn"
        )
        try:
            vector.reset(seed=0)
            rng = np.random.default_rng(0)
            for _ in range(5):  # warm-up: scenes loaded, EGL contexts made
                vector.step(rng.choice([1, 2, 3], size=count))
            begin = time.perf_counter()
            for _ in range(steps):
                vector.step(rng.choice([1, 1, 2, 3], size=count))
            total = steps * count / (time.perf_counter() - begin)
        finally:
            vector.close()
        results[f"processes_{renderer}_{size}_{count}"] = total
        print(
            f"{size:>8}² {renderer:>8} {count:>2} processes side by side: "
            f"{total / count:7.1f} frames/s per process, {total:7.1f} {where}"
        )
    return results


def _appearance_rates(
    poses: list[tuple[float, float, float]], cfg_camera: CameraConfig
) -> tuple[float, float]:
    """Renders/s of the bench scene with plain colours (textures off, default light) and as it
    is (textured floors and walls, its own light), at the same poses, back to back."""
    layout = layout_for(SCENE)
    plain_layout = dataclasses.replace(
        layout,
        boxes=tuple(dataclasses.replace(b, texture="") for b in layout.boxes),
        metadata={k: v for k, v in layout.metadata.items() if k != "lighting"},
    )
    rates = []
    for scene in (plain_layout, layout):
        world = PyBulletWorld.from_layout(scene)
        camera = Camera(cfg_camera, world.client, world.renderer, world.lighting)
        assert scene is layout or world.lighting == DEFAULT_LIGHTING
        begin = time.perf_counter()
        for x, y, yaw in poses:
            camera.render(x, y, yaw, 0.0)
        rates.append(len(poses) / (time.perf_counter() - begin))
        world.close()
    return rates[0], rates[1]


def _print_egl_rates(results: dict[str, float], size: int) -> None:
    r = {k: results[f"rps_egl_{k}_{size}"] for k in (
        "per_box_plugin_light", "merged_plugin_light", "per_box_far_light", "merged_far_light"
    )}  # fmt: skip
    print(
        f"{'':>10} EGL renders/s: body per box {r['per_box_plugin_light']:.1f}, merged "
        f"{r['merged_plugin_light']:.1f}; far light: body per box {r['per_box_far_light']:.1f}, "
        f"merged {r['merged_far_light']:.1f} (before issue 23: the first; now: the last)"
    )


def _egl_rates(
    poses: list[tuple[float, float, float]], cfg_camera: CameraConfig, results: dict[str, float]
) -> None:
    """EGL renders/s of the bench scene at the same poses, back to back, with one body per box
    or the boxes merged into one mesh, and with the plugin's own light (its shadow pass runs)
    or the cameras' far light (``sim.camera.EGL_LIGHT_POSITION``); records them and the draws."""
    for merge in (False, True):
        world = PyBulletWorld.from_layout(layout_for(SCENE), "egl", merge=merge)
        bodies = "merged" if merge else "per_box"
        results[f"draws_egl_{bodies}"] = world.scene_draws()
        camera = Camera(cfg_camera, world.client, world.renderer, world.lighting)
        camera.render(*poses[0], 0.0)  # the plugin uploads the scene on its first image
        for light, position in (
            ("plugin_light", EGL_PLUGIN_LIGHT),
            ("far_light", EGL_LIGHT_POSITION),
        ):
            camera.egl_light_position = position
            begin = time.perf_counter()
            for x, y, yaw in poses:
                camera.render(x, y, yaw, 0.0)
            rate = len(poses) / (time.perf_counter() - begin)
            results[f"rps_egl_{bodies}_{light}_{cfg_camera.width}"] = rate
        world.close()


def _raw_render_rate(env: MultiONEnv, poses: list[tuple[float, float, float]]) -> float:
    """Bare ``getCameraImage`` calls with the same camera, scene and lighting, at the same poses."""
    camera, grid, world = env.sim.camera, env.sim.grid, env.sim.world
    assert camera is not None and grid is not None and world is not None
    flag = p.ER_BULLET_HARDWARE_OPENGL if camera.renderer == "egl" else p.ER_TINY_RENDERER
    light = {"lightDirection": EGL_LIGHT_POSITION} if camera.renderer == "egl" else {}
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
            renderer=flag,
            flags=p.ER_NO_SEGMENTATION_MASK,
            physicsClientId=world.client,
            **light,
        )
        elapsed += time.perf_counter() - begin
    return len(poses) / elapsed
