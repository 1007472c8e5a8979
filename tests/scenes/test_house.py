"""Procedural houses: determinism, floor plans, doors, walls, furniture, colours, navigability.

The geometric invariants are checked on many seeds from the layout alone (fast); the ones that
need the simulator's navigable grid on a few houses.
"""

from __future__ import annotations

import functools
from collections import deque

import numpy as np
import pytest
from scipy import ndimage

from multion.config.scenes import HouseConfig
from multion.scenes.house import generate_house
from multion.scenes.layout import Box, SceneLayout
from multion.scenes.palette import GOAL_MARGIN
from multion.scenes.textures import PATTERNS, texture_image

SEEDS = range(30)
CFG = HouseConfig()
T = CFG.wall_thickness
GOAL_COLOURS = np.array(
    [(1, 0, 0), (0, 1, 0), (0, 0, 1), (0, 1, 1), (1, 0, 1), (1, 1, 0), (0, 0, 0), (1, 1, 1)]
)


@functools.cache
def house(seed: int) -> SceneLayout:
    return generate_house(seed)


def boxes_of(layout: SceneLayout, kind: str) -> list[Box]:
    return [b for b in layout.boxes if b.kind == kind]


def covers(box: Box, x: float, y: float, z: float | None = None) -> bool:
    (x0, y0, z0), (x1, y1, z1) = box.min_corner, box.max_corner
    inside = x0 <= x <= x1 and y0 <= y <= y1
    return inside and (z is None or z0 <= z <= z1)


def overlap_area(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    return max(w, 0.0) * max(h, 0.0)


def xy_rect(box: Box) -> tuple[float, float, float, float]:
    (x0, y0, _), (x1, y1, _) = box.min_corner, box.max_corner
    return (x0, y0, x1, y1)


def footprint(layout: SceneLayout) -> tuple[float, float]:
    return float(layout.metadata["footprint_width"]), float(layout.metadata["footprint_depth"])


def corridors(layout: SceneLayout) -> list[int]:
    return [i for i, r in enumerate(layout.rooms) if r.room_type == "hallway"]


def test_same_seed_gives_identical_layout_and_different_seeds_differ():
    a, b = generate_house(7), generate_house(7)
    assert a == b  # dataclass equality compares every float exactly
    assert a.scene_id == "house-00007"
    assert generate_house(8) != a
    assert generate_house(7, scene_id="custom").scene_id == "custom"


def test_room_counts_footprints_and_shapes_are_matterport_like():
    counts = [len(house(s).rooms) for s in SEEDS]
    assert all(CFG.min_rooms <= c <= CFG.max_rooms for c in counts)
    assert min(counts) <= CFG.min_rooms + 1 and max(counts) >= CFG.max_rooms - 1
    areas = [float(house(s).metadata["footprint_area"]) for s in SEEDS]
    assert 100 <= min(areas) and max(areas) <= 500 and np.mean(areas) >= 180
    # corridors, non-rectangular footprints (corner cuts) and wide openings all occur
    assert sum(int(house(s).metadata["corridor_count"]) > 0 for s in SEEDS) >= 10
    cut = [
        s
        for s in SEEDS
        if float(house(s).metadata["footprint_area"]) < np.prod(footprint(house(s))) - 1
    ]
    assert len(cut) >= 10
    assert any(d.width > 1.5 for s in SEEDS for d in house(s).doors)
    for s in SEEDS:
        assert house(s).metadata["room_count"] == str(len(house(s).rooms))


def test_config_controls_room_count_and_furniture():
    layout = generate_house(
        3, HouseConfig(min_rooms=5, max_rooms=5, furniture_density=0.0, clutter=0)
    )
    assert len(layout.rooms) == 5
    assert boxes_of(layout, "furniture") == []
    with pytest.raises(ValueError):
        HouseConfig(min_rooms=4, max_rooms=3)
    with pytest.raises(ValueError, match="clutter"):
        HouseConfig(clutter=-1)


def test_one_room_houses_too_small_for_corner_cuts_are_still_built():
    # House 1000063352 with one room draws corner cuts its small footprint cannot take; it
    # raised "could not lay out a floor plan" before cuts became optional (a leaderboard with
    # hidden.rooms = [1, 1] drew such houses from its secret).
    one_room = HouseConfig(min_rooms=1, max_rooms=1)
    for seed in (1_000_063_352, 1_000_166_299, 1_000_197_975):
        layout = generate_house(seed, one_room)
        assert len(layout.rooms) == 1
        assert layout.doors == ()


def test_rooms_have_minimum_size_corridors_their_width_and_no_overlap():
    for s in SEEDS:
        rooms = house(s).rooms
        for i, room in enumerate(rooms):
            x0, y0, x1, y1 = room.rect
            narrow = min(x1 - x0, y1 - y0)
            if room.room_type == "hallway":
                assert narrow >= CFG.plan.corridor_width[0] - 1e-9
            else:
                assert narrow >= CFG.min_room_side - 1e-9
            for other in rooms[i + 1 :]:
                assert overlap_area(room.rect, other.rect) == 0.0


def test_every_room_reachable_through_doors_and_dead_ends_exist():
    dead_ends = 0
    for s in SEEDS:
        layout = house(s)
        n = len(layout.rooms)
        links: dict[int, set[int]] = {i: set() for i in range(n)}
        for door in layout.doors:
            i, j = door.rooms
            links[i].add(j)
            links[j].add(i)
        seen, todo = {0}, deque([0])
        while todo:
            for j in links[todo.popleft()] - seen:
                seen.add(j)
                todo.append(j)
        assert seen == set(range(n)), f"seed {s}: rooms {set(range(n)) - seen} unreachable"
        dead_ends += sum(len(v) == 1 for v in links.values())
    assert dead_ends >= 2 * len(SEEDS)


def test_doors_are_real_gaps_between_their_two_rooms():
    for s in range(12):
        layout = house(s)
        walls = boxes_of(layout, "wall")
        for door in layout.doors:
            cx, cy = door.center
            assert door.width >= 0.9
            a, b = (layout.rooms[k].rect for k in door.rooms)
            if door.axis == "y":
                edges = sorted([a[2], b[0]]) if a[2] < b[0] else sorted([b[2], a[0]])
                assert edges == pytest.approx([cx - T / 2, cx + T / 2])
            else:
                edges = sorted([a[3], b[1]]) if a[3] < b[1] else sorted([b[3], a[1]])
                assert edges == pytest.approx([cy - T / 2, cy + T / 2])
            along = np.linspace(-door.width / 2 + 0.01, door.width / 2 - 0.01, 9)
            for u in along:  # no wall anywhere across the opening
                x, y = (cx + u, cy) if door.axis == "x" else (cx, cy + u)
                for v in (-T / 2 + 0.005, 0.0, T / 2 - 0.005):
                    px, py = (x, y + v) if door.axis == "x" else (x + v, y)
                    assert not any(covers(w, px, py, 1.0) for w in walls)


def test_walls_have_the_configured_thickness_and_height():
    for s in range(10):
        layout = house(s)
        for w in boxes_of(layout, "wall"):
            assert min(w.half_extents[:2]) * 2 in (pytest.approx(T), pytest.approx(T / 2))
            assert w.min_corner[2] == pytest.approx(0.0)
            assert w.max_corner[2] == pytest.approx(layout.wall_height)


def test_floor_slabs_cover_every_room_and_the_ceiling_is_on_top():
    for s in range(10):
        layout = house(s)
        floors = boxes_of(layout, "floor")
        assert len(floors) == len(layout.rooms)
        for room in layout.rooms:
            x0, y0, x1, y1 = room.rect
            for x in np.linspace(x0 - T / 2 + 0.01, x1 + T / 2 - 0.01, 12):
                for y in np.linspace(y0 - T / 2 + 0.01, y1 + T / 2 - 0.01, 12):
                    assert any(covers(f, x, y) for f in floors), (
                        f"seed {s}: hole at {x:.2f},{y:.2f}"
                    )
        (ceiling,) = boxes_of(layout, "ceiling")
        assert ceiling.min_corner[2] == pytest.approx(layout.wall_height)


def test_furniture_stays_inside_rooms_and_out_of_walls_and_door_zones():
    for s in range(20):
        layout = house(s)
        furniture = boxes_of(layout, "furniture")
        assert furniture, f"seed {s} has no furniture"
        walls = [xy_rect(w) for w in boxes_of(layout, "wall")]
        zones = []
        for door in layout.doors:  # 1 m in front of the opening on both sides, 0.15 beside it
            cx, cy = door.center
            half, reach = door.width / 2 + 0.15, T / 2 + 1.0
            if door.axis == "x":
                zones.append((cx - half, cy - reach, cx + half, cy + reach))
            else:
                zones.append((cx - reach, cy - half, cx + reach, cy + half))
        for box in furniture:
            r = xy_rect(box)
            assert any(
                q[0] - 1e-9 <= r[0] and q[1] - 1e-9 <= r[1] and r[2] <= q[2] + 1e-9
                and r[3] <= q[3] + 1e-9
                for q in (room.rect for room in layout.rooms)
            ), f"seed {s}: {box} is not inside a room"  # fmt: skip
            assert all(overlap_area(r, w) < 1e-9 for w in walls)
            assert all(overlap_area(r, z) < 1e-9 for z in zones), f"seed {s}: {box} blocks a door"
            assert 0.0 <= box.min_corner[2] and box.max_corner[2] < layout.wall_height


def test_clutter_stands_in_the_middle_of_rooms():
    middle = 0
    for s in range(10):
        layout = house(s)
        for box in boxes_of(layout, "furniture"):
            x0, y0, x1, y1 = xy_rect(box)
            for room in layout.rooms:
                rx0, ry0, rx1, ry1 = room.rect
                if rx0 <= x0 and x1 <= rx1 and ry0 <= y0 and y1 <= ry1:
                    gap = min(x0 - rx0, rx1 - x1, y0 - ry0, ry1 - y1)
                    middle += gap > 0.6 and box.min_corner[2] < 0.1  # free-standing, off the walls
    assert middle >= 10 * 10


def test_colours_walls_muted_some_furniture_close_to_goals_but_never_equal():
    near = 0
    for s in range(20):
        for box in house(s).boxes:
            rgb = np.array(box.rgba[:3])
            gap = np.abs(rgb - GOAL_COLOURS).max(axis=1).min()
            assert gap >= GOAL_MARGIN - 1e-6, f"{box.kind} colour {rgb} is a goal colour"
            if box.kind != "furniture":
                assert gap > 0.2 and rgb.max() - rgb.min() <= 0.5 * rgb.max() + 1e-3
            near += gap < 0.25
    assert near >= 20 * 5  # red sofas, blue rugs, white fridges …


def test_floors_and_walls_are_textured_and_textures_are_deterministic():
    layout = house(0)
    assert all(b.texture in PATTERNS for b in boxes_of(layout, "floor"))
    assert all(b.texture in PATTERNS for b in boxes_of(layout, "wall"))
    for pattern in PATTERNS:
        a, b = texture_image(pattern, 3.0, 2.6), texture_image(pattern, 3.0, 2.6)
        assert a.dtype == np.uint8 and a.shape[2] == 3 and np.array_equal(a, b)
        assert a.std() > 1.0  # a pattern, not a flat colour
    lights = {house(s).metadata["lighting"] for s in range(10)}
    assert len(lights) == 10  # lighting varies between houses


def free_space(layout: SceneLayout, radius: float = 0.1, cell: float = 0.05):
    """Free floor cells for a cylinder agent of ``radius``: over a floor slab, and farther than
    ``radius`` from every wall or furniture part below 1.5 m (Euclidean)."""
    width, depth = footprint(layout)
    xs = np.arange(cell / 2, width, cell)
    ys = np.arange(cell / 2, depth, cell)
    gx, gy = np.meshgrid(xs, ys)
    floor = np.zeros(gx.shape, bool)
    for box in boxes_of(layout, "floor"):
        x0, y0, x1, y1 = xy_rect(box)
        floor |= (gx >= x0) & (gx <= x1) & (gy >= y0) & (gy <= y1)
    free = floor.copy()
    for box in layout.boxes:
        if (
            box.kind in ("wall", "furniture")
            and box.min_corner[2] < 1.5
            and box.max_corner[2] > 0.05
        ):
            x0, y0, x1, y1 = xy_rect(box)
            cols = slice(*np.searchsorted(xs, [x0 - radius - cell, x1 + radius + cell]))
            rows = slice(*np.searchsorted(ys, [y0 - radius - cell, y1 + radius + cell]))
            dx = np.maximum(np.maximum(x0 - gx[rows, cols], gx[rows, cols] - x1), 0.0)
            dy = np.maximum(np.maximum(y0 - gy[rows, cols], gy[rows, cols] - y1), 0.0)
            free[rows, cols] &= np.hypot(dx, dy) > radius
    # the free floor's edge (outer walls of cut corners are half thick) is not walkable
    free &= ndimage.binary_erosion(floor, iterations=int(np.ceil(radius / cell)))
    return free, floor


@pytest.mark.parametrize("radius", [0.1, 0.125])
def test_whole_house_is_one_navigable_piece_about_half_of_the_footprint(radius):
    fractions = []
    for seed in range(0, 30, 2):
        layout = house(seed)
        free, floor = free_space(layout, radius)
        labels, pieces = ndimage.label(free)
        sizes = np.bincount(labels.ravel())[1:]
        # one piece; raster crumbs in corners between furniture and walls aside (at most
        # 20 cells, 0.05 m², each: the navigable grid keeps only its largest region anyway, so
        # no start or goal can be there)
        assert sorted(sizes)[-2:-1] <= [20] and sizes.max() >= 0.995 * free.sum(), (
            f"house {seed} free space falls into pieces of {sorted(sizes)} cells"
        )
        fractions.append(free.sum() / floor.sum())
    if radius == 0.1:
        assert 0.40 <= np.mean(fractions) <= 0.65, fractions
