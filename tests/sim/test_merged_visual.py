"""EGL draws a house as one merged mesh (``multion.sim.merged_visual``): a handful of draws
instead of one per box, the same images as the per-box bodies, and the same collision world
(ray casts, navigable grid); TinyRenderer keeps a body per box."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest

from multion.config.sim import CameraConfig, NavGridConfig
from multion.scenes.layout import Box
from multion.scenes.registry import layout_for
from multion.scenes.textures import texture_image
from multion.sim.bullet import pybullet as p
from multion.sim.camera import EGL_LIGHT_POSITION, EGL_PLUGIN_LIGHT, Camera
from multion.sim.merged_visual import build_atlas, merged_visual
from multion.sim.navgrid import build_navgrid
from multion.sim.simulator import Simulator
from multion.sim.world import PyBulletWorld

HOUSE = "house-00061"
MAX_EGL_SCENE_DRAWS = 3


@pytest.fixture(scope="module")
def poses() -> list[tuple[float, float, float]]:
    """Ten navigable poses of the house, random headings."""
    grid = Simulator().load_scene(HOUSE)
    rng = np.random.default_rng(3)
    rows, cols = np.nonzero(grid.navigable)
    picks = rng.choice(len(rows), 10, replace=False)
    points = grid.cell_to_world(rows[picks], cols[picks])
    return [(float(x), float(y), float(rng.uniform(-math.pi, math.pi))) for x, y in points]


def _images(world: PyBulletWorld, poses, size: int = 96) -> list:
    camera = Camera(
        CameraConfig(width=size, height=size, renderer=world.renderer),
        world.client,
        world.renderer,
        world.lighting,
    )
    try:
        return [camera.render(x, y, yaw, 0.0, segmentation=True) for x, y, yaw in poses]
    finally:
        world.close()


def test_tinyrenderer_draws_a_body_per_box() -> None:
    layout = layout_for(HOUSE)
    world = PyBulletWorld.from_layout(layout, "tiny")
    try:
        assert world.visual_bodies == []
        assert len(world.scene_bodies) == len(layout.boxes) > 400
        assert world.scene_draws() == len(layout.boxes)
    finally:
        world.close()


TINY_POSES = [
    (4.0, 6.0, 0.0),
    (8.5, 3.0, 1.2),
    (12.0, 8.0, -2.0),
    (16.0, 9.5, 2.8),
    (6.0, 10.0, -0.7),
]
TINY_DIGEST = "9222b0db33526365c4cb5d1d676d81d6a6b5dbc9da18b2919cab70bac0be03d7"
"""SHA-256 of TinyRenderer's RGB and depth at ``TINY_POSES``, 64², computed with the code before
the merge (commit 4363208): other work (recorded explorer actions, baseline evaluations)
depends on TinyRenderer's exact pixels."""


def test_tinyrenderer_images_are_bit_identical_to_before_the_merge() -> None:
    world = PyBulletWorld.from_layout(layout_for(HOUSE), "tiny")
    # the depth range the digest was taken with (the default is [0, 10] m since issue 31)
    config = CameraConfig(width=64, height=64, min_depth=0.5, max_depth=5.0)
    camera = Camera(config, world.client, world.renderer, world.lighting)
    digest = hashlib.sha256()
    try:
        for x, y, yaw in TINY_POSES:
            image = camera.render(x, y, yaw, 0.0)
            digest.update(image.rgb.tobytes())
            digest.update(image.depth.tobytes())
    finally:
        world.close()
    assert digest.hexdigest() == TINY_DIGEST


def test_egl_draws_a_house_in_a_few_draws(egl: None) -> None:
    layout = layout_for(HOUSE)
    merged = PyBulletWorld.from_layout(layout, "egl")
    per_box = PyBulletWorld.from_layout(layout, "egl", merge=False)
    try:
        assert per_box.scene_draws() == len(layout.boxes)  # before the merge
        assert 1 <= merged.scene_draws() <= MAX_EGL_SCENE_DRAWS
        # every box keeps its collision body; the plugin sees none of them
        assert len(merged.scene_bodies) == len(layout.boxes)
        for body in merged.scene_bodies:
            assert p.getVisualShapeData(body, physicsClientId=merged.client) == ()
    finally:
        merged.close()
        per_box.close()


def test_merged_mesh_looks_like_the_per_box_bodies(egl: None, poses) -> None:
    layout = layout_for(HOUSE)
    merged = _images(PyBulletWorld.from_layout(layout, "egl"), poses)
    per_box = _images(PyBulletWorld.from_layout(layout, "egl", merge=False), poses)
    for a, b in zip(per_box, merged, strict=True):
        # the same boxes: depth agrees but for float rounding of the merged mesh's vertices
        # (world coordinates instead of box-local ones), which can flip coincident faces
        assert (np.abs(a.depth - b.depth) > 0.002).mean() < 0.01
        # the same surface in every pixel: segmentation differs only in the ids
        assert ((a.segmentation >= 0) == (b.segmentation >= 0)).all()
        # colours: atlas filtering and the triangulation of faces differ slightly
        difference = np.abs(a.rgb.astype(float) - b.rgb.astype(float))
        assert difference.mean() < 6  # atlas or texture coordinates mixed up: 30 to 100
        assert (difference.max(axis=2) > 24).mean() < 0.05


def _light_pair(scene: str, poses) -> tuple[list, list]:
    """Images of ``poses`` with the plugin's own light and with the cameras' far light."""
    pairs = []
    for light in (EGL_PLUGIN_LIGHT, EGL_LIGHT_POSITION):
        world = PyBulletWorld.from_layout(layout_for(scene), "egl")
        camera = Camera(CameraConfig(width=96, height=96, renderer="egl"), world.client, "egl")
        camera.egl_light_position = light
        try:
            pairs.append([camera.render(x, y, yaw, 0.0) for x, y, yaw in poses])
        finally:
            world.close()
    return pairs[0], pairs[1]


def test_the_far_light_only_removes_the_plugins_shadows(egl: None, poses) -> None:
    """Cameras move the plugin's light away (``EGL_LIGHT_POSITION``) so that its shadow map,
    rendered every frame, sees nothing: the light's direction is unchanged (an unshadowed
    view renders the same pixels) and the only change is that shadowed pixels get lighter."""
    room = [(1.0, 2.0, 0.0), (3.0, 1.0, 2.0), (5.0, 3.0, -2.5), (2.0, 3.5, 4.0)]
    for scene, views in (("room-6x4", room), (HOUSE, poses)):
        plugin, far = _light_pair(scene, views)
        if scene == "room-6x4":
            assert np.array_equal(plugin[0].rgb, far[0].rgb)  # facing the unshadowed wall
        for a, b in zip(plugin, far, strict=True):
            assert np.array_equal(a.depth, b.depth)
            lighter = b.rgb.astype(int) - a.rgb.astype(int)
            assert (lighter < -5).mean() < 0.01  # a shadow's edge pixels may flip
            assert lighter.mean() > -0.05


def test_collision_world_and_navigable_grid_are_unchanged(egl: None) -> None:
    """Rays hit the same boxes whichever renderer draws the scene: the merged visual body has
    no collision shape, so floor detection and the grid (a coarse one, for speed) are equal."""
    layout = layout_for(HOUSE)
    config = NavGridConfig(cell_size=0.2)
    grids, bounds = [], []
    for renderer in ("tiny", "egl"):
        world = PyBulletWorld.from_layout(layout, renderer)
        try:
            assert world.renderer == renderer
            bounds.append(world.bounds())
            grids.append(build_navgrid(world, config))
        finally:
            world.close()
    np.testing.assert_array_equal(bounds[0], bounds[1])
    tiny, egl_grid = grids
    assert (tiny.floor_z, tiny.origin) == (egl_grid.floor_z, egl_grid.origin)
    for field in ("inside", "free", "navigable", "view_blocked"):
        np.testing.assert_array_equal(getattr(tiny, field), getattr(egl_grid, field), field)


def test_the_atlas_holds_each_box_colour_and_texture() -> None:
    plain = Box((0, 0, 0.5), (0.5, 0.5, 0.5), (0.2, 0.4, 0.6, 1.0), "furniture")
    wall = Box((0, 2, 1.3), (2.0, 0.05, 1.3), (0.7, 0.6, 0.5, 1.0), "wall", "stripes")
    atlas, regions = build_atlas((plain, wall))
    height, width = atlas.shape[:2]

    def pixels(region) -> np.ndarray:  # texture v is up, image rows go down
        u0, v0, u1, v1, _ = region
        return atlas[
            round((1 - v1) * height) : round((1 - v0) * height),
            round(u0 * width) : round(u1 * width),
        ]

    assert regions[0][4] == 1.0 and regions[1][4] == 0.0  # plain, textured
    assert (pixels(regions[0]) == (51, 102, 153)).all()
    stripes = texture_image("stripes", 4.0, 2.6).astype(float)
    colour = np.round(255 * np.array([0.7, 0.6, 0.5])) / 255  # colours are 8-bit in the atlas
    expected = np.round(stripes * colour).astype(np.uint8)
    assert np.array_equal(pixels(regions[1]), expected)


def test_merged_files_are_cached_by_content(tmp_path) -> None:
    boxes = layout_for("room-6x4").boxes
    first = merged_visual(boxes, tmp_path)
    again = merged_visual(boxes, tmp_path)
    other = merged_visual(boxes[:-1], tmp_path)
    assert (first.mesh, first.atlas) == (again.mesh, again.atlas)
    assert other.mesh != first.mesh and first.mesh.is_file() and first.atlas.is_file()
    assert first.mesh.read_text().count("\nf ") == 12 * len(boxes)
