"""One empty rectangular room, for tests whose numbers are worked out by hand.

The free interior is exactly ``x ∈ [0, width]``, ``y ∈ [0, depth]``; the walls stand outside
that rectangle, and the floor slab (top at ``z = 0``) reaches under them.
"""

from __future__ import annotations

from multion.scenes.layout import Box, Rgba, Room, SceneLayout
from multion.scenes.palette import CEILING, ROOM_COLOURS, muted

WALL_THICKNESS = 0.15
WALL_HEIGHT = 2.6
SLAB_THICKNESS = 0.05


def _box(
    x0: float, y0: float, z0: float, x1: float, y1: float, z1: float, rgba: Rgba, kind: str
) -> Box:
    return Box(
        ((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2),
        ((x1 - x0) / 2, (y1 - y0) / 2, (z1 - z0) / 2),
        rgba,
        kind,
    )


def make_room(width: float, depth: float, scene_id: str | None = None) -> SceneLayout:
    """An empty ``width`` × ``depth`` metre room (free interior ``[0, width] × [0, depth]``)."""
    if not (width > 0 and depth > 0):
        raise ValueError(f"room width and depth must be positive, got {width} x {depth}")
    t, h, s = WALL_THICKNESS, WALL_HEIGHT, SLAB_THICKNESS
    floor_rgb, wall_rgb = ROOM_COLOURS["room"]
    floor, wall, ceiling = muted(floor_rgb), muted(wall_rgb), muted(CEILING)
    boxes = (
        _box(-t, -t, -s, width + t, depth + t, 0.0, floor, "floor"),
        # South and north walls run the full length, west and east fit between them.
        _box(-t, -t, 0.0, width + t, 0.0, h, wall, "wall"),
        _box(-t, depth, 0.0, width + t, depth + t, h, wall, "wall"),
        _box(-t, 0.0, 0.0, 0.0, depth, h, wall, "wall"),
        _box(width, 0.0, 0.0, width + t, depth, h, wall, "wall"),
        _box(-t, -t, h, width + t, depth + t, h + s, ceiling, "ceiling"),
    )
    return SceneLayout(
        scene_id=scene_id if scene_id is not None else f"room-{width:g}x{depth:g}",
        boxes=boxes,
        rooms=(Room(rect=(0.0, 0.0, float(width), float(depth)), room_type="room"),),
        doors=(),
        floor_z=0.0,
        wall_height=h,
        metadata={"generator": "room", "width": f"{width:g}", "depth": f"{depth:g}"},
    )
