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

import numpy as np

from multion.config.scenes import HouseConfig
from multion.scenes.floorplan import make_plan
from multion.scenes.furniture import furnish_room
from multion.scenes.layout import Box, Door, Rgba, Room, SceneLayout
from multion.scenes.palette import CEILING, ROOM_COLOURS, ROOM_TEXTURES, muted, varied

Rect = tuple[float, float, float, float]  # (x0, y0, x1, y1)


def _room_types(
    rng: np.random.Generator, rects: list[Rect], corridors: frozenset[int]
) -> list[str]:
    """Corridors and long narrow rooms are hallways; the biggest room is the living room, the
    smallest a bathroom; then a kitchen and a bedroom, and a mix of the rest."""
    areas = [(r[2] - r[0]) * (r[3] - r[1]) for r in rects]
    types = ["" for _ in rects]
    for i, r in enumerate(rects):
        w, d = r[2] - r[0], r[3] - r[1]
        if i in corridors or (min(w, d) < 3.0 and max(w, d) >= 2.0 * min(w, d)):
            types[i] = "hallway"
    order = [i for i in sorted(range(len(rects)), key=lambda i: (-areas[i], i)) if not types[i]]
    if not order:
        return types
    types[order[0]] = "living_room"
    if len(order) > 1:
        types[order[-1]] = "bathroom"
    must = [str(x) for x in rng.permutation(["kitchen", "bedroom"])]
    must += [str(x) for x in rng.permutation(["dining_room", "bedroom", "bathroom"])]
    extras = ["bedroom", "office", "bedroom", "bathroom", "dining_room"]
    for k, i in enumerate(order[1:-1]):
        types[i] = must[k] if k < len(must) else str(rng.choice(extras))
    return types


def _box(
    x0: float,
    y0: float,
    z0: float,
    x1: float,
    y1: float,
    z1: float,
    rgba: Rgba,
    kind: str,
    texture: str = "",
) -> Box:
    # Round to a micrometre so walls that should meet do meet, without float crumbs between them.
    x0, y0, z0, x1, y1, z1 = (round(v, 6) for v in (x0, y0, z0, x1, y1, z1))
    return Box(
        ((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2),
        ((x1 - x0) / 2, (y1 - y0) / 2, (z1 - z0) / 2),
        rgba,
        kind,
        texture,
    )


def _room_walls(
    cell: Rect,
    outer: dict[str, bool],
    doors: list[Door],
    cfg: HouseConfig,
    rgba: Rgba,
    texture: str = "",
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
                    boxes.append(_box(p0, a0, 0.0, p1, a1, h, rgba, "wall", texture))
                else:
                    boxes.append(_box(a0, p0, 0.0, a1, p1, h, rgba, "wall", texture))
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
    plan = make_plan(rng, long_side, short_side, swap, n, cfg.plan, cfg.max_attempts)
    cells, doors, width, depth = list(plan.cells), list(plan.doors), plan.width, plan.depth

    g, t = cfg.plan.grid, cfg.wall_thickness
    cell_m = [(c[0] * g, c[1] * g, c[2] * g, c[3] * g) for c in cells]
    rects = [(x0 + t / 2, y0 + t / 2, x1 - t / 2, y1 - t / 2) for x0, y0, x1, y1 in cell_m]
    types = _room_types(rng, rects, plan.corridors)
    size = (width * g, depth * g)
    lighting = f"{float(rng.uniform(0.45, 0.75)):.3f},{float(rng.uniform(0.25, 0.5)):.3f}"

    boxes: list[Box] = []
    for i, (cell, rect, room_type) in enumerate(zip(cell_m, rects, types, strict=True)):
        floor_rgb, wall_rgb = ROOM_COLOURS[room_type]
        floor, wall = (
            varied(floor_rgb, rng, cfg.colour_variation),
            varied(wall_rgb, rng, cfg.colour_variation),
        )
        floor_textures, wall_textures = ROOM_TEXTURES[room_type]
        floor_texture = str(rng.choice(floor_textures))
        wall_texture = str(rng.choice(wall_textures))
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
        boxes.append(
            _box(sx0, sy0, -cfg.floor_thickness, sx1, sy1, 0.0, floor, "floor", floor_texture)
        )
        mine = [dr for dr in doors if i in dr.rooms]
        boxes += _room_walls(cell, outer, mine, cfg, wall, wall_texture)
        zones = [door_clear_zone(dr, rect, cfg) for dr in mine]
        boxes += furnish_room(rng, rect, room_type, zones, cfg.furniture_density, cfg.clutter)
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
            "room_count": str(len(cells)),
            "corridor_count": str(len(plan.corridors)),
            "footprint": f"{size[0]:.2f}x{size[1]:.2f}",
            "footprint_width": f"{size[0]:.2f}",
            "footprint_depth": f"{size[1]:.2f}",
            "footprint_area": f"{sum((c[2] - c[0]) * (c[3] - c[1]) for c in cell_m):.2f}",
            "room_types": ",".join(types),
            "door_count": str(len(doors)),
            "lighting": lighting,
        },
    )
