"""Procedural houses: determinism, room counts, doors, walls, furniture, colours, navigability."""

from __future__ import annotations

import functools
from collections import deque

import numpy as np
import pytest
from scipy import ndimage

from multion.scenes.house import HouseConfig, generate_house
from multion.scenes.layout import Box, SceneLayout

SEEDS = range(50)
T = HouseConfig().wall_thickness
GOAL_COLOURS = [
    (1, 0, 0),
    (0, 1, 0),
    (0, 0, 1),
    (0, 1, 1),
    (1, 0, 1),
    (1, 1, 0),
    (0, 0, 0),
    (1, 1, 1),
]


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
    """Overlap area of two rectangles (x0, y0, x1, y1)."""
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    return max(w, 0.0) * max(h, 0.0)


def xy_rect(box: Box) -> tuple[float, float, float, float]:
    (x0, y0, _), (x1, y1, _) = box.min_corner, box.max_corner
    return (x0, y0, x1, y1)


def inside(rect: tuple[float, ...], x: float, y: float) -> bool:
    return rect[0] < x < rect[2] and rect[1] < y < rect[3]


def footprint(layout: SceneLayout) -> tuple[float, float]:
    return float(layout.metadata["footprint_width"]), float(layout.metadata["footprint_depth"])


def test_same_seed_gives_identical_layout_and_different_seeds_differ():
    a, b = generate_house(7), generate_house(7)
    assert a == b  # dataclass equality compares every float exactly
    assert a.scene_id == "house-00007"
    assert generate_house(8) != a
    assert generate_house(7, scene_id="custom").scene_id == "custom"


def test_room_count_between_3_and_8_and_both_ends_occur():
    counts = [len(house(s).rooms) for s in SEEDS]
    assert all(3 <= c <= 8 for c in counts)
    assert {3, 8} <= set(counts)  # the whole range is used, not just the middle
    for s in SEEDS:
        assert house(s).metadata["room_count"] == str(len(house(s).rooms))


def test_config_controls_room_count_and_furniture():
    layout = generate_house(3, HouseConfig(min_rooms=5, max_rooms=5, furniture_density=0.0))
    assert len(layout.rooms) == 5
    assert boxes_of(layout, "furniture") == []
    with pytest.raises(ValueError):
        HouseConfig(min_rooms=4, max_rooms=3)


def test_rooms_have_minimum_size_and_do_not_overlap():
    for s in SEEDS:
        rooms = house(s).rooms
        for i, room in enumerate(rooms):
            x0, y0, x1, y1 = room.rect
            assert min(x1 - x0, y1 - y0) >= HouseConfig().min_room_side - 1e-9
            for other in rooms[i + 1 :]:
                assert overlap_area(room.rect, other.rect) == 0.0


def test_every_room_reachable_through_doors():
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
        assert len(layout.doors) >= n - 1


def test_doors_are_real_gaps_between_their_two_rooms():
    for s in range(15):
        layout = house(s)
        width, depth = footprint(layout)
        walls = boxes_of(layout, "wall")
        for door in layout.doors:
            cx, cy = door.center
            assert 0.9 <= door.width <= 1.1
            assert 0 < cx < width and 0 < cy < depth  # never in an outer wall
            # The two rooms sit on either side of the door, half a wall away.
            a, b = (layout.rooms[k].rect for k in door.rooms)
            if door.axis == "y":
                edges = sorted([a[2], b[0]]) if a[2] < b[0] else sorted([b[2], a[0]])
                assert edges == pytest.approx([cx - T / 2, cx + T / 2])
            else:
                edges = sorted([a[3], b[1]]) if a[3] < b[1] else sorted([b[3], a[1]])
                assert edges == pytest.approx([cy - T / 2, cy + T / 2])
            # No wall anywhere across the opening, at any height.
            along = np.linspace(-door.width / 2 + 0.01, door.width / 2 - 0.01, 9)
            for u in along:
                x, y = (cx + u, cy) if door.axis == "x" else (cx, cy + u)
                for v in (-T / 2 + 0.005, 0.0, T / 2 - 0.005):
                    px, py = (x, y + v) if door.axis == "x" else (x + v, y)
                    assert not any(covers(w, px, py, 1.0) for w in walls)


def test_walls_have_the_configured_thickness_height_and_close_every_room():
    for s in range(15):
        layout = house(s)
        walls = boxes_of(layout, "wall")
        width, depth = footprint(layout)
        checked = 0
        for w in walls:
            assert min(w.half_extents[:2]) * 2 in (pytest.approx(T), pytest.approx(T / 2))
            assert w.min_corner[2] == pytest.approx(0.0)
            assert w.max_corner[2] == pytest.approx(layout.wall_height)

        rects = np.array([xy_rect(w) for w in walls])

        def walled(x: float, y: float, rects=rects) -> bool:
            return bool(np.any((rects[:, :2] <= (x, y)).all(1) & (rects[:, 2:] >= (x, y)).all(1)))

        for room in layout.rooms:
            x0, y0, x1, y1 = room.rect
            # Walk along each side: solid wall from the room's edge for exactly one thickness.
            sides = [
                [((x, y0), (0, -1)) for x in np.linspace(x0 + 0.05, x1 - 0.05, 40)],
                [((x, y1), (0, 1)) for x in np.linspace(x0 + 0.05, x1 - 0.05, 40)],
                [((x0, y), (-1, 0)) for y in np.linspace(y0 + 0.05, y1 - 0.05, 40)],
                [((x1, y), (1, 0)) for y in np.linspace(y0 + 0.05, y1 - 0.05, 40)],
            ]
            for side in sides:
                gaps = 0
                for (px, py), (nx, ny) in side:
                    if not walled(px + 0.3 * T * nx, py + 0.3 * T * ny):
                        gaps += 1  # a door
                        continue
                    for d in (0.005, T / 2 - 0.005, T / 2 + 0.005, T - 0.005):
                        assert walled(px + d * nx, py + d * ny)
                    assert not walled(px - 0.005 * nx, py - 0.005 * ny)
                    # Just past the wall: outside the house or in the next room, never more wall
                    # (except at a T-junction, where the next room's own wall starts).
                    bx, by = px + (T + 0.005) * nx, py + (T + 0.005) * ny
                    outside = not (0 < bx < width and 0 < by < depth)
                    if outside or any(inside(r.rect, bx, by) for r in layout.rooms):
                        assert not walled(bx, by)
                        checked += 1
                assert gaps < len(side)  # doors never take a whole side
        assert checked > 100 * len(layout.rooms)  # T-junctions are the exception


def test_floor_slabs_cover_the_whole_footprint_and_ceiling_is_on_top():
    for s in range(10):
        layout = house(s)
        width, depth = footprint(layout)
        floors = boxes_of(layout, "floor")
        assert len(floors) == len(layout.rooms)
        for f in floors:
            assert f.max_corner[2] == pytest.approx(0.0)
        for x in np.linspace(-T / 2 + 0.01, width + T / 2 - 0.01, 60):
            for y in np.linspace(-T / 2 + 0.01, depth + T / 2 - 0.01, 60):
                assert any(covers(f, x, y) for f in floors), f"seed {s}: hole at {x:.2f},{y:.2f}"
        (ceiling,) = boxes_of(layout, "ceiling")
        assert ceiling.min_corner[2] == pytest.approx(layout.wall_height)
        assert xy_rect(ceiling) == pytest.approx((-T / 2, -T / 2, width + T / 2, depth + T / 2))


def test_footprint_size_is_sensible():
    long_sides = []
    for s in SEEDS:
        width, depth = footprint(house(s))
        long_sides.append(max(width, depth))
        assert house(s).metadata["footprint"] == f"{width:.2f}x{depth:.2f}"
    assert 5.0 <= min(long_sides) and max(long_sides) <= 21.0
    assert max(long_sides) >= 14.0  # big houses exist, for long geodesic distances


def test_furniture_stays_inside_rooms_and_out_of_walls_and_door_zones():
    for s in range(30):
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


def test_no_colour_is_close_to_a_goal_colour():
    for s in range(30):
        for box in house(s).boxes:
            rgb = np.array(box.rgba[:3])
            assert box.rgba[3] == 1.0
            for goal in GOAL_COLOURS:
                assert np.abs(rgb - goal).max() > 0.2, f"{box.kind} colour {rgb} is near {goal}"
            assert rgb.max() - rgb.min() <= 0.5 * rgb.max() + 1e-3  # saturation <= 0.5


def test_room_types_and_their_floor_colours():
    types = {room.room_type for s in SEEDS for room in house(s).rooms}
    assert {"living_room", "kitchen", "bedroom", "bathroom"} <= types
    layout = house(0)
    floors = [tuple(f.rgba) for f in boxes_of(layout, "floor")]
    assert len(set(floors)) > 1  # rooms are told apart by colour


def free_space(layout: SceneLayout, radius: float = 0.1, square: bool = False, cell: float = 0.05):
    """Navigable cells of the house for a cylinder agent of ``radius`` (1.5 m tall).

    Obstacles are grown by ``radius`` either exactly (Euclidean, like a distance-transform grid)
    or as squares (like a binary dilation with a square element, which blocks a bit more).
    """
    width, depth = footprint(layout)
    xs = np.arange(cell / 2, width, cell)
    ys = np.arange(cell / 2, depth, cell)
    free = np.ones((len(ys), len(xs)), bool)
    for box in layout.boxes:
        if box.kind in ("wall", "furniture") and box.min_corner[2] < 1.5:
            x0, y0, x1, y1 = xy_rect(box)
            # Only the cells near the box can be blocked by it.
            cols = slice(*np.searchsorted(xs, [x0 - radius - cell, x1 + radius + cell]))
            rows = slice(*np.searchsorted(ys, [y0 - radius - cell, y1 + radius + cell]))
            gx, gy = np.meshgrid(xs[cols], ys[rows])
            dx = np.maximum(np.maximum(x0 - gx, gx - x1), 0.0)
            dy = np.maximum(np.maximum(y0 - gy, gy - y1), 0.0)
            dist = np.maximum(dx, dy) if square else np.hypot(dx, dy)
            free[rows, cols] &= dist > radius
    return free, xs, ys


@pytest.mark.parametrize(("radius", "square"), [(0.1, False), (0.15, False), (0.1, True)])
def test_whole_house_is_one_navigable_piece(radius, square):
    for seed in range(0, 50, 2):
        layout = house(seed)
        free, xs, ys = free_space(layout, radius, square)
        _, pieces = ndimage.label(free)
        assert pieces == 1, f"house {seed} free space falls into {pieces} pieces"
        for room in layout.rooms:  # every room keeps most of its floor free
            x0, y0, x1, y1 = room.rect
            cells = np.ix_(
                (ys > y0 + radius) & (ys < y1 - radius), (xs > x0 + radius) & (xs < x1 - radius)
            )
            assert free[cells].mean() > 0.3


@pytest.mark.parametrize("seed", [0, 13, 33])
def test_big_houses_have_long_walks(seed):
    layout = house(seed)
    assert len(layout.rooms) == 8
    free, _, _ = free_space(layout)
    # Breadth-first step counts (4-neighbour) from one free cell.
    start = tuple(np.argwhere(free)[0])
    dist = np.full(free.shape, -1)
    dist[start] = 0
    todo = deque([start])
    while todo:
        i, j = todo.popleft()
        for a, b in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)):
            if 0 <= a < free.shape[0] and 0 <= b < free.shape[1] and free[a, b] and dist[a, b] < 0:
                dist[a, b] = dist[i, j] + 1
                todo.append((a, b))
    assert dist.max() * 0.05 >= 12.0
