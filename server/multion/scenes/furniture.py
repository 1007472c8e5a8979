"""How furniture is placed in a room without blocking it (the pieces: :mod:`furniture_items`).

Placing an item means choosing a wall (or the room centre, for dining tables) and an offset
along it, then rotating the parts into the world frame. A placement is kept only if it

* stays inside the room, clear of the door zones and of the furniture already placed, and
* leaves the free floor around the parts in one piece for every agent radius from 5 to 20 cm,

so furniture can never cut a room in two or wall off a door.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import ndimage

from multion.config.scenes import PlacementConfig
from multion.scenes.furniture_items import AGENT_HEIGHT, ROOM_CLUTTER, ROOM_FURNITURE, Item, Rect
from multion.scenes.layout import Box

Point = tuple[float, float]
Frame = tuple[Point, Point, Point]
"""An item's origin and its unit axes (eu, ev) in the world."""


def _frame(rng: np.random.Generator, item: Item, room: Rect, cfg: PlacementConfig) -> Frame | None:
    """A random origin and unit axes (eu, ev) for ``item`` in ``room``, or None if it can't fit."""
    x0, y0, x1, y1 = room
    w, d, g = item.width, item.depth, cfg.wall_gap
    if item.anywhere:
        turn = int(rng.integers(4))  # 0°, 90°, 180°, 270°
        fx, fy = (d, w) if turn % 2 else (w, d)
        if fx > x1 - x0 or fy > y1 - y0:
            return None
        cx, cy = float(rng.uniform(x0, x1 - fx)), float(rng.uniform(y0, y1 - fy))
        return [
            ((cx, cy), (1, 0), (0, 1)),
            ((cx + fx, cy), (0, 1), (-1, 0)),
            ((cx + fx, cy + fy), (-1, 0), (0, -1)),
            ((cx, cy + fy), (0, -1), (1, 0)),
        ][turn]
    if item.centre:
        turned = bool(rng.integers(2))
        fx, fy = (d, w) if turned else (w, d)
        cx = (x0 + x1) / 2 + rng.uniform(-0.3, 0.3) - fx / 2
        cy = (y0 + y1) / 2 + rng.uniform(-0.3, 0.3) - fy / 2
        return ((cx + d, cy), (0, 1), (-1, 0)) if turned else ((cx, cy), (1, 0), (0, 1))
    side = int(rng.integers(4))  # 0 south, 1 north, 2 west, 3 east
    length, across = (x1 - x0, y1 - y0) if side < 2 else (y1 - y0, x1 - x0)
    if w > length - 2 * g or d > cfg.max_depth_fraction * across:
        return None
    s = [g, length - w - g, float(rng.uniform(g, length - w - g))][int(rng.integers(3))]
    return [
        ((x0 + s, y0 + g), (1, 0), (0, 1)),
        ((x0 + s + w, y1 - g), (-1, 0), (0, -1)),
        ((x0 + g, y0 + s + w), (0, -1), (1, 0)),
        ((x1 - g, y0 + s), (0, 1), (-1, 0)),
    ][side]


def _to_world(
    lo: Sequence[float], hi: Sequence[float], origin: Point, eu: Point, ev: Point
) -> tuple[tuple[float, float], tuple[float, float]]:
    """Rotate the rectangle [lo, hi] (in u, v) into world x, y; returns (min corner, max corner)."""
    xs = [origin[0] + u * eu[0] + v * ev[0] for u in (lo[0], hi[0]) for v in (lo[1], hi[1])]
    ys = [origin[1] + u * eu[1] + v * ev[1] for u in (lo[0], hi[0]) for v in (lo[1], hi[1])]
    return (min(xs), min(ys)), (max(xs), max(ys))


def _overlaps(a: Rect, b: Rect, gap: float = 0.0) -> bool:
    return a[0] < b[2] + gap and b[0] < a[2] + gap and a[1] < b[3] + gap and b[1] < a[3] + gap


def _stays_navigable(room: Rect, obstacles: list[Rect], cfg: PlacementConfig) -> bool:
    """True if the room's free space is in one piece for every agent radius we check.

    Checking a range of radii (not just the agent's 0.1 m) means no narrow gap can seal off a
    pocket of free floor, whatever resolution a navigation grid later uses.
    """
    x0, y0, x1, y1 = room
    gx, gy = np.meshgrid(np.arange(x0 + cfg.cell / 2, x1, cfg.cell),
                         np.arange(y0 + cfg.cell / 2, y1, cfg.cell))  # fmt: skip
    # Exact distance from each cell centre to the nearest wall or obstacle.
    dist = np.minimum(np.minimum(gx - x0, x1 - gx), np.minimum(gy - y0, y1 - gy))
    for fx0, fy0, fx1, fy1 in obstacles:
        dx = np.maximum(np.maximum(fx0 - gx, gx - fx1), 0.0)
        dy = np.maximum(np.maximum(fy0 - gy, gy - fy1), 0.0)
        dist = np.minimum(dist, np.hypot(dx, dy))
    if (dist > cfg.clearance).mean() < cfg.min_free_fraction:
        return False
    return all(ndimage.label(dist > r)[1] == 1 for r in cfg.check_radii)


def furnish_room(
    rng: np.random.Generator,
    room: Rect,
    room_type: str,
    keep_clear: list[Rect],
    density: float = 1.0,
    clutter: int = 0,
    cfg: PlacementConfig = PlacementConfig(),
) -> list[Box]:
    """Furniture boxes for one room (interior rectangle ``room``), avoiding ``keep_clear`` areas:
    the room type's furniture along the walls, then ``clutter`` rounds of clutter."""
    boxes: list[Box] = []
    footprints: list[Rect] = []  # whole items: nothing else may be put there
    obstacles: list[Rect] = []  # the parts that block the agent: what navigation will see
    wishes = list(ROOM_FURNITURE.get(room_type, []))
    wishes += list(ROOM_CLUTTER.get(room_type, [])) * clutter
    for builder, probability in wishes:
        if rng.random() >= min(1.0, probability * density):
            continue
        item = builder(rng)
        for _ in range(cfg.attempts):
            frame = _frame(rng, item, room, cfg)
            if frame is None:
                continue
            lo, hi = _to_world((0, 0), (item.width, item.depth), *frame)
            rect = (lo[0], lo[1], hi[0], hi[1])
            inside = room[0] <= lo[0] and room[1] <= lo[1] and hi[0] <= room[2] and hi[1] <= room[3]
            if not inside or any(_overlaps(rect, z) for z in keep_clear):
                continue
            if any(_overlaps(rect, f, cfg.item_gap) for f in footprints):
                continue
            parts = [(*_to_world(p.lo, p.hi, *frame), p) for p in item.parts]
            blocking = [(a[0], a[1], b[0], b[1]) for a, b, p in parts if p.lo[2] < AGENT_HEIGHT]
            if not _stays_navigable(room, [*obstacles, *blocking], cfg):
                continue
            footprints.append(rect)
            obstacles += blocking
            for (bx0, by0), (bx1, by1), part in parts:
                z0, z1 = part.lo[2], part.hi[2]
                boxes.append(
                    Box(
                        center=((bx0 + bx1) / 2, (by0 + by1) / 2, (z0 + z1) / 2),
                        half_extents=((bx1 - bx0) / 2, (by1 - by0) / 2, (z1 - z0) / 2),
                        rgba=part.rgba,
                        kind="furniture",
                    )
                )
            break
    return boxes
