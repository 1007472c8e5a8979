"""``multion bench --only sim``, the ``gl`` renderer's part (issue 43): its speed beside
TinyRenderer's in one run, and its pictures against TinyRenderer's.

Speed: env steps per second (RGB-D + goal, 3-ON, one process) with each renderer in turn,
same house, same seeded actions, at 36², 128² and 256²; and the image alone (camera renders
at the poses walked). Pictures: the share of pixels whose depth agrees within 1 cm and whose
segmentation is equal, and the RGB difference, over poses in val houses, a mesh scan of one
and every goal set, at the same three sizes.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from multion.config.episode import Episode, Goal
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.scenes.obj_export import export_obj
from multion.scenes.registry import layout_for, scene_ids
from multion.sim.camera import CameraImage, why_not_gl
from multion.sim.gl.agreement import agreement
from multion.sim.simulator import Simulator
from multion.task.env import MultiONEnv
from multion.task.generate import generate_episodes
from multion_agents.bench.stepping import timed_steps
from multion_client.constants import GOAL_SETS

SIZES = (36, 128, 256)
SPEED_TARGETS = {36: 2.0, 128: 3.0, 256: 6.0}
"""gl / tiny env steps per second asked for on a 2-core CPU (issue 43)."""
SCENE = "house-00061"


def bench_gl(steps: int, poses_per_house: int = 40) -> dict[str, float]:
    """Both parts; an empty result, with the one-line reason, where no GL context opens."""
    reason = why_not_gl()
    if reason is not None:
        print(f"gl renderer not measured: {reason}")
        return {}
    results = bench_gl_speed(steps)
    results.update(bench_gl_pictures(poses_per_house))
    return results


def _load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.1f} / {five:.1f} on {os.cpu_count()} cores"


def bench_gl_speed(steps: int) -> dict[str, float]:
    results: dict[str, float] = {}
    episodes = generate_episodes(3, "val", 4, seed=0, scenes=[SCENE], progress=False)
    print(
        f"gl vs tiny, {SCENE}, RGB-D + goal, one process, same actions, {steps} steps each; "
        f"{_load()}; LP_NUM_THREADS={os.environ.get('LP_NUM_THREADS', '0 (default)')}"
    )
    print(f"{'size':>6} {'renderer':>8} {'env steps/s':>12} {'images/s':>10} {'ms/image':>9}")
    for size in SIZES:
        for renderer in ("tiny", "gl"):
            config = EnvConfig(
                task=TaskConfig(num_goals=3),
                camera=CameraConfig(width=size, height=size, renderer=renderer),
                sensors=("rgb", "depth", "goal"),
            )
            env = MultiONEnv(config, episodes=episodes)
            try:
                env_rate, poses = timed_steps(env, steps, warm_up=3)
                image_rate = _image_rate(env, poses)
                assert env.sim.renderer == renderer
            finally:
                env.close()
            results[f"gl_bench_env_sps_{renderer}_{size}"] = env_rate
            results[f"gl_bench_images_per_s_{renderer}_{size}"] = image_rate
            print(
                f"{size:>5}² {renderer:>8} {env_rate:>12.1f} {image_rate:>10.1f} "
                f"{1000 / image_rate:>9.2f}"
            )
        speedup = results[f"gl_bench_env_sps_gl_{size}"] / results[f"gl_bench_env_sps_tiny_{size}"]
        images = (
            results[f"gl_bench_images_per_s_gl_{size}"]
            / results[f"gl_bench_images_per_s_tiny_{size}"]
        )
        results[f"gl_speedup_{size}"] = speedup
        print(
            f"{size:>5}² gl / tiny: env steps {speedup:.2f}× (target ≥ {SPEED_TARGETS[size]:.0f}×), "
            f"images alone {images:.2f}×"
        )
    print(f"(after: {_load()})")
    return results


def _image_rate(env: MultiONEnv, poses: list[tuple[float, float, float]]) -> float:
    """Camera renders (RGB, depth, no segmentation) per second at ``poses``."""
    camera, grid = env.sim.camera, env.sim.grid
    assert camera is not None and grid is not None
    begin = time.perf_counter()
    for x, y, yaw in poses:
        camera.render(x, y, yaw, grid.floor_z)
    return len(poses) / (time.perf_counter() - begin)


# ---------------------------------------------------------------------- pictures
def bench_gl_pictures(poses_per_house: int, houses: int = 4) -> dict[str, float]:
    """gl against TinyRenderer: val houses (``poses_per_house`` each, goal cylinders in view),
    a mesh scan of the first, and every goal set in a room, at 36², 128² and 256²."""
    results: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as folder:
        scan = export_obj(layout_for(scene_ids("val")[0]), Path(folder) / "scan.obj")
        scenes = [*scene_ids("val")[:houses], str(scan)]
        print(
            f"gl vs tiny pictures: {len(scenes) - 1} val houses and a mesh scan, "
            f"{poses_per_house} poses each, and the {len(GOAL_SETS)} goal sets "
            f"(depth within 1 cm, segmentation equal, RGB |difference| per channel)"
        )
        for size in SIZES:
            tiny: list[CameraImage] = []
            drawn: list[CameraImage] = []
            for number, scene in enumerate(scenes):
                pair = scene_images(scene, size, poses_per_house, seed=number)
                tiny += pair["tiny"]
                drawn += pair["gl"]
            for goal_set in GOAL_SETS:
                pair = goal_set_images(goal_set, size)
                tiny += pair["tiny"]
                drawn += pair["gl"]
            measured = agreement(tiny, drawn)
            for name in ("depth", "segmentation", "rgb_mean", "rgb_p99"):
                results[f"gl_pictures_{name}_{size}"] = getattr(measured, name)
            print(
                f"{size:>5}² {len(tiny)} images: depth {100 * measured.depth:.2f} %, "
                f"segmentation {100 * measured.segmentation:.2f} % (targets ≥ 99 %), RGB mean "
                f"{measured.rgb_mean:.3f}, 99th percentile {measured.rgb_p99:.0f} levels"
            )
    return results


def scene_images(scene: str, size: int, poses: int, seed: int) -> dict[str, list[CameraImage]]:
    """Both renderers' images (metres of depth, segmentation) of ``scene`` at the same
    navigable poses, with goal cylinders one metre ahead of every third pose."""
    images: dict[str, list[CameraImage]] = {}
    rng = np.random.default_rng(seed)
    cells: np.ndarray | None = None
    yaws = rng.uniform(-math.pi, math.pi, poses)
    for renderer in ("tiny", "gl"):
        camera = CameraConfig(width=size, height=size, renderer=renderer, normalize_depth=False)
        sim = Simulator(camera=camera)
        try:
            grid = sim.load_scene(scene)
            free = np.argwhere(grid.navigable)
            if cells is None:
                cells = free[rng.choice(len(free), poses)]
            points = [grid.cell_to_world(row, col) for row, col in cells]
            assert sim.world is not None
            sim.world.place_goals(
                [
                    (
                        (x + math.cos(yaw), y + math.sin(yaw), grid.floor_z),
                        (1.0, 0.3 * (k % 4), 0, 1),
                    )
                    for k, ((x, y), yaw) in enumerate(zip(points, yaws, strict=True))
                    if k % 3 == 0
                ],
                0.15,
                0.8,
            )
            images[renderer] = []
            for (x, y), yaw in zip(points, yaws, strict=True):
                sim.set_agent(np.array([x, y]), float(yaw))
                images[renderer].append(sim.render(segmentation=True))
        finally:
            sim.close()
    return images


def goal_set_images(goal_set: str, size: int) -> dict[str, list[CameraImage]]:
    """Both renderers' view of all 8 goals of ``goal_set`` in a row, in a room."""
    goals = tuple(Goal(c, (0.7 + 0.6 * c, 3.4, 0.0)) for c in range(8))
    episode = Episode("s", "room-6x4", (3.0, 0.6, 0.0), math.pi / 2, goals)
    images: dict[str, list[CameraImage]] = {}
    for renderer in ("tiny", "gl"):
        config = EnvConfig(
            task=TaskConfig(num_goals=8, goal_set=goal_set),
            camera=CameraConfig(
                width=size, height=size, renderer=renderer, hfov_deg=120.0, normalize_depth=False
            ),
            sensors=("depth",),
        )
        env = MultiONEnv(config, episodes=[episode])
        try:
            env.reset(seed=0)
            images[renderer] = [env.sim.render(segmentation=True)]
        finally:
            env.close()
    return images
