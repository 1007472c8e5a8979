"""The ``gl`` renderer (issue 43) against TinyRenderer, the reference: the same world, the same
poses, the same pictures.

Bounds (measured on Mesa's llvmpipe, ``docs/rendering.md``): depth within 1 cm on ≥ 99 % of
pixels, segmentation equal on ≥ 99 %, RGB within a mean absolute difference of 0.5 levels per
channel and a 99th percentile of 2 levels. The tests skip where no OpenGL context opens (the
``gl`` fixture names the packages) unless ``MULTION_REQUIRE_EGL=1``.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from multion.config.episode import Episode, Goal
from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig, TaskConfig
from multion.scenes.obj_export import export_obj
from multion.scenes.registry import layout_for
from multion.sim.bullet import pybullet as p
from multion.sim.camera import CameraImage, RendererUnavailableError
from multion.sim.gl.agreement import DEPTH_TOLERANCE_M, Agreement, agreement
from multion.sim.simulator import Simulator
from multion.task.env import MultiONEnv

MIN_DEPTH_AGREEMENT = 0.99
MIN_SEGMENTATION_AGREEMENT = 0.99
MAX_RGB_MEAN_DIFFERENCE = 0.5
MAX_RGB_P99_DIFFERENCE = 2.0


def _renders(scene: str, size: int, poses: int, seed: int = 0) -> dict[str, list[CameraImage]]:
    """Both renderers' images of ``scene`` at the same navigable poses, goal cylinders in view."""
    images: dict[str, list[CameraImage]] = {}
    rng = np.random.default_rng(seed)
    cells = None
    for renderer in ("tiny", "gl"):
        camera = CameraConfig(width=size, height=size, renderer=renderer, normalize_depth=False)
        sim = Simulator(camera=camera)
        try:
            grid = sim.load_scene(scene)
            assert sim.renderer == renderer
            free = np.argwhere(grid.navigable)
            if cells is None:
                cells = free[rng.choice(len(free), poses)]
            points = [grid.cell_to_world(row, col) for row, col in cells]
            yaws = np.linspace(-math.pi, math.pi, poses, endpoint=False)
            assert sim.world is not None
            goals = [
                ((x + math.cos(yaw), y + math.sin(yaw), grid.floor_z), (1.0, 0.3 * (k % 4), 0, 1))
                for k, ((x, y), yaw) in enumerate(zip(points, yaws, strict=True))
                if k % 3 == 0
            ]
            sim.world.place_goals(goals, 0.15, 0.8)
            images[renderer] = []
            for (x, y), yaw in zip(points, yaws, strict=True):
                sim.set_agent(np.array([x, y]), float(yaw))
                images[renderer].append(sim.render(segmentation=True))
        finally:
            sim.close()
    return images


def _assert_same_pictures(measured: Agreement) -> None:
    assert measured.depth >= MIN_DEPTH_AGREEMENT, measured
    assert measured.segmentation >= MIN_SEGMENTATION_AGREEMENT, measured
    assert measured.rgb_mean <= MAX_RGB_MEAN_DIFFERENCE, measured
    assert measured.rgb_p99 <= MAX_RGB_P99_DIFFERENCE, measured


@pytest.mark.parametrize("size", [36, 128])
def test_gl_draws_a_house_as_tiny_does(gl: None, size: int) -> None:
    images = _renders("house-00061", size, poses=12)
    _assert_same_pictures(agreement(images["tiny"], images["gl"]))
    # the goals were seen, in both
    assert any(
        image.segmentation is not None and (image.segmentation > 500).any()
        for image in images["gl"]
    )


def test_gl_draws_a_mesh_scan_as_tiny_does(gl: None, tmp_path: Path) -> None:
    scan = export_obj(layout_for("house-00066"), tmp_path / "house.obj")
    images = _renders(str(scan), 64, poses=8)
    _assert_same_pictures(agreement(images["tiny"], images["gl"]))


def _goal_set_view(goal_set: str, renderer: str) -> dict[str, np.ndarray]:
    goals = tuple(Goal(c, (0.7 + 0.6 * c, 3.4, 0.0)) for c in range(8))
    episode = Episode("s", "room-6x4", (3.0, 0.6, 0.0), math.pi / 2, goals)
    config = EnvConfig(
        task=TaskConfig(num_goals=8, goal_set=goal_set),
        camera=CameraConfig(width=128, height=128, renderer=renderer, hfov_deg=120.0),
        sensors=("rgb", "depth", "goal_mask"),
    )
    env = MultiONEnv(config, episodes=[episode])
    try:
        obs, _ = env.reset(seed=0)
        assert env.sim.renderer == renderer
        return obs
    finally:
        env.close()


@pytest.mark.parametrize("goal_set", ["colours", "shapes", "objects", "unseen_test"])
def test_gl_draws_every_goal_set_as_tiny_does(gl: None, goal_set: str) -> None:
    tiny, drawn = _goal_set_view(goal_set, "tiny"), _goal_set_view(goal_set, "gl")
    depth_m = np.abs(tiny["depth"] - drawn["depth"]) * 10.0  # normalised over [0, 10] m
    assert (depth_m <= DEPTH_TOLERANCE_M).mean() >= MIN_DEPTH_AGREEMENT
    assert (tiny["goal_mask"] == drawn["goal_mask"]).mean() >= MIN_SEGMENTATION_AGREEMENT
    for category in range(1, 9):  # every goal shows, in both
        assert (drawn["goal_mask"] == category).sum() > 2, category
    rgb = np.abs(tiny["rgb"].astype(int) - drawn["rgb"].astype(int))
    assert rgb.mean() <= MAX_RGB_MEAN_DIFFERENCE and np.percentile(rgb, 99) <= 2


def test_every_body_pybullet_draws_is_in_the_gl_scene(gl: None) -> None:
    sim = Simulator(camera=CameraConfig(width=16, height=16, renderer="gl"))
    try:
        grid = sim.load_scene("house-00061")
        world = sim.world
        assert world is not None and world.gl is not None
        floor = grid.floor_z
        world.place_object_goals([((1.0 + k, 2.0, floor), k, 0.3 * k) for k in range(8)])
        world.place_shape_goals([((1.0, 3.0, floor), 4)], 0.4, 0.6, (1.0, 0.0, 0.0, 1.0))
        world.place_goals([((2.0, 3.0, floor), (0.0, 1.0, 0.0, 1.0))], 0.15, 0.8)
        sim.set_agent(np.array([2.0, 1.0]), 0.0)
        sim.render(segmentation=True)  # bodies created since the scene was built join here
        client = world.client
        drawn_by_pybullet = {
            body
            for body in (
                p.getBodyUniqueId(i, physicsClientId=client)
                for i in range(p.getNumBodies(physicsClientId=client))
            )
            if any(s[7][3] > 0 for s in p.getVisualShapeData(body, physicsClientId=client))
        }
        assert len(drawn_by_pybullet) > 500  # the house's boxes and the goals
        assert drawn_by_pybullet - world.gl.drawn_bodies == set()
    finally:
        sim.close()


def test_gl_images_are_deterministic(gl: None) -> None:
    first, second = _renders("house-00061", 64, 4), _renders("house-00061", 64, 4)
    for a, b in zip(first["gl"], second["gl"], strict=True):
        assert np.array_equal(a.rgb, b.rgb) and np.array_equal(a.depth, b.depth)
        assert a.segmentation is not None and b.segmentation is not None
        assert np.array_equal(a.segmentation, b.segmentation)


def _resident_mib() -> float:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


@pytest.mark.slow
def test_opening_and_closing_100_scenes_leaks_no_gl_memory(gl: None) -> None:
    camera = CameraConfig(width=64, height=64, renderer="gl")

    def open_render_close() -> None:
        sim = Simulator(camera=camera)
        sim.load_scene("room-6x4")
        assert sim.world is not None
        sim.world.place_goals([((3.0, 2.0, 0.0), (1.0, 0.0, 0.0, 1.0))], 0.15, 0.8)
        sim.set_agent(np.array([3.0, 0.6]), math.pi / 2)
        sim.render(segmentation=True)
        sim.close()

    for _ in range(10):  # the context, shader caches and allocator pools settle first
        open_render_close()
    before = _resident_mib()
    for _ in range(100):
        open_render_close()
    grown = _resident_mib() - before
    assert grown < 20, f"resident memory grew by {grown:.1f} MiB over 100 scenes"


NO_EGL_SCRIPT = """
from multion.sim.camera import RendererUnavailableError, resolve_renderer
from multion.sim.simulator import Simulator
from multion.config.sim import CameraConfig
print("auto ->", resolve_renderer("auto"))
sim = Simulator(camera=CameraConfig(width=8, height=8, renderer="auto"))
sim.load_scene("room-6x4")
print("used ->", sim.renderer)
try:
    Simulator(camera=CameraConfig(width=8, height=8, renderer="gl")).load_scene("room-6x4")
except RendererUnavailableError as error:
    print("gl ->", error)
"""


def test_without_egl_auto_falls_back_to_tiny_and_gl_names_the_packages() -> None:
    # libglvnd finds no EGL vendor: what a machine without Mesa's EGL or a GPU driver sees
    env = {**os.environ, "__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent/egl-vendor.json"}
    result = subprocess.run(
        [sys.executable, "-c", NO_EGL_SCRIPT], capture_output=True, text=True, env=env, timeout=120
    )
    assert result.returncode == 0, result.stderr[-2000:]
    lines = result.stdout.splitlines()
    assert "auto -> tiny" in lines and "used -> tiny" in lines
    reason = next(line for line in lines if line.startswith("gl ->"))
    assert "libegl-mesa0" in reason and "camera.renderer 'tiny'" in reason


def test_a_gl_camera_without_a_gl_scene_is_refused() -> None:
    from multion.sim.camera import Camera

    with pytest.raises(ValueError, match="GL scene"):
        Camera(CameraConfig(renderer="gl"), client=0, renderer="gl")
    assert issubclass(RendererUnavailableError, ValueError)
