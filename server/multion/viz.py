"""Top-down pictures of scenes (and, later, episodes) with Pillow.

A picture covers exactly the navigable grid it is given: grid cell ``(i, j)`` is the square whose
centre is ``x = origin[0] + (j + 0.5) * cell_size``, ``y = origin[1] + (i + 0.5) * cell_size``.
The picture is flipped so that +y points up, like a floor plan. :class:`PictureFrame` and
:func:`world_to_pixel` convert world metres to pixels, so other drawings (agent paths, goals) can
be added on top of :func:`scene_picture`'s result with the same numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from multion.scenes.layout import SceneLayout

NAVIGABLE = (236, 232, 222)
BLOCKED = (120, 118, 114)
WALL = (48, 48, 52)
FURNITURE_EDGE = (150, 95, 60)
DOOR = (70, 140, 200)
TEXT = (20, 20, 20)
ROOM_LABEL = (110, 110, 110)


@dataclass(frozen=True)
class PictureFrame:
    """Which part of the world a picture shows and at what scale."""

    origin: tuple[float, float]  # world (x, y) of the picture's lower-left corner
    size: tuple[float, float]  # width and height covered, metres
    pixels_per_metre: float

    @property
    def image_size(self) -> tuple[int, int]:
        """Picture ``(width, height)`` in pixels."""
        return (
            max(1, round(self.size[0] * self.pixels_per_metre)),
            max(1, round(self.size[1] * self.pixels_per_metre)),
        )


def picture_frame(
    navigable: np.ndarray,
    origin: tuple[float, float],
    cell_size: float,
    pixels_per_metre: float = 40,
) -> PictureFrame:
    """The frame :func:`scene_picture` uses for a grid of this shape, origin and cell size."""
    rows, cols = navigable.shape
    return PictureFrame(
        (float(origin[0]), float(origin[1])), (cols * cell_size, rows * cell_size), pixels_per_metre
    )


def world_to_pixel(x: float, y: float, frame: PictureFrame) -> tuple[float, float]:
    """Pixel coordinates ``(column, row)`` of world point ``(x, y)``; rows grow downwards."""
    ppm = frame.pixels_per_metre
    top = frame.origin[1] + frame.size[1]
    return ((x - frame.origin[0]) * ppm, (top - y) * ppm)


def _rect_pixels(x0: float, y0: float, x1: float, y1: float, frame: PictureFrame):
    (px0, py1), (px1, py0) = world_to_pixel(x0, y0, frame), world_to_pixel(x1, y1, frame)
    return [px0, py0, px1, py1]


def draw_layout(draw: ImageDraw.ImageDraw, layout: SceneLayout, frame: PictureFrame) -> None:
    """Draw walls (filled), furniture (outlined), room types and doors of ``layout`` onto ``draw``."""
    furniture = [b for b in layout.boxes if b.kind == "furniture"]
    # Large boxes first so small parts (legs, handles) stay visible on top.
    furniture.sort(key=lambda b: -b.half_extents[0] * b.half_extents[1])
    for box in furniture:
        (x0, y0, _), (x1, y1, _) = box.min_corner, box.max_corner
        fill = tuple(int(255 * c) for c in box.rgba[:3])
        draw.rectangle(_rect_pixels(x0, y0, x1, y1, frame), fill=fill, outline=FURNITURE_EDGE)
    for box in layout.boxes:
        if box.kind == "wall":
            (x0, y0, _), (x1, y1, _) = box.min_corner, box.max_corner
            draw.rectangle(_rect_pixels(x0, y0, x1, y1, frame), fill=WALL)
    for room in layout.rooms:  # room type in its top-left corner
        x0, y0, x1, y1 = room.rect
        px, py = world_to_pixel(x0 + 0.1, y1 - 0.1, frame)
        draw.text((px, py), room.room_type.replace("_", " "), fill=ROOM_LABEL)
    for door in layout.doors:
        cx, cy = door.center
        dx, dy = (door.width / 2, 0.0) if door.axis == "x" else (0.0, door.width / 2)
        a, b = world_to_pixel(cx - dx, cy - dy, frame), world_to_pixel(cx + dx, cy + dy, frame)
        draw.line([a, b], fill=DOOR, width=max(1, round(frame.pixels_per_metre * 0.04)))


def _scale_bar(draw: ImageDraw.ImageDraw, frame: PictureFrame, font) -> None:
    """A 1 m bar in the lower-left corner."""
    ppm = frame.pixels_per_metre
    _, height = frame.image_size
    x0, y = 8, height - 10
    draw.rectangle([x0 - 3, y - 16, x0 + ppm + 24, y + 5], fill=(255, 255, 255))
    draw.line([(x0, y), (x0 + ppm, y)], fill=TEXT, width=3)
    draw.text((x0 + ppm + 3, y - 12), "1 m", fill=TEXT, font=font)


def _caption(draw: ImageDraw.ImageDraw, frame: PictureFrame, text: str, font) -> None:
    """``text`` on a white patch in the lower-right corner."""
    width, height = frame.image_size
    left, top, right, bottom = draw.textbbox((0, 0), text, font=font)
    x, y = width - (right - left) - 8, height - (bottom - top) - 8
    draw.rectangle([x - 3, y - 3, x + right - left + 3, y + bottom - top + 3], fill=(255, 255, 255))
    draw.text((x - left, y - top), text, fill=TEXT, font=font)


def scene_picture(
    layout: SceneLayout | None,
    navigable: np.ndarray,
    origin: tuple[float, float],
    cell_size: float,
    pixels_per_metre: float = 40,
    caption: bool = True,
) -> Image.Image:
    """A top-down RGB picture: navigable cells light, the rest darker, the layout drawn on top
    (with the scene id in a corner if ``caption``).

    The picture is ``round(cols * cell_size * pixels_per_metre)`` pixels wide and
    ``round(rows * cell_size * pixels_per_metre)`` high.
    """
    grid = np.asarray(navigable, dtype=bool)
    if grid.ndim != 2:
        raise ValueError(f"navigable must be a 2-D array, got shape {grid.shape}")
    frame = picture_frame(grid, origin, cell_size, pixels_per_metre)
    colours = np.where(grid[..., None], np.array(NAVIGABLE, np.uint8), np.array(BLOCKED, np.uint8))
    # Row 0 is the lowest y, so flip it to the bottom of the picture.
    image = Image.fromarray(np.ascontiguousarray(colours[::-1]), mode="RGB")
    image = image.resize(frame.image_size, Image.Resampling.NEAREST)
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default()
    if layout is not None:
        draw_layout(draw, layout, frame)
        if caption:
            _caption(draw, frame, layout.scene_id, font)
    _scale_bar(draw, frame, font)
    return image
