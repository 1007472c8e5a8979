"""Every house the generator can build, at every room count a challenge may ask for, is sound
(issue 33): a property test over house numbers and room counts, on the geometry and the grid.

Hypothesis keeps it bounded: few examples, no deadline (a grid takes 0.5–5 s), one simulator.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from multion.scenes.layout import Box, SceneLayout
from multion.scenes.registry import MAX_SIZED_ROOMS, layout_for, scene_ids, sized_house_id
from multion.scenes.room import make_room
from multion.sim.house_check import geometry_problems, grid_problems, points_outside_rooms
from multion.sim.navgrid import build_navgrid
from multion.sim.simulator import Simulator
from multion.sim.world import PyBulletWorld

NUMBERS = st.integers(min_value=0, max_value=10**12)
ROOMS = st.integers(min_value=1, max_value=MAX_SIZED_ROOMS)
BOUNDED = settings(
    max_examples=6, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)  # fmt: skip


@pytest.fixture(scope="module")
def simulator():
    sim = Simulator()
    yield sim
    sim.close()


@settings(BOUNDED, max_examples=25)
@given(number=NUMBERS, rooms=ROOMS)
@example(number=14, rooms=1)  # one room in a plate three times its size (issue 33)
@example(number=4, rooms=1)
@example(number=1, rooms=2)
def test_house_geometry_is_sound_at_every_room_count(number, rooms):
    layout = layout_for(sized_house_id(number, rooms))
    assert len(layout.rooms) == rooms
    assert geometry_problems(layout) == []


@BOUNDED
@given(number=NUMBERS, rooms=ROOMS)
@example(number=14, rooms=1)  # its grid stood on the roof: 218 % of the footprint navigable
@example(number=5, rooms=1)
def test_house_grid_is_sound_at_every_room_count(simulator, monkeypatch, number, rooms):
    monkeypatch.setenv("MULTION_NAVGRID_CACHE", "off")  # judge the grid built now, not a cached one
    scene = sized_house_id(number, rooms)
    layout, grid = layout_for(scene), simulator.load_scene(scene)
    assert grid_problems(layout, grid) == []
    rows, cols = np.nonzero(grid.navigable)
    assert not points_outside_rooms(layout, grid.cell_to_world(rows, cols)).any()


def test_default_houses_are_sound_geometrically():
    for split in ("train", "val", "test"):
        for scene in scene_ids(split)[:4]:
            assert geometry_problems(layout_for(scene)) == [], scene


def test_the_checks_catch_a_roof_taken_for_the_floor():
    # a room under a roof four times its size: the ray search finds the roof's top as the floor
    room = make_room(3.0, 3.0, scene_id="roofed")
    roof = Box((3.0, 3.0, 2.625), (6.0, 6.0, 0.025), (1.0, 1.0, 1.0, 1.0), "ceiling")
    layout = SceneLayout(
        "roofed", (*[b for b in room.boxes if b.kind != "ceiling"], roof), room.rooms
    )
    assert any("roof" in p for p in geometry_problems(layout))
    world = PyBulletWorld.from_layout(layout, "tiny")
    try:
        grid = build_navgrid(world)
    finally:
        world.close()
    problems = grid_problems(layout, grid)
    assert any("stands at z" in p for p in problems)
    assert any("exceeds the footprint" in p for p in problems)


def test_sized_houses_have_their_own_grid_cache_revision():
    # sized houses changed without GENERATOR_VERSION (the default houses did not): their cached
    # grids must be rebuilt, the default houses' kept
    from multion.config.sim import NavGridConfig
    from multion.sim.grid_cache import cache_key

    assert "sized_revision" not in cache_key("house-00061", NavGridConfig())
    assert '"sized_revision": 1' in cache_key("house-00014-r1", NavGridConfig())
