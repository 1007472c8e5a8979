"""Scene layouts as plain data: what a procedural scene is made of, before any simulator sees it.

Coordinates are metres in a right-handed frame with z up (PyBullet's convention); the floor is at
``z = floor_z``. A layout is a list of axis-aligned boxes (floor slabs, walls, ceiling, furniture
parts) plus the room rectangles, enough to build the scene in PyBullet, export it as a mesh, or
draw it from above.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

Rgba = tuple[float, float, float, float]
Vec3 = tuple[float, float, float]


def vec3(values: Iterable[float]) -> Vec3:
    """Three numbers as a point (a ``ValueError`` if there are not three)."""
    x, y, z = values
    return (float(x), float(y), float(z))


@dataclass(frozen=True)
class Box:
    """An axis-aligned box: ``center`` and ``half_extents`` in metres, a colour and a kind.

    ``kind`` is one of ``floor``, ``wall``, ``ceiling``, ``furniture``: pictures and tests use it;
    the simulator treats all boxes alike (static, colliding, rendered).
    """

    center: tuple[float, float, float]
    half_extents: tuple[float, float, float]
    rgba: Rgba
    kind: str = "furniture"
    texture: str = ""
    """A pattern of :mod:`multion.scenes.textures` ("planks", "tiles" …) or "" for a plain colour."""

    @property
    def min_corner(self) -> tuple[float, float, float]:
        return vec3(c - h for c, h in zip(self.center, self.half_extents, strict=True))

    @property
    def max_corner(self) -> tuple[float, float, float]:
        return vec3(c + h for c, h in zip(self.center, self.half_extents, strict=True))


@dataclass(frozen=True)
class Room:
    """A room's interior rectangle ``(x_min, y_min, x_max, y_max)`` and its type (``bedroom`` …)."""

    rect: tuple[float, float, float, float]
    room_type: str


@dataclass(frozen=True)
class Door:
    """A gap in the wall between two rooms: its centre, width and the axis the wall runs along."""

    center: tuple[float, float]
    width: float
    axis: str  # "x" when the wall runs along x, "y" when it runs along y
    rooms: tuple[int, int]


@dataclass(frozen=True)
class SceneLayout:
    """Everything needed to build one procedural scene."""

    scene_id: str
    boxes: tuple[Box, ...]
    rooms: tuple[Room, ...] = ()
    doors: tuple[Door, ...] = ()
    floor_z: float = 0.0
    wall_height: float = 2.6
    metadata: dict[str, str] = field(default_factory=dict)

    @property
    def bounds(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Axis-aligned bounds of all boxes: ``((x0, y0, z0), (x1, y1, z1))``."""
        lows = [b.min_corner for b in self.boxes]
        highs = [b.max_corner for b in self.boxes]
        return (
            vec3(min(v[i] for v in lows) for i in range(3)),
            vec3(max(v[i] for v in highs) for i in range(3)),
        )
