"""Procedural multi-room houses: seeded, deterministic floor plans with doors and furniture.

How a house is made (all randomness comes from one ``numpy.random.default_rng(seed)``):

1. Pick a room count ``n`` and a rectangular footprint of about ``n`` rooms' worth of area.
2. Split the footprint recursively (binary space partition) into ``n`` cells, always cutting a
   cell across its longer side at 35–65 %, so no room gets narrower than ``min_room_side``.
   Cells are in integer steps of ``grid`` metres so that "do these cells touch?" is exact.
3. Cells sharing at least ``min_shared_wall`` of wall are neighbours. A random spanning tree of
   neighbours gets doors (so every room is reachable), plus a few extra doors that make loops.
4. Walls are centred on the cell boundaries and ``wall_thickness`` thick. Every room owns the
   half of each interior wall that faces it (so both sides get their room's colour) and the
   whole thickness of its outer walls; a door is a gap cut through both halves.
5. Each room gets a floor slab (covering the cell, so there is no hole under walls or doors), a
   type (living room, kitchen, …) with its colours, and furniture along its walls.

A room's ``rect`` is its free interior: the cell shrunk by half a wall on every side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from multion.scenes.furniture import furnish_room
from multion.scenes.layout import Box, Door, Room, SceneLayout
from multion.scenes.palette import CEILING, ROOM_COLOURS, muted, varied

Rect = tuple[float, float, float, float]  # (x0, y0, x1, y1)
Cell = tuple[int, int, int, int]  # a Rect in integer grid steps


@dataclass(frozen=True)
class HouseConfig:
    """Knobs of the house generator; the defaults give 3–8 room homes of about 30–200 m²."""

    min_rooms: int = 3
    max_rooms: int = 8
    room_area: tuple[float, float] = (10.0, 25.0)  # m² per room (wall centre to wall centre)
    footprint_aspect: tuple[float, float] = (1.2, 2.0)  # long side / short side of the house
    min_room_side: float = 2.5  # free interior, metres
    split_fraction: tuple[float, float] = (0.35, 0.65)  # where a cell is cut, along its long side
    min_shared_wall: float = 1.3  # two rooms are neighbours if they share this much wall
    wall_thickness: float = 0.15
    wall_height: float = 2.6
    floor_thickness: float = 0.05
    ceiling_thickness: float = 0.05
    door_width: tuple[float, float] = (0.9, 1.1)
    extra_door_probability: float = 0.3  # chance that a non-tree neighbour pair gets a door too
    door_clear_depth: float = 1.0  # no furniture this far in front of a door, on both sides
    door_clear_margin: float = 0.15  # … nor this far beside the door opening
    furniture_density: float = 1.0  # multiplies each furniture item's probability; 0 = empty
    colour_variation: float = 0.04  # per-channel shade variation per house
    grid: float = 0.05  # cut positions are multiples of this (metres)
    max_attempts: int = 200  # floor-plan retries before the footprint is enlarged further

    def __post_init__(self) -> None:
        if not 1 <= self.min_rooms <= self.max_rooms:
            raise ValueError(
                f"need 1 <= min_rooms <= max_rooms, got {self.min_rooms}, {self.max_rooms}"
            )
        if self.door_width[1] > self.min_shared_wall - self.wall_thickness:
            raise ValueError("door_width must fit in min_shared_wall minus the wall thickness")


def _units(metres: float, grid: float) -> int:
    return int(math.ceil(metres / grid - 1e-9))


def _split_cells(
    rng: np.random.Generator,
    width: int,
    depth: int,
    n: int,
    cfg: HouseConfig,
) -> list[Cell] | None:
    """Cut the footprint into ``n`` cells, or None when this random attempt gets stuck."""
    min_side = _units(cfg.min_room_side + cfg.wall_thickness, cfg.grid)
    cells: list[Cell] = [(0, 0, width, depth)]
    while len(cells) < n:
        splittable = [c for c in cells if max(c[2] - c[0], c[3] - c[1]) >= 2 * min_side]
        if not splittable:
            return None
        # Prefer big cells so rooms end up of similar size.
        weights = np.array([float((c[2] - c[0]) * (c[3] - c[1])) ** 2 for c in splittable])
        cell = splittable[int(rng.choice(len(splittable), p=weights / weights.sum()))]
        x0, y0, x1, y1 = cell
        along_x = (x1 - x0) >= (y1 - y0)
        length = (x1 - x0) if along_x else (y1 - y0)
        lo = max(math.ceil(cfg.split_fraction[0] * length), min_side)
        hi = min(math.floor(cfg.split_fraction[1] * length), length - min_side)
        if lo > hi:
            return None
        cut = int(rng.integers(lo, hi + 1))
        cells.remove(cell)
        if along_x:
            cells += [(x0, y0, x0 + cut, y1), (x0 + cut, y0, x1, y1)]
        else:
            cells += [(x0, y0, x1, y0 + cut), (x0, y0 + cut, x1, y1)]
    return sorted(cells, key=lambda c: (c[1], c[0]))


def _neighbours(cells: list[Cell], cfg: HouseConfig) -> list[tuple[int, int, str, int, int, int]]:
    """Pairs sharing enough wall: ``(i, j, axis, line, start, end)`` in grid steps.

    ``axis`` is the direction the shared wall runs in: "y" for a wall at ``x = line``.
    """
    pairs = []
    need = cfg.min_shared_wall / cfg.grid - 1e-9
    for i, a in enumerate(cells):
        for j, b in enumerate(cells):
            if a[2] == b[0]:  # b is east of a
                start, end = max(a[1], b[1]), min(a[3], b[3])
                if end - start >= need:
                    pairs.append((i, j, "y", a[2], start, end))
            if a[3] == b[1]:  # b is north of a
                start, end = max(a[0], b[0]), min(a[2], b[2])
                if end - start >= need:
                    pairs.append((i, j, "x", a[3], start, end))
    return pairs


def _choose_doors(
    rng: np.random.Generator,
    cells: list[Cell],
    cfg: HouseConfig,
) -> list[Door] | None:
    """A random spanning tree of doors plus extras; None if some room has no neighbour."""
    pairs = _neighbours(cells, cfg)
    parent = list(range(len(cells)))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    doors = []
    t, g, margin = cfg.wall_thickness, cfg.grid, 0.05
    for k in rng.permutation(len(pairs)):
        i, j, axis, line, start, end = pairs[int(k)]
        joins = root(i) != root(j)
        if not joins and rng.random() >= cfg.extra_door_probability:
            continue
        parent[root(i)] = root(j)
        s0, s1 = start * g + t / 2 + margin, end * g - t / 2 - margin  # keep clear of corners
        width = min(float(rng.uniform(*cfg.door_width)), s1 - s0)
        c = float(rng.uniform(s0 + width / 2, s1 - width / 2))
        centre = (line * g, c) if axis == "y" else (c, line * g)
        doors.append(Door(center=centre, width=width, axis=axis, rooms=(i, j)))
    if len({root(i) for i in range(len(cells))}) != 1:
        return None
    return sorted(doors, key=lambda d: (d.rooms, d.center))


def _room_types(rng: np.random.Generator, rects: list[Rect]) -> list[str]:
    """Biggest room is the living room, smallest the bathroom; narrow ones become hallways."""
    areas = [(r[2] - r[0]) * (r[3] - r[1]) for r in rects]
    order = sorted(range(len(rects)), key=lambda i: (-areas[i], i))
    types = ["" for _ in rects]
    types[order[0]] = "living_room"
    if len(order) > 1:
        types[order[-1]] = "bathroom"
    middle = order[1:-1]
    must = [str(x) for x in rng.permutation(["kitchen", "bedroom"])]
    extras = ["bedroom", "dining_room", "office", "bedroom", "bathroom"]
    for k, i in enumerate(middle):
        w, d = rects[i][2] - rects[i][0], rects[i][3] - rects[i][1]
        if min(w, d) < 3.0 and max(w, d) >= 2.0 * min(w, d):  # long and narrow
            types[i] = "hallway"
        elif k < len(must):
            types[i] = must[k]
        else:
            types[i] = str(rng.choice(extras))
    return types


def _box(x0: float, y0: float, z0: float, x1: float, y1: float, z1: float, rgba, kind: str) -> Box:
    # Round to a micrometre so walls that should meet do meet, without float crumbs between them.
    x0, y0, z0, x1, y1, z1 = (round(v, 6) for v in (x0, y0, z0, x1, y1, z1))
    return Box(
        ((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2),
        ((x1 - x0) / 2, (y1 - y0) / 2, (z1 - z0) / 2),
        rgba,
        kind,
    )


def _room_walls(
    cell: Rect, outer: dict[str, bool], doors: list[Door], cfg: HouseConfig, rgba
) -> list[Box]:
    """The wall boxes one room owns, with gaps where its doors are.

    Each side is ``t`` thick if it is an outer wall, else ``t/2`` (the other room owns the other
    half). Along its length a side reaches past the room's corners by the thickness of the
    perpendicular wall there, so corners and T-junctions are closed.
    """
    t, h = cfg.wall_thickness, cfg.wall_height
    thick = {side: t if outer[side] else t / 2 for side in outer}
    x0, y0, x1, y1 = cell[0] + t / 2, cell[1] + t / 2, cell[2] - t / 2, cell[3] - t / 2
    sides = {  # side: (start, end along the wall, fixed coordinate range across it, wall axis)
        "south": (x0 - thick["west"], x1 + thick["east"], (y0 - thick["south"], y0), "x"),
        "north": (x0 - thick["west"], x1 + thick["east"], (y1, y1 + thick["north"]), "x"),
        "west": (y0 - thick["south"], y1 + thick["north"], (x0 - thick["west"], x0), "y"),
        "east": (y0 - thick["south"], y1 + thick["north"], (x1, x1 + thick["east"]), "y"),
    }
    boxes = []
    for start, end, (a0, a1), axis in sides.values():
        gaps = sorted(
            (d.center[0] if axis == "x" else d.center[1], d.width)
            for d in doors
            if d.axis == axis
            and a0 - 1e-9 <= (d.center[1] if axis == "x" else d.center[0]) <= a1 + 1e-9
        )
        pieces, pos = [], start
        for c, w in gaps:
            pieces.append((pos, c - w / 2))
            pos = c + w / 2
        pieces.append((pos, end))
        for p0, p1 in pieces:
            if p1 - p0 > 1e-6:
                if axis == "x":
                    boxes.append(_box(p0, a0, 0.0, p1, a1, h, rgba, "wall"))
                else:
                    boxes.append(_box(a0, p0, 0.0, a1, p1, h, rgba, "wall"))
    return boxes


def door_clear_zone(door: Door, room: Rect, cfg: HouseConfig = HouseConfig()) -> Rect:
    """The area inside ``room`` in front of ``door`` that furniture must leave free."""
    half = door.width / 2 + cfg.door_clear_margin
    along, across = (door.center[0], door.center[1]) if door.axis == "x" else door.center[::-1]
    reach = cfg.wall_thickness / 2 + cfg.door_clear_depth
    lo, hi = (room[0], room[2]) if door.axis == "y" else (room[1], room[3])
    a0, a1 = max(lo, across - reach), min(hi, across + reach)
    if door.axis == "x":
        return (along - half, a0, along + half, a1)
    return (a0, along - half, a1, along + half)


def generate_house(
    seed: int, config: HouseConfig = HouseConfig(), scene_id: str | None = None
) -> SceneLayout:
    """Build house number ``seed``; the same seed and config always give the same layout."""
    cfg = config
    rng = np.random.default_rng(seed)
    n = int(rng.integers(cfg.min_rooms, cfg.max_rooms + 1))
    area = float(rng.uniform(*cfg.room_area, size=n).sum())
    aspect = float(rng.uniform(*cfg.footprint_aspect))
    long_side = math.sqrt(area * aspect)
    short_side = max(area / long_side, cfg.min_room_side + cfg.wall_thickness)
    swap = bool(rng.integers(2))
    cells = doors = None
    for attempt in range(10 * cfg.max_attempts):
        grow = 1.05 ** (attempt // cfg.max_attempts)  # enlarge if this size keeps failing
        w, d = _units(long_side * grow, cfg.grid), _units(short_side * grow, cfg.grid)
        width, depth = (d, w) if swap else (w, d)
        cells = _split_cells(rng, width, depth, n, cfg)
        doors = _choose_doors(rng, cells, cfg) if cells else None
        if doors is not None:
            break
    if cells is None or doors is None:
        raise RuntimeError(f"could not lay out house {seed} with {n} rooms")

    g, t = cfg.grid, cfg.wall_thickness
    cell_m = [(c[0] * g, c[1] * g, c[2] * g, c[3] * g) for c in cells]
    rects = [(x0 + t / 2, y0 + t / 2, x1 - t / 2, y1 - t / 2) for x0, y0, x1, y1 in cell_m]
    types = _room_types(rng, rects)
    size = (width * g, depth * g)

    boxes: list[Box] = []
    for i, (cell, rect, room_type) in enumerate(zip(cell_m, rects, types, strict=True)):
        floor_rgb, wall_rgb = ROOM_COLOURS[room_type]
        floor, wall = (
            varied(floor_rgb, rng, cfg.colour_variation),
            varied(wall_rgb, rng, cfg.colour_variation),
        )
        outer = {
            "south": cells[i][1] == 0,
            "north": cells[i][3] == depth,
            "west": cells[i][0] == 0,
            "east": cells[i][2] == width,
        }
        # The slab covers the cell, plus the outer half of outer walls, so there is no hole.
        sx0, sy0 = (
            cell[0] - (t / 2 if outer["west"] else 0),
            cell[1] - (t / 2 if outer["south"] else 0),
        )
        sx1, sy1 = (
            cell[2] + (t / 2 if outer["east"] else 0),
            cell[3] + (t / 2 if outer["north"] else 0),
        )
        boxes.append(_box(sx0, sy0, -cfg.floor_thickness, sx1, sy1, 0.0, floor, "floor"))
        mine = [dr for dr in doors if i in dr.rooms]
        boxes += _room_walls(cell, outer, mine, cfg, wall)
        zones = [door_clear_zone(dr, rect, cfg) for dr in mine]
        boxes += furnish_room(rng, rect, room_type, zones, cfg.furniture_density)
    h = cfg.wall_height
    boxes.append(
        _box(
            -t / 2,
            -t / 2,
            h,
            size[0] + t / 2,
            size[1] + t / 2,
            h + cfg.ceiling_thickness,
            muted(CEILING),
            "ceiling",
        )
    )

    return SceneLayout(
        scene_id=scene_id if scene_id is not None else f"house-{seed:05d}",
        boxes=tuple(boxes),
        rooms=tuple(Room(rect=r, room_type=rt) for r, rt in zip(rects, types, strict=True)),
        doors=tuple(doors),
        floor_z=0.0,
        wall_height=h,
        metadata={
            "generator": "house",
            "seed": str(seed),
            "room_count": str(n),
            "footprint": f"{size[0]:.2f}x{size[1]:.2f}",
            "footprint_width": f"{size[0]:.2f}",
            "footprint_depth": f"{size[1]:.2f}",
            "room_types": ",".join(types),
            "door_count": str(len(doors)),
        },
    )
